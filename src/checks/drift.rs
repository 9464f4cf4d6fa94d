//! The drift stage (isotropic samples only): the lamp's gain and colour over the run from
//! repeated geometry. Every capture at its exact pose is compared with the first capture of the
//! same (θi, θo, |Δφ|), the same geometry at another time, so ln(Y/Y₀) is the gain change; the
//! occlusion substitutes' interpolated pairs join in buckets of their own, weighted by their
//! spread; gain steps found by the light sweeps enter as step terms. Rate alarms only: see
//! `detect::drift` for why steps are left to the sweeps and the probes.
//!
//! The same comparisons give the lamp's colour: ln(X/Y) and ln(Z/Y) against the first capture
//! of the geometry move with the lamp's colour temperature and not with its luminance. Each has
//! a rate fit of its own (the same model as the gain's, geometry buckets as fixed effects); the
//! two rates become one colour-temperature rate through `detect::lamp`, alarmed as
//! `colour-drift` in K/h and in ΔE00/h of a white.

use super::evidence::{self, Evidence, Source};
use super::pairs::PendingPartner;
use super::records::{PairRecord, PairStatus};
use super::{Ctx, GeometryKey, Ledger};
use crate::checks::alarm::{action, Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use crate::detect::drift::{
    mount_coordinates, DriftDetector, DriftEstimate, DriftEvent, DriftSpec, GainPath, MountPattern,
    PairObservation, StepEffect,
};
use crate::detect::lamp::LampColour;
use crate::detect::probes::{colour_fit_spec, UNSTABLE_FACTOR};
use crate::measure::colour::{White, Xyz};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// The colour-drift check (`[checks.colour_drift]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ColourDriftSpec {
    /// The lamp's colour temperature at the start of the run (K), where the camera was
    /// white-balanced: the reference of the lamp model.
    pub lamp_cct_k: f64,
    /// Alarm when the colour-temperature rate is significant and larger than this (K/h).
    pub tolerance_k_per_h: f64,
    /// Two-sided confidence for "significant" (z of the normal distribution).
    pub z: f64,
}

impl Default for ColourDriftSpec {
    fn default() -> Self {
        ColourDriftSpec {
            lamp_cct_k: 3000.0,
            tolerance_k_per_h: 5.0,
            z: 4.0,
        }
    }
}

/// The lamp's colour drift as estimated from isotropy classes or probes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColourDriftEstimate {
    /// Isotropy classes or probes.
    pub source: Source,
    /// Observations in each of the two rate fits.
    pub observations: usize,
    /// The lamp model's reference colour temperature (K).
    pub lamp_cct_k: f64,
    /// Colour-temperature rate (K/h; negative: redder) and its standard error.
    pub k_per_h: f64,
    pub se_k_per_h: f64,
    /// ΔE00 per hour of a white surface at that rate.
    pub de00_per_h: f64,
    /// The rates of ln(X/Y) and ln(Z/Y) (%/h) with their standard errors.
    pub x_rate_pct_per_h: f64,
    pub x_se_pct_per_h: f64,
    pub z_rate_pct_per_h: f64,
    pub z_se_pct_per_h: f64,
}

/// Two rate fits on the log-chromaticities and the alarm state, for one source.
pub(super) struct ColourStage {
    source: Source,
    spec: ColourDriftSpec,
    model: LampColour,
    /// ln(X/Y) and ln(Z/Y).
    fits: [DriftDetector; 2],
    estimate: Option<ColourDriftEstimate>,
    alarm: bool,
    /// The latest observation's time (hours): the span the rates were observed over.
    span_h: f64,
}

/// The drift model shared by the gain and the colour fits: about 6,561 − 1,378 observations in
/// a UBO run; rate only, because consecutive observations share neighbouring geometry, so
/// their residuals are correlated and heavy-tailed and the CUSUM's ARL design does not hold
/// (steps are the sweeps' and the probes' job).
fn isotropy_drift_spec() -> DriftSpec {
    DriftSpec {
        run_pairs: 5200.0,
        step_detection: false,
        mount_terms: true,
        pattern_check: true,
        ..DriftSpec::default()
    }
}

/// How often the isotropy classes' colour fits are refitted (pairs): a lamp's colour
/// temperature moves over hours, and 100 pairs are about 2 % of a UBO run, so a refit every 100
/// pairs costs the colour alarm at most 100 pairs of delay and a fifth of the refits of the gain
/// fit (every 20), which must follow steps.
const COLOUR_REFIT_PAIRS: usize = 100;

impl ColourStage {
    /// The colour fits for `source`, with the fits' model `fits` (its own rate alarm is
    /// switched off: the colour alarm is decided on the combined rate).
    fn new(source: Source, spec: ColourDriftSpec, fits: DriftSpec) -> Option<Self> {
        // the config's range check keeps the temperature valid; a model that cannot be built
        // leaves the colour check out rather than the session
        let model = LampColour::new(spec.lamp_cct_k).ok()?;
        let quiet = DriftSpec {
            rate_tolerance_pct_per_h: f64::INFINITY,
            mount_terms: false,
            pattern_check: false,
            ..fits
        };
        Some(ColourStage {
            source,
            spec,
            model,
            fits: [DriftDetector::new(quiet.clone()), DriftDetector::new(quiet)],
            estimate: None,
            alarm: false,
            span_h: 0.0,
        })
    }

    /// The colour fits of the drift probes: one geometry (the probe pose), so one bucket, a
    /// refit at every probe once there are `min_probes`, the residual scale floored at
    /// `scale_floor` (`colour_fit_spec`).
    pub(super) fn probes(
        spec: &ColourDriftSpec,
        min_probes: usize,
        scale_floor: f64,
    ) -> Option<Self> {
        Self::new(
            Source::Probes,
            spec.clone(),
            colour_fit_spec(min_probes, scale_floor),
        )
    }

    pub(super) fn estimate(&self) -> Option<ColourDriftEstimate> {
        self.estimate.clone()
    }

    /// One capture against an earlier one of the same geometry (`first` and `now` are (hours,
    /// XYZ)).
    pub(super) fn observe(
        &mut self,
        bucket: (i64, i64),
        first: (f64, Xyz),
        now: (f64, Xyz),
        at: (Option<u64>, Option<f64>),
        alarms: &mut Vec<Alarm>,
    ) {
        let (a, b) = (first.1, now.1);
        if !(a.iter().chain(&b).all(|v| *v > 0.0 && v.is_finite())) {
            return;
        }
        let d = [
            (b[0] / b[1]).ln() - (a[0] / a[1]).ln(),
            (b[2] / b[1]).ln() - (a[2] / a[1]).ln(),
        ];
        self.span_h = self.span_h.max(now.0);
        let before = self.fits[0].estimate().map(|e| e.pairs);
        for (fit, d) in self.fits.iter_mut().zip(d) {
            fit.add(PairObservation {
                t_a_h: first.0,
                t_b_h: now.0,
                d,
                bucket,
                sigma: 0.0,
                // the chromaticity ratios cancel the mount's achromatic pattern
                mount: [0.0; 4],
                light_az: [0.0; 2],
            });
        }
        let (Some(u), Some(v)) = (self.fits[0].estimate(), self.fits[1].estimate()) else {
            return;
        };
        if before == Some(u.pairs) {
            return;
        }
        let Some(rate) = self.model.cct_rate(
            (u.rate_pct_per_h / 100.0, u.se_pct_per_h / 100.0),
            (v.rate_pct_per_h / 100.0, v.se_pct_per_h / 100.0),
            self.span_h,
        ) else {
            return;
        };
        let de00 = White::d65_scaled(100.0)
            .map(|w| self.model.delta_e00_per_h(rate.k_per_h, w))
            .unwrap_or(f64::NAN);
        let e = ColourDriftEstimate {
            source: self.source,
            observations: u.pairs,
            lamp_cct_k: self.model.reference_k(),
            k_per_h: rate.k_per_h,
            se_k_per_h: rate.se_k_per_h,
            de00_per_h: de00,
            x_rate_pct_per_h: u.rate_pct_per_h,
            x_se_pct_per_h: u.se_pct_per_h,
            z_rate_pct_per_h: v.rate_pct_per_h,
            z_se_pct_per_h: v.se_pct_per_h,
        };
        self.estimate = Some(e.clone());
        let (tol, z) = (self.spec.tolerance_k_per_h, self.spec.z);
        if !self.alarm && rate.exceeds(tol, z) {
            self.alarm = true;
            alarms.push(colour_alarm(&e, at));
        } else if self.alarm && rate.within(tol, z) {
            self.alarm = false;
            alarms.push(
                Alarm::new(
                    AlarmKind::Drift,
                    Severity::Info,
                    AlarmCode::ColourDriftCleared,
                    format!(
                        "the lamp's colour drift estimate is back within the tolerance: {:+.1} ± {:.1} K/h ({})",
                        e.k_per_h, e.se_k_per_h, e.source
                    ),
                )
                .at(at.0, at.1),
            );
        }
    }

    /// ln(X/Y) and ln(Z/Y) of the lamp's colour change at `t_h` relative to the start: the
    /// lamp model at the estimated colour temperature then, which follows the curvature of the
    /// chromaticity in T (ln X/Y turns over near 3500 K) where a straight line per channel
    /// would not.
    pub(super) fn ln_chromaticity_at(&self, t_h: f64) -> Option<[f64; 2]> {
        let e = self.estimate.as_ref()?;
        let c = self
            .model
            .log_chromaticity(self.model.reference_k() + e.k_per_h * t_h);
        c.iter().all(|v| v.is_finite()).then_some(c)
    }
}

/// The alarm for a significant colour drift.
fn colour_alarm(e: &ColourDriftEstimate, at: (Option<u64>, Option<f64>)) -> Alarm {
    Alarm::new(
        AlarmKind::Drift,
        Severity::Warning,
        AlarmCode::ColourDrift,
        format!(
            "the lamp's colour drifts by {:+.1} K/h (± {:.1} K/h standard error, from {} {}; ΔE00 {:.2}/h on a white): {}; beyond the tolerance. Every later capture's chromaticity moves with the lamp",
            e.k_per_h,
            e.se_k_per_h,
            e.observations,
            if e.source == Source::Probes { "probes" } else { "isotropy comparisons" },
            e.de00_per_h,
            if e.k_per_h < 0.0 { "cooler, redder light" } else { "hotter, bluer light" },
        ),
    )
    .at(at.0, at.1)
    .with(Evidence::ColourRate(evidence::ColourRate {
        k_per_h: e.k_per_h,
        se_k_per_h: e.se_k_per_h,
        de00_per_h: e.de00_per_h,
        lamp_cct_k: e.lamp_cct_k,
        x_rate_pct_per_h: e.x_rate_pct_per_h,
        z_rate_pct_per_h: e.z_rate_pct_per_h,
        n: e.observations,
        source: e.source,
    }))
    .advise(action::COLOUR_DRIFT, Some(Affects::Since { from_idx: 0, handling: Handling::Corrected }))
}

/// The isotropy model's drift events as alarms.
fn raise(events: Vec<DriftEvent>, at: (Option<u64>, Option<f64>), alarms: &mut Vec<Alarm>) {
    alarms.extend(
        events
            .into_iter()
            .map(|ev| drift_alarm(ev, Source::IsotropyClasses, at, None)),
    );
}

pub(super) struct DriftStage {
    detector: DriftDetector,
    /// The lamp's colour (None when the lamp model cannot be built).
    colour: Option<ColourStage>,
    /// The first capture of each geometry: (time in hours, XYZ, `mount_coordinates`, the
    /// light's azimuth in radians).
    first_of_geometry: HashMap<GeometryKey, (f64, Xyz, [f64; 4], f64)>,
    /// Interpolated pairs fed to the fit.
    pub(super) interpolated: u64,
}

impl DriftStage {
    pub(super) fn new(colour: &ColourDriftSpec) -> Self {
        DriftStage {
            detector: DriftDetector::new(isotropy_drift_spec()),
            colour: ColourStage::new(
                Source::IsotropyClasses,
                colour.clone(),
                DriftSpec {
                    refit_every: COLOUR_REFIT_PAIRS,
                    ..isotropy_drift_spec()
                },
            ),
            first_of_geometry: HashMap::new(),
            interpolated: 0,
        }
    }

    /// A capture of `key` at time `t_s` with colour `xyz` (Y > 0), the gnomonic coordinates
    /// `mount` of its directions and its light's azimuth `light_az` (radians, sample frame):
    /// an observation against the first capture of its geometry, or that first capture.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn observe(
        &mut self,
        key: GeometryKey,
        t_s: f64,
        xyz: Xyz,
        mount: [f64; 4],
        light_az: f64,
        at: (Option<u64>, Option<f64>),
        alarms: &mut Vec<Alarm>,
    ) {
        let t_h = t_s / 3600.0;
        let light_az = if light_az.is_finite() { light_az } else { 0.0 };
        match self.first_of_geometry.get(&key) {
            Some(&(t0, xyz0, mount0, az0)) => {
                let obs = PairObservation {
                    t_a_h: t0,
                    t_b_h: t_h,
                    d: (xyz[1] / xyz0[1]).ln(),
                    bucket: (key.0, key.1),
                    sigma: 0.0,
                    mount: std::array::from_fn(|j| mount[j] - mount0[j]),
                    light_az: [az0, light_az],
                };
                let events = self.detector.add(obs);
                raise(events, at, alarms);
                if let Some(colour) = self.colour.as_mut() {
                    colour.observe((key.0, key.1), (t0, xyz0), (t_h, xyz), at, alarms);
                }
            }
            None => {
                self.first_of_geometry
                    .insert(key, (t_h, xyz, mount, light_az));
            }
        }
    }

    /// The lamp's colour drift estimate, once both fits have one.
    pub(super) fn colour_estimate(&self) -> Option<ColourDriftEstimate> {
        self.colour.as_ref()?.estimate()
    }

    /// ln(X/Y) and ln(Z/Y) of the lamp's colour change at `t_h`, once estimated.
    pub(super) fn ln_chromaticity_at(&self, t_h: f64) -> Option<[f64; 2]> {
        self.colour.as_ref()?.ln_chromaticity_at(t_h)
    }

    /// A gain step found by the light sweeps, starting at `t_s`, becomes a step term.
    pub(super) fn add_step(&mut self, t_s: f64) {
        self.detector.add_step(t_s / 3600.0);
    }

    /// A joint slip named by the light sweeps, from `t_s` on: later pairs leave the gain fit
    /// (`DriftDetector::add_pose_break`). The colour fits keep them: a tilt changes the
    /// luminance of a geometry, hardly its chromaticity ratios.
    pub(super) fn add_pose_break(
        &mut self,
        t_s: f64,
        at: (Option<u64>, Option<f64>),
        alarms: &mut Vec<Alarm>,
    ) {
        let events = self.detector.add_pose_break(t_s / 3600.0);
        raise(events, at, alarms);
    }

    /// A step term withdrawn (the light sweeps attributed its level change to a joint slip).
    pub(super) fn remove_step(
        &mut self,
        t_s: f64,
        at: (Option<u64>, Option<f64>),
        alarms: &mut Vec<Alarm>,
    ) {
        let events = self.detector.remove_step(t_s / 3600.0);
        raise(events, at, alarms);
    }

    /// Whether the isotropy classes raise rate alarms (`DriftDetector::set_rate_alarms`).
    pub(super) fn set_rate_alarms(&mut self, on: bool) {
        self.detector.set_rate_alarms(on);
    }

    /// Pairs left out of the gain fit after a named joint slip.
    pub(super) fn left_out(&self) -> usize {
        self.detector.left_out
    }

    /// An interpolated pair in the fit: the substitute against its partner interpolated at the
    /// mirrored pose, timed at the mean time of the partner light's captures, in a bucket of its
    /// own per (θ light, θ camera) so that the pair's stationary non-reciprocity is a fixed
    /// effect, and weighted by the interpolation's relative spread.
    pub(super) fn observe_interpolated(
        &mut self,
        ctx: &Ctx,
        ledger: &Ledger,
        p: &PendingPartner,
        pair: &PairRecord,
        alarms: &mut Vec<Alarm>,
    ) {
        if pair.status != PairStatus::Interpolated {
            return;
        }
        let (Some(a), Some(b), Some(info)) = (pair.xyz_a, pair.xyz_b, &pair.interpolated) else {
            return;
        };
        let Some(spread) = info.spread_xyz else {
            return;
        };
        let Some(t_partner) = ledger.light_mean_time(ctx.plan, p.light) else {
            return;
        };
        if !(a[1] > 0.0 && b[1] > 0.0) {
            return;
        }
        let Ok(pe) = ctx.plan.entry(p.entry) else {
            return;
        };
        let dirs = ctx.plan.directions();
        let bucket = (
            -1 - (dirs[pe.light].theta_deg * 1000.0).round() as i64,
            (dirs[pe.camera].theta_deg * 1000.0).round() as i64,
        );
        let (t_sub, t_par) = (p.capture.t / 3600.0, t_partner / 3600.0);
        // the pair swaps light and camera: the mount's coordinates of the partner are the
        // substitute's swapped (nominal directions)
        let (wl, wc) = (
            dirs[pe.light].spherical().to_vector(),
            dirs[pe.camera].spherical().to_vector(),
        );
        let (m_sub, m_par) = (mount_coordinates(&wl, &wc), mount_coordinates(&wc, &wl));
        // d = ln(Y later / Y earlier)
        let (t_a_h, t_b_h, d, mount) = if t_sub <= t_par {
            (
                t_sub,
                t_par,
                (b[1] / a[1]).ln(),
                std::array::from_fn(|j| m_par[j] - m_sub[j]),
            )
        } else {
            (
                t_par,
                t_sub,
                (a[1] / b[1]).ln(),
                std::array::from_fn(|j| m_sub[j] - m_par[j]),
            )
        };
        let obs = PairObservation {
            t_a_h,
            t_b_h,
            d,
            bucket,
            sigma: (spread[1] / b[1]).abs(),
            mount,
            light_az: [0.0; 2],
        };
        if !(obs.d.is_finite() && obs.sigma.is_finite()) {
            return;
        }
        let at = (Some(p.capture.idx), Some(p.capture.t));
        let events = self.detector.add(obs);
        raise(events, at, alarms);
        self.interpolated += 1;
    }

    /// ln g(t) and its standard uncertainty at `t_h` hours, once there is an estimate.
    pub(super) fn ln_gain_at(&self, t_h: f64) -> Option<(f64, f64)> {
        self.detector.ln_gain_at(t_h)
    }

    pub(super) fn estimate(&self) -> Option<DriftEstimate> {
        self.detector.estimate()
    }

    pub(super) fn steps(&self) -> &[StepEffect] {
        self.detector.steps()
    }

    /// The fitted gain path, once there is an estimate.
    pub(super) fn gain_path(&self) -> Option<GainPath> {
        self.detector.gain_path()
    }

    /// The off-centre mount's pattern, once it is part of the model.
    pub(super) fn mount(&self) -> Option<MountPattern> {
        self.detector.mount()
    }
}

/// The alarm for a drift event of `source` (isotropy classes or probes). `since` is the first
/// capture a step can have affected (after the last observation before it), when known.
pub(super) fn drift_alarm(
    ev: DriftEvent,
    source: Source,
    at: (Option<u64>, Option<f64>),
    since: Option<u64>,
) -> Alarm {
    match ev {
        DriftEvent::RateSignificant(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            AlarmCode::GainDrift,
            format!(
                "the gain drifts by {:+.2} %/h (± {:.2} %/h standard error, from {} {source}); beyond the tolerance",
                e.rate_pct_per_h, e.se_pct_per_h, e.pairs
            ),
        )
        .at(at.0, at.1)
        .with(Evidence::GainRate(evidence::GainRate { rate_pct_per_h: e.rate_pct_per_h, se_pct_per_h: e.se_pct_per_h, n: e.pairs, source }))
        // a rate acts on the whole run, from its first capture
        .advise(action::GAIN_DRIFT, Some(Affects::Since { from_idx: 0, handling: Handling::Corrected })),
        DriftEvent::RateCleared(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            AlarmCode::GainDriftCleared,
            format!(
                "the gain drift estimate is back within the tolerance: {:+.2} ± {:.2} %/h ({source})",
                e.rate_pct_per_h, e.se_pct_per_h
            ),
        )
        .at(at.0, at.1),
        DriftEvent::Unstable { scatter, design, probes, from_idx } => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            AlarmCode::LampUnstable,
            format!(
                "the lamp is unstable: the {source} scatter by {:.2} % (the smaller of two robust SDs of {probes} probes, about their trend and from one to the next) against the {:.2} % the probe cadence was designed for ([probes] design_scatter_pct; lamp-unstable above {UNSTABLE_FACTOR} ×); steps smaller than 5 × the scatter go unseen meanwhile, and on an isotropic sample the light sweeps do not judge the arm joints or the wagon's lag (each capture has a gain of its own)",
                100.0 * scatter,
                100.0 * design
            ),
        )
        .at(at.0, at.1)
        .with(Evidence::LampScatter(evidence::LampScatter { scatter_pct: 100.0 * scatter, design_scatter_pct: 100.0 * design, probes, source }))
        .advise(
            "Let the lamp warm up and settle; check its supply, its connections and any draught or fan near it; if the scatter stays, pause the run and fix the lamp. The captures since the first probe judged carry the lamp's noise, which no correction removes.",
            Some(Affects::Since { from_idx, handling: Handling::Inspect }),
        ),
        DriftEvent::UnstableCleared { scatter, design, probes } => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            AlarmCode::LampUnstableCleared,
            format!(
                "the lamp is steady again: the {source} scatter by {:.2} % over {probes} probes (design {:.2} %)",
                100.0 * scatter,
                100.0 * design
            ),
        )
        .at(at.0, at.1)
        .with(Evidence::LampScatter(evidence::LampScatter { scatter_pct: 100.0 * scatter, design_scatter_pct: 100.0 * design, probes, source })),
        DriftEvent::MountPattern(m) => mount_alarm(&m, source, at),
        DriftEvent::Unresolved { estimate: e, robust: r } => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            AlarmCode::TrendUnresolved,
            format!(
                "the {source} show a gain trend of {:+.2} ± {:.2} %/h, but beside a stationary pattern of the light's direction in each θi layer (a beam not uniform over the sample, a holder's shadow) it is {:+.2} ± {:.2} %/h: in this acquisition order the two are not told apart yet, so no alarm. Probes would decide at once; without them the classes decide as the light turns through more of its layers",
                e.rate_pct_per_h, e.se_pct_per_h, r.rate_pct_per_h, r.se_pct_per_h
            ),
        )
        .at(at.0, at.1)
        .with(Evidence::UnresolvedTrend(evidence::UnresolvedTrend {
            rate_pct_per_h: e.rate_pct_per_h,
            se_pct_per_h: e.se_pct_per_h,
            robust_rate_pct_per_h: r.rate_pct_per_h,
            robust_se_pct_per_h: r.se_pct_per_h,
            n: e.pairs,
            source,
        })),
        DriftEvent::Step { direction, statistic, threshold, pairs_since_reset } => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            AlarmCode::GainStep,
            format!(
                "the gain stepped {}: the latest of the {source} departs from the trend of the previous {pairs_since_reset} by {statistic:.1} standard deviations (threshold {threshold})",
                if direction > 0 { "up" } else { "down" }
            ),
        )
        .at(at.0, at.1)
        .with(Evidence::TrendStep(evidence::TrendStep { direction, statistic, threshold, source }))
        .advise(
            action::GAIN_STEP,
            since.or(at.0).map(|from_idx| Affects::Since { from_idx, handling: Handling::Corrected }),
        ),
    }
}

/// The off-centre mount's pattern became part of the drift model.
fn mount_alarm(m: &MountPattern, source: Source, at: (Option<u64>, Option<f64>)) -> Alarm {
    let ((cam, cam_az), (light, light_az)) = (m.camera_pct(), m.light_pct());
    let (cam_se, light_se) = (100.0 * m.camera_se, 100.0 * m.light_se);
    Alarm::new(
        AlarmKind::Isotropy,
        Severity::Warning,
        AlarmCode::SampleOffCentre,
        format!(
            "the luminance follows the camera's azimuth by {cam:.2} ± {cam_se:.2} % per unit tan θo (brightest towards φ = {cam_az:.0}°) in every light sweep, {}: the sample sits off the arm's rotation centre, or is not isotropic. The {source} drift model and the light sweeps carry this pattern from now on, which makes their drift estimates less precise",
            if m.light_separated() {
                format!("and the light's by {light:.2} ± {light_se:.2} % per unit tan θi (φ = {light_az:.0}°)")
            } else {
                "and the light's (not yet told apart from a drift: no rate alarm until the light has turned through a θ layer)".to_string()
            }
        ),
    )
    .at(at.0, at.1)
    .with(Evidence::MountPattern(evidence::MountPattern {
        camera_pct: cam,
        camera_azimuth_deg: cam_az,
        camera_se_pct: cam_se,
        light_pct: light,
        light_azimuth_deg: light_az,
        light_se_pct: light_se,
        rate_inflation: m.rate_inflation,
        source,
    }))
    .advise(action::SAMPLE_OFF_CENTRE, Some(Affects::Since { from_idx: 0, handling: Handling::Inspect }))
}
