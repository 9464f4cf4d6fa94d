//! The per-capture checks of a session, incremental and in capture order: measured geometry from
//! the encoder pose, colour, capture quality, reciprocal pairs (the paper's Section 6.1, exact
//! partners only), isotropy classes, reciprocity outliers and the running Table 2 summary.
//!
//! Pure: a `Checker` is a deterministic function of the sequence of `CaptureInput`s it is given.
//! Partner look-up is O(1) (captures are stored by plan entry); isotropy classes are a hash map.

use super::alarm::{Alarm, AlarmKind, Severity};
use super::averaging::CaptureStats;
use super::colour::{colour_difference, xyz_to_lab, ColourDifference, Lab, RgbToXyz, White, Xyz};
use super::drift::{DriftDetector, DriftEstimate, DriftEvent, DriftSpec, PairObservation};
use super::geometry::{angle_between, Spherical, Vec3};
use super::kinematics::{Angles, Incidence, Rig};
use super::plan::{IsotropyKey, SamplingPlan};
use super::probes::{ProbeDrift, ProbeSpec};
use super::reciprocity::{pair_residual, PairError};
use super::resample::{ResampleSpec, Resampler, Sample};
use super::sweeps::{SweepCapture, SweepMonitor, SweepRecord, SweepSpec};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::collections::HashMap;

/// Thresholds of the checks (`[checks]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CheckSpec {
    /// A pair is exact when each capture's ωi is within this of the partner's ωo (degrees).
    pub pair_tolerance_deg: f64,
    /// Measured (encoder) directions further than this from the plan raise a positioning alarm.
    pub pose_tolerance_deg: f64,
    /// |encoder − commanded| above this on any axis raises a positioning alarm (degrees).
    pub encoder_tolerance_deg: f64,
    /// A pair is an outlier when its ΔE00 exceeds median + k · 1.4826 · MAD of the pairs so far
    /// with the same two nominal θ …
    pub outlier_k: f64,
    /// … and this floor …
    pub outlier_floor_de2000: f64,
    /// … once this many exact pairs are in.
    pub outlier_min_pairs: usize,
    /// More non-finite pixels than this in a capture raise a capture-quality alarm.
    pub nonfinite_max: u64,
    /// A larger fraction of clipped pixels raises a capture-quality alarm.
    pub clipped_fraction_max: f64,
    /// A capture whose mean Y (configured XYZ scale) is at or below this is dark.
    pub dark_y: f64,
    /// This many failed captures in a row is critical.
    pub failures_critical: u32,
    /// Light-sweep checks: gain level shifts and joint offsets (isotropic samples).
    pub sweeps: SweepSpec,
}

impl Default for CheckSpec {
    fn default() -> Self {
        CheckSpec {
            pair_tolerance_deg: 0.5,
            pose_tolerance_deg: 0.25,
            encoder_tolerance_deg: 0.1,
            outlier_k: 6.0,
            outlier_floor_de2000: 5.0,
            outlier_min_pairs: 30,
            nonfinite_max: 0,
            clipped_fraction_max: 0.001,
            dark_y: 0.5,
            failures_critical: 5,
            sweeps: SweepSpec::default(),
        }
    }
}

/// What the ingestion made of one announced capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum Outcome {
    Ok {
        stats: CaptureStats,
        width: usize,
        height: usize,
        size: u64,
        sha256: String,
    },
    Failed {
        error: String,
    },
    Missing {
        reason: String,
    },
}

/// One announced capture with its outcome, as the checker sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureInput {
    pub idx: u64,
    pub entry: usize,
    pub file: String,
    pub t: f64,
    pub cmd: [f64; 4],
    pub enc: [f64; 4],
    pub substitute: Option<f64>,
    pub probe: bool,
    pub outcome: Outcome,
}

/// One line of `captures.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureRecord {
    pub idx: u64,
    pub entry: usize,
    pub light: usize,
    pub camera: usize,
    pub probe: bool,
    pub t: f64,
    pub file: String,
    pub status: String,
    pub error: Option<String>,
    pub mean_rgb: Option<[f64; 3]>,
    pub xyz: Option<Xyz>,
    pub lab: Option<Lab>,
    pub pixels: Option<u64>,
    pub nonfinite: Option<u64>,
    pub clipped: Option<u64>,
    pub negative: Option<u64>,
    /// Angles measured from the encoder pose.
    pub angles: Option<Angles>,
    /// θi the rig used instead of the plan's (occlusion substitute).
    pub substitute: Option<f64>,
    /// Largest angle between a measured and a planned direction (degrees).
    pub pose_error_deg: Option<f64>,
    /// The XYZ with the gain drift known at check time divided out, when there is an estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_corrected: Option<GainCorrected>,
}

/// A capture's drift-corrected colour: xyz / g(t), with g from the drift probes when enabled
/// (the current segment's line: its level includes steps) or else from isotropy classes (a rate
/// from the start of the run: steps are not in it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GainCorrected {
    pub xyz: Xyz,
    /// The gain divided out, g(t) relative to the start (probes: to the probe pose's original).
    pub gain: f64,
    /// Relative standard uncertainty of the correction.
    pub sigma_rel: f64,
    /// `probes` or `isotropy classes`.
    pub source: String,
}

/// One line of `pairs.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairRecord {
    /// Capture indices, earlier first.
    pub a: u64,
    pub b: u64,
    pub entries: [usize; 2],
    /// `exact`, `needs-resampling` (a partner is not at the mirrored pose), `grazing`.
    pub status: String,
    /// Largest angle between one capture's ωi and the other's ωo (degrees).
    pub mismatch_deg: f64,
    pub t: f64,
    pub xyz_a: Option<Xyz>,
    pub xyz_b: Option<Xyz>,
    pub diff: Option<ColourDifference>,
    /// For an `interpolated` (or `unresolved`) pair: how the partner was made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolated: Option<Interpolation>,
}

/// The partner of an occlusion substitute, interpolated from the session's own captures of the
/// partner's light direction at the exact mirrored pose (`measure::resample`, slice layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Interpolation {
    /// The plan light direction whose captures were interpolated.
    pub light: usize,
    /// `cshep2d` or `qshep2d`; empty when unresolved.
    pub method: String,
    /// Captures used as nodes.
    pub nodes: usize,
    /// The interpolated partner's uncertainty: the nodal functions' spread per XYZ channel, in
    /// the units of the re-corrected partner `xyz_b`.
    pub spread_xyz: Option<Xyz>,
    /// ΔE00 between the partner and the partner moved by one spread: the pair's ΔE00 is only
    /// meaningful beyond this.
    pub sigma_de2000: Option<f64>,
    /// Why no partner could be interpolated.
    pub error: Option<String>,
}

/// One line of `isotropy.jsonl`: a capture against the mean of its class's earlier members.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IsotropyRecord {
    pub idx: u64,
    pub entry: usize,
    pub class: [f64; 3],
    pub earlier_members: usize,
    pub diff: ColourDifference,
}

/// Running means in the form of the paper's Table 2.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Table2 {
    pub pairs: u64,
    pub abs_dx: f64,
    pub abs_dy: f64,
    pub abs_dz: f64,
    pub de76: f64,
    pub dc: f64,
    pub dh: f64,
    pub de2000: f64,
}

impl Table2 {
    fn add(&mut self, d: &ColourDifference) {
        let n = self.pairs as f64;
        let upd = |m: &mut f64, v: f64| *m = (*m * n + v) / (n + 1.0);
        upd(&mut self.abs_dx, d.abs_dxyz[0]);
        upd(&mut self.abs_dy, d.abs_dxyz[1]);
        upd(&mut self.abs_dz, d.abs_dxyz[2]);
        upd(&mut self.de76, d.de76);
        upd(&mut self.dc, d.dc);
        upd(&mut self.dh, d.dh);
        upd(&mut self.de2000, d.de2000);
        self.pairs += 1;
    }
}

/// Counters for the summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CheckCounts {
    pub captures: u64,
    pub ok: u64,
    pub failed: u64,
    pub missing: u64,
    pub probes: u64,
    pub pairs_exact: u64,
    pub pairs_needs_resampling: u64,
    pub pairs_grazing: u64,
    /// Occlusion substitutes scored against an interpolated partner, and those that could not be.
    #[serde(default)]
    pub pairs_interpolated: u64,
    #[serde(default)]
    pub pairs_unresolved: u64,
    pub isotropy_comparisons: u64,
    /// Interpolated pairs fed to the isotropy drift fit (weighted by their spread).
    #[serde(default)]
    pub drift_interpolated: u64,
    pub alarms: u64,
}

/// Everything the checker produced for one capture.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckOutput {
    pub capture: Option<CaptureRecord>,
    pub pairs: Vec<PairRecord>,
    pub isotropy: Vec<IsotropyRecord>,
    pub sweeps: Vec<SweepRecord>,
    pub alarms: Vec<Alarm>,
}

#[derive(Debug, Clone)]
struct Checked {
    idx: u64,
    t: f64,
    xyz: Xyz,
    theta_i_deg: f64,
    omega_i: Vec3,
    omega_o: Vec3,
    exact_pose: bool,
    dark: bool,
    substitute: bool,
}

/// A substitute capture waiting for its partner's light direction to be complete.
#[derive(Debug, Clone)]
struct PendingPartner {
    capture: Checked,
    entry: usize,
    light: usize,
}

#[derive(Debug, Clone, Default)]
struct ClassAcc {
    n: usize,
    sum: [f64; 3],
}

/// The colour settings the checker needs.
#[derive(Debug, Clone)]
pub struct ColourSettings {
    pub to_xyz: RgbToXyz,
    pub rgb_scale: f64,
    pub white: White,
    pub min_cos: f64,
}

pub struct Checker {
    plan: SamplingPlan,
    rig: Rig,
    colour: ColourSettings,
    spec: CheckSpec,
    isotropic: bool,
    by_entry: Vec<Option<Checked>>,
    classes: HashMap<IsotropyKey, ClassAcc>,
    table2: Table2,
    isotropy_table: Table2,
    /// ΔE00 of exact pairs so far, sorted, per geometry bucket (the pair's two nominal θ):
    /// realistic data are less reciprocal toward grazing angles, so an outlier is judged
    /// against pairs of the same geometry.
    sorted_de2000: HashMap<(i64, i64), Vec<f64>>,
    counts: CheckCounts,
    consecutive_failures: u32,
    probes: ProbeDrift,
    /// Plan entries seen (first capture of each, any outcome) and the count per light direction:
    /// a light direction is complete when all its entries have been seen.
    entry_seen: Vec<bool>,
    seen_per_light: Vec<usize>,
    pending: Vec<PendingPartner>,
    interpolated_table: Table2,
    /// Gain drift from isotropy classes (isotropic samples only): every capture against the
    /// first capture of the same (θi, θo, |φi − φo|), i.e. the same geometry at another time.
    first_of_geometry: HashMap<(i64, i64, i64), (f64, f64)>,
    isotropy_drift: Option<DriftDetector>,
    /// Light-sweep checks (isotropic samples, light-outer orders).
    sweeps: Option<SweepMonitor>,
    /// Drift probes are enabled: the sweep level test is left out (the probes see steps).
    probes_enabled: bool,
}

fn drift_alarm(ev: DriftEvent, source: &str, at: (Option<u64>, Option<f64>)) -> Alarm {
    match ev {
        DriftEvent::RateSignificant(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            "gain-drift",
            format!(
                "the gain drifts by {:+.2} %/h (± {:.2} %/h standard error, from {} {source}); beyond the tolerance",
                e.rate_pct_per_h, e.se_pct_per_h, e.pairs
            ),
        )
        .at(at.0, at.1)
        .with(json!({"rate_pct_per_h": e.rate_pct_per_h, "se_pct_per_h": e.se_pct_per_h, "n": e.pairs, "source": source})),
        DriftEvent::RateCleared(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            "gain-drift-cleared",
            format!(
                "the gain drift estimate is back within the tolerance: {:+.2} ± {:.2} %/h ({source})",
                e.rate_pct_per_h, e.se_pct_per_h
            ),
        )
        .at(at.0, at.1),
        DriftEvent::Step { direction, statistic, threshold, pairs_since_reset } => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            "gain-step",
            format!(
                "the gain stepped {}: the latest of the {source} departs from the trend of the previous {pairs_since_reset} by {statistic:.1} standard deviations (threshold {threshold})",
                if direction > 0 { "up" } else { "down" }
            ),
        )
        .at(at.0, at.1)
        .with(json!({"direction": direction, "statistic": statistic, "threshold": threshold, "source": source})),
    }
}

impl Checker {
    pub fn new(
        plan: SamplingPlan,
        rig: Rig,
        colour: ColourSettings,
        spec: CheckSpec,
        isotropic: bool,
        probes: ProbeSpec,
    ) -> Self {
        let n = plan.capture_count();
        let plan_dirs = plan.direction_count();
        let light_outer = !matches!(plan.order(), super::plan::AcquisitionOrder::CameraOuter);
        let sweeps = (isotropic && spec.sweeps.enabled && light_outer)
            .then(|| SweepMonitor::new(spec.sweeps.clone(), rig.clone(), plan_dirs));
        let probes_enabled = probes.every > 0;
        Checker {
            sweeps,
            probes_enabled,
            plan,
            rig,
            colour,
            spec,
            isotropic,
            by_entry: vec![None; n],
            classes: HashMap::new(),
            table2: Table2::default(),
            isotropy_table: Table2::default(),
            sorted_de2000: HashMap::new(),
            counts: CheckCounts::default(),
            consecutive_failures: 0,
            probes: ProbeDrift::new(probes),
            entry_seen: vec![false; n],
            seen_per_light: vec![0; plan_dirs],
            pending: Vec::new(),
            interpolated_table: Table2::default(),
            first_of_geometry: HashMap::new(),
            isotropy_drift: isotropic.then(|| {
                DriftDetector::new(DriftSpec {
                    // about 6,561 − 1,378 observations in a UBO run
                    run_pairs: 5200.0,
                    // rate only: consecutive observations share neighbouring geometry, so their
                    // residuals are correlated and heavy-tailed and the CUSUM's ARL design does
                    // not hold (measured: 1–3 false steps per fault-free realistic run even with
                    // per-geometry scales, and with medians of 81-capture batches); steps are
                    // the probes' job
                    step_detection: false,
                    ..DriftSpec::default()
                })
            }),
        }
    }

    /// The gain drift estimate from the probes, once there are enough.
    pub fn probe_drift(&self) -> Option<DriftEstimate> {
        self.probes.estimate()
    }

    /// The gain known now at time `t_h`, divided out of `xyz`.
    fn gain_correction(&self, t_h: f64, xyz: Xyz) -> Option<GainCorrected> {
        let (gain, sigma_rel, source) = if let Some((g, s)) = self.probes.gain_at(t_h) {
            (g, s, "probes")
        } else if self.counts.probes > 0 {
            // probes are in use but their segment is too short to fit (just after a step): the
            // isotropy rate would leave the step out, so nothing rather than a wrong correction
            return None;
        } else {
            // the rate and any steps the light sweeps found
            let (ln_g, sigma) = self.isotropy_drift.as_ref()?.ln_gain_at(t_h)?;
            (ln_g.exp(), sigma, "isotropy classes")
        };
        (gain > 0.0 && gain.is_finite()).then(|| GainCorrected {
            xyz: [xyz[0] / gain, xyz[1] / gain, xyz[2] / gain],
            gain,
            sigma_rel,
            source: source.into(),
        })
    }

    /// Gain steps in the isotropy drift model (found by the light sweeps).
    pub fn isotropy_steps(&self) -> Vec<super::drift::StepEffect> {
        self.isotropy_drift
            .as_ref()
            .map(|d| d.steps().to_vec())
            .unwrap_or_default()
    }

    /// The light-sweep checks' state (none when they do not run for this session).
    pub fn sweeps(&self) -> Option<super::sweeps::SweepSummary> {
        self.sweeps.as_ref().map(|m| m.summary())
    }

    /// The gain drift estimate from isotropy classes (isotropic samples), once there are enough.
    pub fn isotropy_drift(&self) -> Option<DriftEstimate> {
        self.isotropy_drift.as_ref().and_then(|d| d.estimate())
    }

    pub fn plan(&self) -> &SamplingPlan {
        &self.plan
    }
    pub fn table2(&self) -> &Table2 {
        &self.table2
    }
    pub fn isotropy_table(&self) -> &Table2 {
        &self.isotropy_table
    }
    /// Table 2 over the substitutes' interpolated pairs.
    pub fn interpolated_table(&self) -> &Table2 {
        &self.interpolated_table
    }
    pub fn counts(&self) -> &CheckCounts {
        &self.counts
    }

    fn nominal(&self, entry: usize, substitute: Option<f64>) -> Option<(Incidence, usize, usize)> {
        let e = self.plan.entry(entry).ok()?;
        let dirs = self.plan.directions();
        let (l, c) = (dirs[e.light], dirs[e.camera]);
        let theta_i = substitute.unwrap_or(l.theta_deg);
        Some((
            Incidence {
                omega_i: Spherical::from_deg(theta_i, l.phi_deg).to_vector(),
                omega_o: c.spherical().to_vector(),
            },
            e.light,
            e.camera,
        ))
    }

    fn xyz_of(&self, rgb: [f64; 3]) -> Xyz {
        let s = self.colour.rgb_scale;
        self.colour
            .to_xyz
            .convert([rgb[0] * s, rgb[1] * s, rgb[2] * s])
    }

    /// Check one capture. Captures must come in index order.
    pub fn check(&mut self, input: &CaptureInput) -> CheckOutput {
        let light = if input.probe {
            None
        } else {
            self.plan.entry(input.entry).ok().map(|e| e.light)
        };
        let mut out = self.check_capture(input);
        if let Some(light) = light {
            if let Some(seen) = self.entry_seen.get_mut(input.entry) {
                if !*seen {
                    *seen = true;
                    self.seen_per_light[light] += 1;
                    if self.seen_per_light[light] == self.plan.direction_count() {
                        let level_test = !self.probes_enabled;
                        if let Some(m) = self.sweeps.as_mut() {
                            let o = m.light_complete(light, level_test);
                            // a gain step the sweeps found becomes a step term of the isotropy
                            // drift model
                            if let (Some(det), Some(t)) =
                                (self.isotropy_drift.as_mut(), o.step_at_s)
                            {
                                det.add_step(t / 3600.0);
                            }
                            out.sweeps.extend(o.record);
                            self.counts.alarms += o.alarms.len() as u64;
                            out.alarms.extend(o.alarms);
                        }
                    }
                }
            }
        }
        // a pending partner is interpolated once its light direction is complete
        let complete = self.plan.direction_count();
        if self
            .pending
            .iter()
            .any(|p| self.seen_per_light[p.light] == complete)
        {
            let done = self.seen_per_light.clone();
            self.resolve_pending(|p| done[p.light] == complete, input.t, &mut out);
        }
        out
    }

    /// At the end of a session: the substitutes still waiting for their partner's light
    /// direction are interpolated from whatever was captured.
    pub fn finish(&mut self, t: f64) -> CheckOutput {
        let mut out = CheckOutput::default();
        self.resolve_pending(|_| true, t, &mut out);
        out
    }

    fn resolve_pending(
        &mut self,
        ready: impl Fn(&PendingPartner) -> bool,
        t: f64,
        out: &mut CheckOutput,
    ) {
        if self.pending.is_empty() {
            return;
        }
        let (ready, wait): (Vec<PendingPartner>, Vec<PendingPartner>) =
            std::mem::take(&mut self.pending)
                .into_iter()
                .partition(|p| ready(p));
        self.pending = wait;
        let mut slices: HashMap<usize, Result<Resampler, String>> = HashMap::new();
        for p in ready {
            let slice = slices
                .entry(p.light)
                .or_insert_with(|| self.slice_of(p.light));
            let pair = self.score_interpolated(&p, slice, t);
            if let (Some(d), "interpolated") = (&pair.diff, pair.status.as_str()) {
                self.interpolated_table.add(d);
            }
            self.feed_interpolated_to_drift(&p, &pair, out);
            if pair.status == "interpolated" {
                self.counts.pairs_interpolated += 1;
            } else {
                self.counts.pairs_unresolved += 1;
            }
            out.pairs.push(pair);
        }
    }

    /// An interpolated pair in the isotropy drift fit: the substitute against its partner
    /// interpolated at the mirrored pose, timed at the mean time of the partner light's
    /// captures, in a bucket of its own per (θ light, θ camera) so that the pair's stationary
    /// non-reciprocity is a fixed effect, and weighted by the interpolation's relative spread.
    fn feed_interpolated_to_drift(
        &mut self,
        p: &PendingPartner,
        pair: &PairRecord,
        out: &mut CheckOutput,
    ) {
        if self.isotropy_drift.is_none() || pair.status != "interpolated" {
            return;
        }
        let (Some(a), Some(b), Some(info)) = (pair.xyz_a, pair.xyz_b, &pair.interpolated) else {
            return;
        };
        let Some(spread) = info.spread_xyz else {
            return;
        };
        let Some(t_partner) = self.light_mean_time(p.light) else {
            return;
        };
        if !(a[1] > 0.0 && b[1] > 0.0) {
            return;
        }
        let Ok(pe) = self.plan.entry(p.entry) else {
            return;
        };
        let dirs = self.plan.directions();
        let bucket = (
            -1 - (dirs[pe.light].theta_deg * 1000.0).round() as i64,
            (dirs[pe.camera].theta_deg * 1000.0).round() as i64,
        );
        let (t_sub, t_par) = (p.capture.t / 3600.0, t_partner / 3600.0);
        // d = ln(Y later / Y earlier)
        let (t_a_h, t_b_h, d) = if t_sub <= t_par {
            (t_sub, t_par, (b[1] / a[1]).ln())
        } else {
            (t_par, t_sub, (a[1] / b[1]).ln())
        };
        let obs = PairObservation {
            t_a_h,
            t_b_h,
            d,
            bucket,
            sigma: (spread[1] / b[1]).abs(),
        };
        if !(obs.d.is_finite() && obs.sigma.is_finite()) {
            return;
        }
        let at = (Some(p.capture.idx), Some(p.capture.t));
        if let Some(det) = self.isotropy_drift.as_mut() {
            for ev in det.add(obs) {
                out.alarms.push(drift_alarm(ev, "isotropy classes", at));
                self.counts.alarms += 1;
            }
        }
        self.counts.drift_interpolated += 1;
    }

    /// The captures of one light direction that can be interpolation nodes: checked, at their
    /// exact pose, not dark, not occlusion substitutes.
    fn light_nodes(&self, light: usize) -> impl Iterator<Item = &Checked> + '_ {
        (0..self.plan.directions().len())
            .filter_map(move |c| self.plan.index_of(light, c))
            .filter_map(|e| self.by_entry.get(e).and_then(|c| c.as_ref()))
            .filter(|c| c.exact_pose && !c.dark && !c.substitute)
    }

    /// Mean controller time of a light direction's node captures.
    fn light_mean_time(&self, light: usize) -> Option<f64> {
        let (sum, n) = self
            .light_nodes(light)
            .fold((0.0, 0usize), |(s, n), c| (s + c.t, n + 1));
        (n > 0).then(|| sum / n as f64)
    }

    /// The session's captures of one light direction as a slice interpolant.
    fn slice_of(&self, light: usize) -> Result<Resampler, String> {
        let dirs = self.plan.directions();
        let omega_i = dirs
            .get(light)
            .ok_or_else(|| format!("no light direction {light}"))?
            .spherical()
            .to_vector();
        let samples: Vec<Sample> = self
            .light_nodes(light)
            .map(|c| Sample {
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                value: c.xyz,
            })
            .collect();
        Resampler::slice(&samples, &omega_i, &ResampleSpec::default()).map_err(|e| e.to_string())
    }

    fn score_interpolated(
        &self,
        p: &PendingPartner,
        slice: &Result<Resampler, String>,
        t: f64,
    ) -> PairRecord {
        let c = &p.capture;
        let light_dir = self.plan.directions()[p.light].spherical().to_vector();
        // the mirrored pose: the lamp where this capture's camera was, the camera where its lamp was
        let mismatch = angle_between(&light_dir, &c.omega_o).to_degrees();
        let mut rec = PairRecord {
            a: c.idx,
            b: c.idx,
            entries: [p.entry, p.entry],
            status: "unresolved".into(),
            mismatch_deg: mismatch,
            t,
            xyz_a: None,
            xyz_b: None,
            diff: None,
            interpolated: None,
        };
        let mut info = Interpolation {
            light: p.light,
            method: String::new(),
            nodes: 0,
            spread_xyz: None,
            sigma_de2000: None,
            error: None,
        };
        let resampled = match slice {
            Ok(r) => {
                info.method = r.method_name().into();
                info.nodes = r.nodes();
                r.at(&light_dir, &c.omega_i).map_err(|e| e.to_string())
            }
            Err(e) => Err(e.clone()),
        };
        match resampled {
            Err(e) => info.error = Some(e),
            Ok(v) => {
                let theta_l = Spherical::from_vector(&light_dir).theta_deg();
                match pair_residual(
                    c.xyz,
                    c.theta_i_deg,
                    v.value,
                    theta_l,
                    self.colour.white,
                    self.colour.min_cos,
                ) {
                    Ok(r) => {
                        // the spread in the units of the re-corrected partner (xyz_b): the
                        // cosine re-correction scales the partner by one factor
                        let f = if v.value[1] > 0.0 {
                            r.xyz2[1] / v.value[1]
                        } else {
                            1.0
                        };
                        let spread = [f * v.spread[0], f * v.spread[1], f * v.spread[2]];
                        let moved = [
                            r.xyz2[0] + spread[0],
                            r.xyz2[1] + spread[1],
                            r.xyz2[2] + spread[2],
                        ];
                        info.spread_xyz = Some(spread);
                        info.sigma_de2000 =
                            Some(colour_difference(r.xyz2, moved, self.colour.white).de2000);
                        rec.xyz_a = Some(r.xyz1);
                        rec.xyz_b = Some(r.xyz2);
                        rec.diff = Some(r.diff);
                        rec.status = "interpolated".into();
                    }
                    Err(e) => {
                        rec.status = match e {
                            PairError::Grazing { .. } => "grazing",
                            _ => "unresolved",
                        }
                        .into();
                        info.error = Some(e.to_string());
                    }
                }
            }
        }
        rec.interpolated = Some(info);
        rec
    }

    fn check_capture(&mut self, input: &CaptureInput) -> CheckOutput {
        let mut out = CheckOutput::default();
        self.counts.captures += 1;
        let at = (Some(input.idx), Some(input.t));
        let Some((nominal, light, camera)) = self.nominal(input.entry, input.substitute) else {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    "bad-entry",
                    format!(
                        "capture {} names plan entry {}, which is not in the {}-capture plan",
                        input.idx,
                        input.entry,
                        self.plan.capture_count()
                    ),
                )
                .at(at.0, at.1),
            );
            self.counts.alarms += out.alarms.len() as u64;
            return out;
        };
        let mut rec = CaptureRecord {
            idx: input.idx,
            entry: input.entry,
            light,
            camera,
            probe: input.probe,
            t: input.t,
            file: input.file.clone(),
            status: String::new(),
            error: None,
            mean_rgb: None,
            xyz: None,
            lab: None,
            pixels: None,
            nonfinite: None,
            clipped: None,
            negative: None,
            angles: None,
            substitute: input.substitute,
            pose_error_deg: None,
            gain_corrected: None,
        };
        if input.probe {
            self.counts.probes += 1;
        }

        // geometry from the encoder pose
        let measured = match self.rig.forward(&crate::measure::kinematics::Pose {
            joints_deg: [input.enc[0], input.enc[1], input.enc[2]],
            wagon_deg: input.enc[3],
        }) {
            Ok(m) => m,
            Err(e) => {
                out.alarms.push(
                    Alarm::new(
                        AlarmKind::Positioning,
                        Severity::Warning,
                        "bad-pose",
                        format!("capture {}: encoder pose {:?} unusable ({e}); the plan's pose is assumed", input.idx, input.enc),
                    )
                    .at(at.0, at.1),
                );
                nominal
            }
        };
        let pose_err = angle_between(&measured.omega_i, &nominal.omega_i)
            .max(angle_between(&measured.omega_o, &nominal.omega_o))
            .to_degrees();
        rec.angles = Some(measured.angles());
        rec.pose_error_deg = Some(pose_err);
        if pose_err > self.spec.pose_tolerance_deg {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Warning,
                    "pose-off-plan",
                    format!(
                        "capture {}: the encoders put the lamp/camera {:.3}° from plan entry {} (tolerance {}°)",
                        input.idx, pose_err, input.entry, self.spec.pose_tolerance_deg
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"pose_error_deg": pose_err, "enc": input.enc, "cmd": input.cmd})),
            );
        }
        let enc_err = (0..4)
            .map(|k| (input.enc[k] - input.cmd[k]).abs())
            .fold(0.0, f64::max);
        if enc_err > self.spec.encoder_tolerance_deg {
            let axis = (0..4)
                .max_by(|&a, &b| {
                    (input.enc[a] - input.cmd[a])
                        .abs()
                        .total_cmp(&(input.enc[b] - input.cmd[b]).abs())
                })
                .unwrap_or(0);
            let name = ["joint 1", "joint 2", "joint 3", "wagon"][axis];
            out.alarms.push(
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Warning,
                    "encoder-mismatch",
                    format!(
                        "capture {}: {name} encoder reads {:.4}° but {:.4}° was commanded (|Δ| {:.4}° > {}°)",
                        input.idx, input.enc[axis], input.cmd[axis], enc_err, self.spec.encoder_tolerance_deg
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"axis": name, "enc": input.enc, "cmd": input.cmd})),
            );
        }

        let stats = match &input.outcome {
            Outcome::Ok { stats, .. } => *stats,
            Outcome::Failed { error } | Outcome::Missing { reason: error } => {
                let missing = matches!(input.outcome, Outcome::Missing { .. });
                rec.status = if missing { "missing" } else { "failed" }.to_string();
                rec.error = Some(error.clone());
                if missing {
                    self.counts.missing += 1;
                } else {
                    self.counts.failed += 1;
                }
                self.consecutive_failures += 1;
                let critical = self.consecutive_failures >= self.spec.failures_critical;
                out.alarms.push(
                    Alarm::new(
                        AlarmKind::CaptureQuality,
                        if critical { Severity::Critical } else { Severity::Warning },
                        if missing { "missing-capture" } else { "capture-failed" },
                        format!(
                            "capture {} ({}) {}: {error}{}",
                            input.idx,
                            input.file,
                            if missing { "is missing" } else { "could not be used" },
                            if critical {
                                format!("; {} captures in a row have failed", self.consecutive_failures)
                            } else {
                                String::new()
                            }
                        ),
                    )
                    .at(at.0, at.1)
                    .with(json!({"file": input.file, "consecutive_failures": self.consecutive_failures})),
                );
                out.capture = Some(rec);
                self.counts.alarms += out.alarms.len() as u64;
                return out;
            }
        };
        self.consecutive_failures = 0;
        self.counts.ok += 1;
        let xyz = self.xyz_of(stats.mean_rgb);
        rec.status = "ok".into();
        rec.mean_rgb = Some(stats.mean_rgb);
        rec.xyz = Some(xyz);
        rec.lab = Some(xyz_to_lab(xyz, self.colour.white));
        rec.gain_corrected = self.gain_correction(input.t / 3600.0, xyz);
        rec.pixels = Some(stats.pixels);
        rec.nonfinite = Some(stats.nonfinite);
        rec.clipped = Some(stats.clipped);
        rec.negative = Some(stats.negative);

        // capture quality
        if stats.nonfinite > self.spec.nonfinite_max {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    "non-finite-pixels",
                    format!(
                        "capture {}: {} of {} pixels are NaN or infinite (allowed {}); they are left out of the mean",
                        input.idx, stats.nonfinite, stats.pixels, self.spec.nonfinite_max
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"nonfinite": stats.nonfinite, "pixels": stats.pixels})),
            );
        }
        let clipped_fraction = stats.clipped as f64 / stats.pixels.max(1) as f64;
        if clipped_fraction > self.spec.clipped_fraction_max {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    "clipped-pixels",
                    format!(
                        "capture {}: {:.2} % of the pixels are clipped (allowed {:.2} %)",
                        input.idx,
                        100.0 * clipped_fraction,
                        100.0 * self.spec.clipped_fraction_max
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"clipped": stats.clipped, "pixels": stats.pixels, "max_value": stats.max_value})),
            );
        }
        if xyz[1] <= self.spec.dark_y {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    "dark-capture",
                    format!(
                        "capture {}: mean Y = {:.4} is at or below the dark level {} (lamp off or shutter closed?)",
                        input.idx, xyz[1], self.spec.dark_y
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"y": xyz[1]})),
            );
        }
        let dark = xyz[1] <= self.spec.dark_y;

        if input.probe {
            // a probe re-captures its entry's pose: the luminance ratio is the gain change
            if !dark {
                if let Some(orig) = self.by_entry.get(input.entry).and_then(|c| c.as_ref()) {
                    let (t0, y0) = (orig.t, orig.xyz[1]);
                    for ev in self.probes.add(t0 / 3600.0, y0, input.t / 3600.0, xyz[1]) {
                        out.alarms.push(drift_alarm(ev, "probes", at));
                    }
                }
            }
            out.capture = Some(rec);
            self.counts.alarms += out.alarms.len() as u64;
            return out;
        }

        let exact_pose = pose_err <= self.spec.pair_tolerance_deg;
        let checked = Checked {
            idx: input.idx,
            t: input.t,
            xyz,
            theta_i_deg: Spherical::from_vector(&measured.omega_i).theta_deg(),
            omega_i: measured.omega_i,
            omega_o: measured.omega_o,
            exact_pose,
            dark,
            substitute: input.substitute.is_some(),
        };

        // a retake of an entry already checked is reported, not paired or classed again
        let retake = self
            .by_entry
            .get(input.entry)
            .map(|s| s.is_some())
            .unwrap_or(false);

        // an occlusion substitute's partner pose is off the grid: it is interpolated from the
        // captures of the partner's light direction once they are all in (only when needed: a
        // session without substitutes never builds an interpolant)
        if input.substitute.is_some() && !dark && !retake {
            self.pending.push(PendingPartner {
                capture: checked.clone(),
                entry: input.entry,
                light: camera,
            });
        }

        // reciprocal partner
        if let Ok(partner_entry) = self.plan.reciprocal_of(input.entry) {
            if partner_entry != input.entry && !dark && !retake {
                if let Some(p) = self
                    .by_entry
                    .get(partner_entry)
                    .and_then(|p| p.as_ref())
                    .filter(|p| !p.dark)
                {
                    let pair = self.score_pair(p, &checked, [partner_entry, input.entry], input.t);
                    if let Some(d) = &pair.diff {
                        if pair.status == "exact" {
                            self.table2.add(d);
                            if let Some(a) = self.outlier(d.de2000, &pair, at) {
                                out.alarms.push(a);
                            }
                        }
                    }
                    match pair.status.as_str() {
                        "exact" => self.counts.pairs_exact += 1,
                        "grazing" => self.counts.pairs_grazing += 1,
                        _ => self.counts.pairs_needs_resampling += 1,
                    }
                    out.pairs.push(pair);
                }
            }
        }

        // isotropy class (isotropic samples only; exact poses only)
        if self.isotropic && exact_pose && input.substitute.is_none() && !dark && !retake {
            if let Ok(e) = self.plan.entry(input.entry) {
                let key = self.plan.isotropy_key(&e);
                let c_lo = (key.theta_lo_mdeg as f64 / 1000.0).to_radians().cos();
                let c_hi = (key.theta_hi_mdeg as f64 / 1000.0).to_radians().cos();
                let ci = checked.theta_i_deg.to_radians().cos();
                if ci >= self.colour.min_cos && c_lo * c_hi > 0.0 {
                    let f = (c_lo * c_hi).sqrt() / ci;
                    let v = [xyz[0] * f, xyz[1] * f, xyz[2] * f];
                    let acc = self.classes.entry(key).or_default();
                    if acc.n > 0 {
                        let n = acc.n as f64;
                        let mean = [acc.sum[0] / n, acc.sum[1] / n, acc.sum[2] / n];
                        let diff = colour_difference(mean, v, self.colour.white);
                        self.isotropy_table.add(&diff);
                        self.counts.isotropy_comparisons += 1;
                        out.isotropy.push(IsotropyRecord {
                            idx: input.idx,
                            entry: input.entry,
                            class: [
                                key.theta_lo_mdeg as f64 / 1000.0,
                                key.theta_hi_mdeg as f64 / 1000.0,
                                key.dphi_mdeg as f64 / 1000.0,
                            ],
                            earlier_members: acc.n,
                            diff,
                        });
                    }
                    acc.n += 1;
                    for c in 0..3 {
                        acc.sum[c] += v[c];
                    }
                }
            }
        }

        // the same geometry captured earlier: a gain ratio free of geometric effects
        if self.isotropy_drift.is_some()
            && exact_pose
            && input.substitute.is_none()
            && !dark
            && !retake
            && xyz[1] > 0.0
        {
            let dirs = self.plan.directions();
            let (l, c) = (dirs[light], dirs[camera]);
            let dphi = if l.theta_deg == 0.0 || c.theta_deg == 0.0 {
                0.0
            } else {
                super::geometry::azimuth_difference_deg(l.phi_deg, c.phi_deg)
            };
            let key = (
                (l.theta_deg * 1000.0).round() as i64,
                (c.theta_deg * 1000.0).round() as i64,
                (dphi * 1000.0).round() as i64,
            );
            let t_h = input.t / 3600.0;
            match self.first_of_geometry.get(&key) {
                Some(&(t0, y0)) => {
                    let obs = PairObservation {
                        t_a_h: t0,
                        t_b_h: t_h,
                        d: (xyz[1] / y0).ln(),
                        bucket: (key.0, key.1),
                        sigma: 0.0,
                    };
                    if let Some(det) = self.isotropy_drift.as_mut() {
                        for ev in det.add(obs) {
                            out.alarms.push(drift_alarm(ev, "isotropy classes", at));
                        }
                    }
                }
                None => {
                    self.first_of_geometry.insert(key, (t_h, xyz[1]));
                }
            }
            if let Some(m) = self.sweeps.as_mut() {
                m.add(SweepCapture {
                    idx: input.idx,
                    t: input.t,
                    light,
                    camera,
                    class: key,
                    layer: key.0,
                    omega_i: nominal.omega_i,
                    omega_o: nominal.omega_o,
                    cmd: input.cmd,
                    y: xyz[1],
                });
            }
        }

        if let Some(slot) = self.by_entry.get_mut(input.entry) {
            if slot.is_none() {
                *slot = Some(checked);
            } else {
                out.alarms.push(
                    Alarm::new(
                        AlarmKind::CaptureQuality,
                        Severity::Info,
                        "entry-repeated",
                        format!(
                            "capture {} repeats plan entry {}; the first capture of it is kept for the checks",
                            input.idx, input.entry
                        ),
                    )
                    .at(at.0, at.1),
                );
            }
        }
        out.capture = Some(rec);
        self.counts.alarms += out.alarms.len() as u64;
        out
    }

    fn score_pair(
        &self,
        first: &Checked,
        second: &Checked,
        entries: [usize; 2],
        t: f64,
    ) -> PairRecord {
        let mismatch = angle_between(&first.omega_i, &second.omega_o)
            .max(angle_between(&first.omega_o, &second.omega_i))
            .to_degrees();
        let mut rec = PairRecord {
            a: first.idx,
            b: second.idx,
            entries,
            status: String::new(),
            mismatch_deg: mismatch,
            t,
            xyz_a: None,
            xyz_b: None,
            diff: None,
            interpolated: None,
        };
        match pair_residual(
            first.xyz,
            first.theta_i_deg,
            second.xyz,
            second.theta_i_deg,
            self.colour.white,
            self.colour.min_cos,
        ) {
            Ok(r) => {
                rec.xyz_a = Some(r.xyz1);
                rec.xyz_b = Some(r.xyz2);
                rec.diff = Some(r.diff);
                let exact = mismatch <= self.spec.pair_tolerance_deg
                    && first.exact_pose
                    && second.exact_pose;
                rec.status = if exact { "exact" } else { "needs-resampling" }.into();
            }
            Err(PairError::Grazing { .. }) | Err(PairError::NotFinite(_)) => {
                rec.status = "grazing".into()
            }
        }
        rec
    }

    fn outlier(
        &mut self,
        de: f64,
        pair: &PairRecord,
        at: (Option<u64>, Option<f64>),
    ) -> Option<Alarm> {
        let bucket = self
            .plan
            .entry(pair.entries[0])
            .map(|e| {
                let k = self.plan.isotropy_key(&e);
                (k.theta_lo_mdeg, k.theta_hi_mdeg)
            })
            .unwrap_or((0, 0));
        let spec = self.spec.clone();
        let sorted = self.sorted_de2000.entry(bucket).or_default();
        let pos = sorted.partition_point(|v| *v < de);
        let n = sorted.len();
        let result = if n >= spec.outlier_min_pairs {
            let med = median_sorted(sorted);
            let mut dev: Vec<f64> = sorted.iter().map(|v| (v - med).abs()).collect();
            dev.sort_by(f64::total_cmp);
            let mad = median_sorted(&dev);
            let limit = (med + spec.outlier_k * 1.4826 * mad).max(spec.outlier_floor_de2000);
            (de > limit).then(|| {
                Alarm::new(
                    AlarmKind::ReciprocityOutlier,
                    Severity::Warning,
                    "reciprocity-outlier",
                    format!(
                        "pair of captures {} and {} (entries {} ↔ {}) differs by ΔE00 = {:.2}, above the limit {:.2} (median {:.2} + {}·MAD over {} pairs at θ {}°/{}°)",
                        pair.a,
                        pair.b,
                        pair.entries[0],
                        pair.entries[1],
                        de,
                        limit,
                        med,
                        spec.outlier_k,
                        n,
                        bucket.0 as f64 / 1000.0,
                        bucket.1 as f64 / 1000.0
                    ),
                )
                .at(at.0, at.1)
                .with(json!({"de2000": de, "limit": limit, "median": med, "mad": mad, "pairs": n, "a": pair.a, "b": pair.b, "theta_pair_deg": [bucket.0 as f64 / 1000.0, bucket.1 as f64 / 1000.0]}))
            })
        } else {
            None
        };
        sorted.insert(pos, de);
        result
    }
}

fn median_sorted(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::colour::RgbPrimaries;
    use crate::measure::kinematics::RigSpec;

    /// A reciprocal, smooth BRDF (RGB), times cos θi: what an ideal rig would average.
    fn reading(wi: &Vec3, wo: &Vec3) -> [f64; 3] {
        let h = (wi + wo).normalize();
        let lobe = 0.6 * h.z.powi(40);
        let f = [0.40 + lobe, 0.34 + lobe, 0.25 + lobe];
        [f[0] * wi.z, f[1] * wi.z, f[2] * wi.z]
    }

    fn checker() -> Checker {
        let colour = ColourSettings {
            to_xyz: RgbToXyz::new(RgbPrimaries::SrgbIec),
            rgb_scale: 100.0,
            white: White::d65_scaled(100.0).unwrap(),
            min_cos: 1e-3,
        };
        Checker::new(
            SamplingPlan::ubo(),
            Rig::new(RigSpec::default()).unwrap(),
            colour,
            CheckSpec::default(),
            true,
            ProbeSpec::default(),
        )
    }

    /// The captures of the UBO plan in light-outer order, as the rig would take them.
    fn session(upto: usize) -> Vec<CaptureInput> {
        session_with_gain(upto, |_| 1.0)
    }

    fn session_with_gain(upto: usize, gain: impl Fn(f64) -> f64) -> Vec<CaptureInput> {
        let plan = SamplingPlan::ubo();
        let rig = Rig::new(RigSpec::default()).unwrap();
        (0..upto)
            .map(|idx| {
                let e = plan.entry(idx).unwrap();
                let d = plan.directions();
                let pp = rig
                    .plan_pose(d[e.light].spherical(), d[e.camera].spherical())
                    .unwrap();
                let r = [
                    pp.pose.joints_deg[0],
                    pp.pose.joints_deg[1],
                    pp.pose.joints_deg[2],
                    pp.pose.wagon_deg,
                ];
                CaptureInput {
                    idx: idx as u64,
                    entry: idx,
                    file: format!("c{idx}.hdr"),
                    t: idx as f64 * 7.0,
                    cmd: r,
                    enc: r,
                    substitute: pp.substitute.map(|s| s.1),
                    probe: false,
                    outcome: Outcome::Ok {
                        stats: CaptureStats {
                            mean_rgb: reading(&pp.used.omega_i, &pp.used.omega_o)
                                .map(|v| v * gain(idx as f64 * 7.0 / 3600.0)),
                            pixels: 100,
                            nonfinite: 0,
                            negative: 0,
                            clipped: 0,
                            dark: 0,
                            max_value: 1.0,
                        },
                        width: 10,
                        height: 10,
                        size: 1,
                        sha256: String::new(),
                    },
                }
            })
            .collect()
    }

    #[test]
    fn substitutes_are_paired_with_an_interpolated_partner_once_its_light_is_complete() {
        let mut ch = checker();
        let mut interpolated = Vec::new();
        for (k, input) in session(6561).iter().enumerate() {
            let out = ch.check(input);
            for p in out.pairs.into_iter().filter(|p| p.interpolated.is_some()) {
                // light-outer order: the substitute (ℓ, ℓ) waits for the end of light ℓ's sweep
                assert_eq!((k + 1) % 81, 0, "resolved at capture {k}");
                interpolated.push(p);
            }
        }
        assert!(ch.finish(0.0).pairs.is_empty());
        // every direction but the pole has a substitute (the pole's partner is itself)
        assert_eq!(ch.counts().pairs_unresolved, 0);
        assert_eq!(interpolated.len() as u64, ch.counts().pairs_interpolated);
        assert!(interpolated.len() >= 80, "{}", interpolated.len());
        // each went into the isotropy drift fit, weighted by its spread
        assert_eq!(
            ch.counts().drift_interpolated,
            ch.counts().pairs_interpolated
        );
        assert!(ch.isotropy_drift().unwrap().rate_pct_per_h.abs() < 0.01);
        let mut worst: f64 = 0.0;
        let mut beyond = 0;
        for p in &interpolated {
            assert_eq!(p.status, "interpolated");
            let i = p.interpolated.as_ref().unwrap();
            assert!(i.nodes >= 79 && i.method == "cshep2d", "{i:?}");
            let sigma = i.sigma_de2000.unwrap();
            assert!(sigma.is_finite() && sigma >= 0.0);
            worst = worst.max(p.diff.as_ref().unwrap().de2000);
            // the spread is an uncertainty estimate, not a bound: count the pairs beyond 3σ
            let de = p.diff.as_ref().unwrap().de2000;
            if de > 3.0 * sigma + 0.05 {
                beyond += 1;
            }
        }
        // a reciprocal BRDF: the only difference is the interpolation's error (measured: worst
        // 1.38 ΔE00 at a 30° light, where the 15° grid barely resolves this lobe; median < 0.1)
        assert!(worst < 2.0, "worst ΔE00 {worst}");
        // measured: 4 of 81 beyond 3σ + 0.05 (the nodal spread underestimates the error next
        // to the retro-reflection hole, where the lobe peaks between nodes)
        assert!(
            beyond * 10 <= interpolated.len(),
            "{beyond} of {} beyond 3σ",
            interpolated.len()
        );
        assert!(ch.interpolated_table().pairs >= 80);
        // exact pairs are untouched by all this
        assert_eq!(ch.counts().pairs_exact, 3240);
    }

    #[test]
    fn a_session_cut_short_interpolates_what_it_has_at_the_end() {
        let mut ch = checker();
        // light 0 (the pole) complete, light 1 cut after 40 of its 81 cameras
        let inputs = session(81 + 40);
        let mut during = 0;
        for input in &inputs {
            during += ch
                .check(input)
                .pairs
                .iter()
                .filter(|p| p.interpolated.is_some())
                .count();
        }
        let end = ch.finish(1000.0);
        let resolved: Vec<_> = end
            .pairs
            .iter()
            .filter(|p| p.interpolated.is_some())
            .collect();
        assert_eq!(
            during + resolved.len(),
            (ch.counts().pairs_interpolated + ch.counts().pairs_unresolved) as usize
        );
        for p in &resolved {
            let i = p.interpolated.as_ref().unwrap();
            if p.status == "interpolated" {
                assert!(i.nodes < 81);
            } else {
                assert!(i.error.is_some(), "{p:?}");
            }
            assert_eq!(p.t, 1000.0);
        }
        // nothing is resolved twice
        assert!(ch.finish(2000.0).pairs.is_empty());
    }

    #[test]
    fn a_session_without_substitutes_builds_no_interpolant() {
        // a rig that can put the camera anywhere: no substitutes, no interpolated pairs
        let mut ch = checker();
        ch.rig = Rig::new(RigSpec {
            min_separation_deg: 0.0,
            ..RigSpec::default()
        })
        .unwrap();
        for mut input in session(200) {
            input.substitute = None;
            let _ = ch.check(&input);
        }
        assert_eq!(
            ch.counts().pairs_interpolated + ch.counts().pairs_unresolved,
            0
        );
        assert!(ch.pending.is_empty());
    }

    #[test]
    fn isotropy_classes_give_the_drift_rate_and_the_corrected_colour() {
        // −1 %/h exponential decay over 3,000 captures (5.8 h)
        let mut ch = checker();
        let mut alarms = Vec::new();
        let mut last = None;
        for input in session_with_gain(3000, |t| (-0.01 * t).exp()) {
            let out = ch.check(&input);
            alarms.extend(out.alarms.into_iter().filter(|a| a.code == "gain-drift"));
            last = out.capture;
        }
        let e = ch.isotropy_drift().unwrap();
        assert!((e.rate_pct_per_h + 1.0).abs() < 0.01, "{e:?}");
        assert_eq!(alarms.len(), 1, "{alarms:?}");
        assert!(alarms[0].message.contains("isotropy classes"));
        // the last capture's colour with the drift divided out is the undrifted colour
        let c = last.unwrap();
        let g = c.gain_corrected.unwrap();
        assert_eq!(g.source, "isotropy classes");
        let t_h = c.t / 3600.0;
        assert!((g.gain - (-0.01 * t_h).exp()).abs() < 1e-3, "{g:?}");
        assert!(g.sigma_rel >= 0.0 && g.sigma_rel < 0.01);
        assert!((g.xyz[1] - c.xyz.unwrap()[1] / g.gain).abs() < 1e-12);

        // no drift: an estimate near 0, no alarm
        let mut quiet = checker();
        let mut n = 0;
        for input in session(3000) {
            n += quiet
                .check(&input)
                .alarms
                .iter()
                .filter(|a| a.code.starts_with("gain"))
                .count();
        }
        assert_eq!(n, 0);
        assert!(quiet.isotropy_drift().unwrap().rate_pct_per_h.abs() < 0.01);
    }

    #[test]
    fn an_anisotropic_sample_gets_no_isotropy_terms() {
        let mut ch = checker();
        ch.isotropic = false;
        ch.isotropy_drift = None;
        for input in session_with_gain(1500, |t| (-0.05 * t).exp()) {
            let out = ch.check(&input);
            assert!(out.isotropy.is_empty());
            assert!(out.capture.unwrap().gain_corrected.is_none());
        }
        assert!(ch.isotropy_drift().is_none());
        assert_eq!(ch.counts().isotropy_comparisons, 0);
    }

    #[test]
    fn light_sweeps_run_only_where_they_mean_something() {
        use super::super::plan::{AcquisitionOrder, PlanSpec};
        let colour = || checker().colour.clone();
        let make = |isotropic: bool, order: AcquisitionOrder, enabled: bool| {
            let mut spec = CheckSpec::default();
            spec.sweeps.enabled = enabled;
            Checker::new(
                SamplingPlan::new(&PlanSpec {
                    order,
                    ..PlanSpec::default()
                })
                .unwrap(),
                Rig::new(RigSpec::default()).unwrap(),
                colour(),
                spec,
                isotropic,
                ProbeSpec::default(),
            )
        };
        assert!(make(true, AcquisitionOrder::LightOuter, true)
            .sweeps
            .is_some());
        assert!(make(true, AcquisitionOrder::LightOuterSerpentine, true)
            .sweeps
            .is_some());
        // an anisotropic sample has no isotropy classes to compare sweeps by
        assert!(make(false, AcquisitionOrder::LightOuter, true)
            .sweeps
            .is_none());
        // camera-outer: a light direction completes only at the end of the run
        assert!(make(true, AcquisitionOrder::CameraOuter, true)
            .sweeps
            .is_none());
        assert!(make(true, AcquisitionOrder::LightOuter, false)
            .sweeps
            .is_none());

        // on an isotropic light-outer session every completed light gives a sweep record
        let mut ch = checker();
        let mut records = Vec::new();
        for input in session(20 * 81) {
            records.extend(ch.check(&input).sweeps);
        }
        assert!(records.len() >= 15, "{}", records.len());
        assert!(records.windows(2).all(|w| w[0].idx < w[1].idx));
    }

    #[test]
    fn a_step_found_by_the_sweeps_enters_the_gain_correction() {
        // −3 % from capture 2,000 (inside light sweep 24), no drift otherwise
        let t_step = 2000.0 * 7.0;
        let mut ch = checker();
        let mut steps = Vec::new();
        let mut last = None;
        for input in session_with_gain(2600, |t_h| if t_h * 3600.0 >= t_step { 0.97 } else { 1.0 })
        {
            let out = ch.check(&input);
            steps.extend(out.alarms.into_iter().filter(|a| a.code == "gain-step"));
            last = out.capture;
        }
        assert_eq!(steps.len(), 1, "{steps:?}");
        let since_t = steps[0].evidence["since_t"].as_f64().unwrap();
        assert!(
            since_t <= t_step && since_t > t_step - 81.0 * 7.0,
            "{since_t}"
        );
        let det = ch.isotropy_drift.as_ref().unwrap();
        let st = det.steps()[0];
        assert!((st.ln_size - 0.97f64.ln()).abs() < 0.005, "{st:?}");
        assert!(ch.isotropy_drift().unwrap().rate_pct_per_h.abs() < 0.05);
        // the last capture's correction carries the step
        let g = last.unwrap().gain_corrected.unwrap();
        assert!((g.gain - 0.97).abs() < 0.005, "{g:?}");
    }
}
