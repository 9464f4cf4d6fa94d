//! Temporal gain drift from pairs of captures: a rate fit with geometry fixed effects and a CUSUM.
//! Wired in with *isotropy-class* observations (`Checker`: each capture against the first
//! capture of the same (θi, θo, |Δφ|)), rate only. It is not fed with reciprocal pairs, because:
//!
//! - The realistic non-reciprocity depends on the light direction (footprint) and the camera
//!   direction (holder bleed) separately, so a pair's nuisance is v(c) − v(ℓ) for the capture
//!   (ℓ, c) and its mirror (c, ℓ). In light-outer order t(ℓ, c) = (81ℓ + c)·T, so a pair's time
//!   difference is 80(c − ℓ)·T: a *linear* drift r·Δt = F(c) − F(ℓ) has exactly that form.
//!   Reciprocal pairs alone cannot separate a linear drift from per-direction non-reciprocity in
//!   this order; only non-linear gain changes (steps, curvature) are identifiable from them.
//!   The θ-bucket model below also leaves azimuth-dependent effects in the residuals, which are
//!   strongly correlated between consecutive pairs, so a rate and a CUSUM on them are biased and
//!   overconfident (docs/detectors.md).
//! - What breaks the confounding: isotropy classes (same geometry, different directions and
//!   times), drift probes (re-captures of one pose), or an acquisition order whose times are not
//!   a function of the direction indices alone. The estimators are built on those.
//!
//! Each exact pair (a earlier, b later) gives d = ln(Y′_b / Y′_a) of the re-corrected luminances.
//! With a lamp gain g(t), d = ln g(t_b) − ln g(t_a) + ν + ε, where ν is the pair's stationary,
//! geometry-dependent non-reciprocity (border and footprint effects) and ε the noise. The model:
//!
//! - ln g(t) = r · t (t in hours): one drift rate r;
//! - ν = β_bucket: a fixed effect per ordered geometry bucket (θ of a's light, θ of a's camera), so
//!   that the systematic non-reciprocity of a geometry cannot masquerade as drift. r is identified
//!   by the spread of t_b − t_a within each bucket.
//!
//! The fit is weighted least squares with Huber weights (iteratively reweighted, residual scale
//! from the MAD), recomputed every `refit_every` pairs on all pairs so far (n ≤ 3,240; a refit is
//! O(n)). Deterministic: fixed iteration count and order.
//!
//! A sample that does not sit on the arm's rotation centre (off-centre, or raised above it) breaks
//! the isotropy the classes rely on: the lamp's spot and the camera's view move across it with
//! the *absolute* azimuths, so members of one class differ by a stationary pattern that
//! light-outer order turns into a trend. To first order the pattern is linear in the directions'
//! gnomonic coordinates g(ω) = (ωx/ωz, ωy/ωz) = tan θ·(cos φ, sin φ), one vector for the light and
//! one for the camera (`mount_coordinates`). The camera's half is identified within every light
//! sweep, free of the gain; the light's half only across sweeps, partly confounded with a rate,
//! so the four terms cost precision and enter the model only once the camera's half is
//! significant and larger than `mount_min_pct` per unit tan θ (`MountPattern`, latched).
//!
//! Change detection: two-sided CUSUM on the standardized residuals of new pairs (clipped at ±4),
//! reference k = 0.5 and threshold h designed from the average run length (Siegmund's
//! approximation) so that a whole 3,240-pair run raises a false alarm in at most 1 of
//! `false_alarm_runs` runs.

use crate::measure::geometry::Vec3;
use crate::measure::stats::{cusum_threshold, robust_scale_upper};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

mod fit;
use fit::*;
#[cfg(test)]
mod tests;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct DriftSpec {
    /// Alarm when the drift rate is significant and its size exceeds this (%/h).
    pub rate_tolerance_pct_per_h: f64,
    /// Two-sided confidence for "significant" (z of the normal distribution).
    pub z: f64,
    /// Refit the rate every this many new pairs.
    pub refit_every: usize,
    /// Pairs needed before the rate is reported.
    pub min_pairs: usize,
    /// CUSUM reference value k (in residual standard deviations).
    pub cusum_k: f64,
    /// Pairs before the CUSUM starts (the fit and its residual scale must settle first).
    pub cusum_burn_in: usize,
    /// The CUSUM is designed for at most one false alarm in this many runs of `run_pairs` pairs.
    pub false_alarm_runs: f64,
    pub run_pairs: f64,
    /// Run the CUSUM step detector (off where the observations are too correlated in time for
    /// its ARL design to hold; see `Checker`'s isotropy source).
    #[serde(default = "yes")]
    pub step_detection: bool,
    /// Test for the off-centre mount's azimuthal pattern and model it once found (isotropy
    /// classes; a single-pose source has no such pattern).
    #[serde(default)]
    pub mount_terms: bool,
    /// The camera-side pattern enters the model when its amplitude, less z standard errors,
    /// exceeds this (% of luminance per unit tan θ).
    #[serde(default = "mount_min_pct")]
    pub mount_min_pct: f64,
    /// The residual scale the rate's standard error assumes is at least this (ln units): a
    /// source whose scatter is known (the probes' design scatter) keeps a fit of a few
    /// observations from judging its rate by a scale that happens to be small.
    #[serde(skip)]
    pub scale_floor: f64,
    /// Before a rate alarm, ask whether a stationary light-side pattern could make the trend
    /// (`DriftDetector::pattern_robust`): the alarm is raised only when the rate stays
    /// significant beside such a pattern, and an `Unresolved` advisory says so otherwise.
    #[serde(default)]
    pub pattern_check: bool,
}

fn mount_min_pct() -> f64 {
    0.5
}

fn yes() -> bool {
    true
}

impl Default for DriftSpec {
    fn default() -> Self {
        DriftSpec {
            rate_tolerance_pct_per_h: 0.25,
            z: 4.0,
            refit_every: 20,
            min_pairs: 200,
            cusum_k: 0.5,
            cusum_burn_in: 400,
            false_alarm_runs: 20.0,
            run_pairs: 3240.0,
            step_detection: true,
            mount_terms: false,
            mount_min_pct: mount_min_pct(),
            scale_floor: 0.0,
            pattern_check: false,
        }
    }
}

/// A bucket's effect must rest on this many pairs before its new pairs feed the CUSUM.
const MIN_BUCKET_PAIRS: usize = 8;

/// The isotropy rate alarm's rule: raised when the rate is significant, `|rate| > z·se` (z
/// guards the repeated looks of a whole run), and its estimate is beyond `tolerance`, the
/// smallest rate worth an alarm. This fit rests on hundreds to thousands of comparisons, so its
/// standard error is itself well determined and a z test on it keeps its false-alarm rate;
/// asking the lower confidence bound to clear the tolerance as well would ask twice for the same
/// certainty (a rate of twice the tolerance would be held back until its standard error is an
/// eighth of the rate, where the z test alone needs a quarter). The probes' rate keeps that
/// stricter rule (`probes::ProbeDrift`): a segment's fit rests on a few probes, whose standard
/// error is uncertain in its turn. So does the colour alarm (`lamp::CctRate::exceeds`), one rule for
/// both its sources, which `plan` simulates on the probes.
fn rate_alarm_raised(rate: f64, se: f64, tolerance: f64, z: f64) -> bool {
    rate.abs() > z * se && rate.abs() > tolerance
}

/// The clearing rule: the rate is within `tolerance` by `z` standard errors (the hysteresis
/// keeps one alarm from chattering about the tolerance).
fn rate_alarm_cleared(rate: f64, se: f64, tolerance: f64, z: f64) -> bool {
    rate.abs() + z * se < tolerance
}

/// One observation: a pair's log luminance ratio between its two capture times.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(crate) struct PairObservation {
    pub t_a_h: f64,
    pub t_b_h: f64,
    pub d: f64,
    pub bucket: (i64, i64),
    /// Extra standard uncertainty of `d` beyond the residual scale (ln units), e.g. an
    /// interpolated partner's spread; 0 for a measured pair. The fit weights the observation by
    /// 1 / (1 + (sigma / scale)²) on top of its Huber weight.
    #[serde(default)]
    pub sigma: f64,
    /// `mount_coordinates` of the later capture less those of the earlier one (0 where the
    /// source has no such pattern).
    #[serde(default)]
    pub mount: [f64; 4],
    /// The light's azimuth in the sample frame (radians) of the earlier and of the later
    /// capture, for the stationary light-side pattern of `pattern_check` (0 where unknown: the
    /// pattern's columns are then 0).
    #[serde(default)]
    pub light_az: [f64; 2],
}

/// The gnomonic coordinates (tan θ·cos φ, tan θ·sin φ) of the light and of the camera direction
/// (sample frame): the off-centre mount's pattern is linear in them. θ is capped at 85°.
pub(crate) fn mount_coordinates(omega_i: &Vec3, omega_o: &Vec3) -> [f64; 4] {
    let g = |w: &Vec3| {
        let z = w.z.max(MOUNT_MIN_COS);
        [w.x / z, w.y / z]
    };
    let (a, b) = (g(omega_i), g(omega_o));
    let v = [a[0], a[1], b[0], b[1]];
    if v.iter().all(|x| x.is_finite()) {
        v
    } else {
        [0.0; 4]
    }
}

/// The light's half of the mount pattern and a rate are confounded until the light has turned
/// through most of a θ layer: while it widens the rate's standard error more than this many
/// times, the rate is not alarmed (that standard error, from correlated residuals, is
/// optimistic, and the two are then traded against each other).
const MAX_RATE_INFLATION: f64 = 2.0;

/// cos 85°: the gnomonic coordinates grow without bound at grazing directions.
const MOUNT_MIN_COS: f64 = 0.087_155_742_747_658_17;

/// The off-centre mount's azimuthal pattern as fitted: ln-luminance per unit of each gnomonic
/// coordinate, light side and camera side, with the larger standard error of each pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MountPattern {
    pub light: [f64; 2],
    pub light_se: f64,
    pub camera: [f64; 2],
    pub camera_se: f64,
    /// How many times the light's half widens the rate's standard error: large until the light
    /// has turned through a θ layer, when the two can be told apart.
    pub rate_inflation: f64,
}

impl MountPattern {
    /// The pattern's ln-luminance at the gnomonic coordinates `m` (`mount_coordinates`).
    pub(crate) fn ln_effect(&self, m: &[f64; 4]) -> f64 {
        self.light[0] * m[0] + self.light[1] * m[1] + self.camera[0] * m[2] + self.camera[1] * m[3]
    }

    /// Whether the light's half is told apart from a rate in this fit.
    pub(crate) fn light_separated(&self) -> bool {
        self.rate_inflation <= MAX_RATE_INFLATION
    }

    /// Amplitude (% per unit tan θ) and the azimuth it points to (degrees), light side.
    pub(crate) fn light_pct(&self) -> (f64, f64) {
        polar(self.light)
    }

    /// Amplitude (% per unit tan θ) and the azimuth it points to (degrees), camera side.
    pub(crate) fn camera_pct(&self) -> (f64, f64) {
        polar(self.camera)
    }
}

fn polar(v: [f64; 2]) -> (f64, f64) {
    (
        100.0 * v[0].hypot(v[1]),
        v[1].atan2(v[0]).to_degrees().rem_euclid(360.0),
    )
}

/// A fitted gain path: ln g(t) = r·t + Σ s_k·[t ≥ τ_k] (t in hours).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GainPath {
    pub rate_per_h: f64,
    /// (τ_k in hours, s_k in ln units)
    pub steps: Vec<(f64, f64)>,
}

impl GainPath {
    /// ln g at `t_s` controller seconds (0 where it is not finite).
    pub(crate) fn ln_at(&self, t_s: f64) -> f64 {
        let v = self.ln_at_h(t_s / 3600.0);
        if v.is_finite() {
            v
        } else {
            0.0
        }
    }

    /// ln g at `t_h` hours.
    pub(crate) fn ln_at_h(&self, t_h: f64) -> f64 {
        let steps: f64 = self
            .steps
            .iter()
            .filter(|(t, _)| *t <= t_h)
            .map(|(_, s)| s)
            .sum();
        self.rate_per_h * t_h + steps
    }
}

/// The current drift estimate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct DriftEstimate {
    pub pairs: usize,
    /// Drift rate of the gain in %/h (100 · r; ln-gain per hour is r).
    pub rate_pct_per_h: f64,
    /// Standard error of the rate (%/h).
    pub se_pct_per_h: f64,
    /// Robust residual scale (ln units).
    pub residual_scale: f64,
}

/// A known gain step (its time found elsewhere, e.g. by the light sweeps) and its fitted size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepEffect {
    /// When the step happened (controller hours; pairs spanning it carry it).
    pub t_h: f64,
    /// ln of the gain ratio across the step, and its standard error.
    pub ln_size: f64,
    pub se: f64,
}

/// What the detector says after one pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(crate) enum DriftEvent {
    /// The rate became significant and larger than the tolerance.
    RateSignificant(DriftEstimate),
    /// The rate is back within the tolerance (hysteresis re-arm).
    RateCleared(DriftEstimate),
    /// The CUSUM crossed its threshold: a step in the gain. `direction` is +1 (brighter) or −1.
    Step {
        direction: i8,
        statistic: f64,
        threshold: f64,
        pairs_since_reset: usize,
    },
    /// (Probes) the capture-to-capture scatter of the lamp, as the robust scale of the current
    /// segment's residuals, exceeds the scatter the probe plan was designed for by
    /// `UNSTABLE_FACTOR`: an unstable lamp (flicker, a loose contact) or a noisy probe pose.
    Unstable {
        scatter: f64,
        design: f64,
        probes: usize,
        /// The first probe of the window judged.
        from_idx: u64,
    },
    /// The off-centre mount's pattern is significant and large (once per session): from now on
    /// it is part of the model.
    MountPattern(MountPattern),
    /// (`pattern_check`) The rate is significant, but a stationary light-side pattern could
    /// make the same trend in this acquisition order: no alarm (once per session, until the
    /// rate is confirmed or cleared). `robust` is the rate fitted beside that pattern.
    Unresolved {
        estimate: DriftEstimate,
        robust: DriftEstimate,
    },
    /// (Probes) the scatter is back under `UNSTABLE_CLEAR_FACTOR` times the design.
    UnstableCleared {
        scatter: f64,
        design: f64,
        probes: usize,
    },
}

#[derive(Debug, Clone)]
pub(crate) struct DriftDetector {
    spec: DriftSpec,
    obs: Vec<PairObservation>,
    /// The observations' buckets.
    index: BucketIndex,
    estimate: Option<DriftEstimate>,
    /// Bucket effects and bucket sizes from the last fit.
    beta: BTreeMap<(i64, i64), (f64, usize)>,
    /// Robust residual scale per bucket (MAD), for standardizing new observations: geometries
    /// differ in their noise by several times, and one global scale makes the noisy ones fire.
    bucket_scale: BTreeMap<(i64, i64), f64>,
    rate_alarm: bool,
    cusum_hi: f64,
    cusum_lo: f64,
    cusum_n: usize,
    h: f64,
    /// Known step times (hours) and, after a fit, their sizes.
    step_times: Vec<f64>,
    step_effects: Vec<StepEffect>,
    /// The off-centre mount's pattern, once found (then part of every fit).
    mount: Option<MountPattern>,
    /// Whether the light's half of the pattern has been told apart from the rate (latched);
    /// until then the rate is not alarmed.
    light_separated: bool,
    /// The first time (hours) from which the pose is known to have changed (a named joint
    /// slip): pairs whose later capture is at or after it are left out of the model.
    pose_break: Option<f64>,
    /// Pairs left out for that.
    pub(crate) left_out: usize,
    /// Whether this source raises rate alarms (off while another source is the lamp's watch).
    rate_alarms: bool,
    /// The pair count at the last `pattern_robust` fit, and its verdict.
    pattern_checked: Option<(usize, bool)>,
    /// Whether the `Unresolved` advisory has been given.
    unresolved_said: bool,
}

impl DriftDetector {
    pub(crate) fn new(spec: DriftSpec) -> Self {
        let h = cusum_threshold(spec.cusum_k, spec.false_alarm_runs * spec.run_pairs);
        DriftDetector {
            spec,
            obs: Vec::new(),
            index: BucketIndex::default(),
            estimate: None,
            beta: BTreeMap::new(),
            bucket_scale: BTreeMap::new(),
            rate_alarm: false,
            cusum_hi: 0.0,
            cusum_lo: 0.0,
            cusum_n: 0,
            h,
            step_times: Vec::new(),
            step_effects: Vec::new(),
            mount: None,
            light_separated: false,
            pose_break: None,
            left_out: 0,
            rate_alarms: true,
            pattern_checked: None,
            unresolved_said: false,
        }
    }

    /// Whether this source raises rate alarms. Off while the probes are the lamp's watch (a
    /// re-capture of one pose sees no stationary pattern of the geometry, where this source's
    /// classes do); the fit goes on for the corrections. Turned back on (the rig refused the
    /// probes), the next refit raises what is significant then.
    pub(crate) fn set_rate_alarms(&mut self, on: bool) {
        self.rate_alarms = on;
    }

    /// The pose changed at `t_h` (hours; a named joint slip, placed at the start of the light
    /// sweep before the first that showed it): pairs whose later capture comes at or after it
    /// are taken out of the model, now and as they come. Not only the pairs across the slip
    /// carry it: two members of an isotropy class sit at different absolute azimuths, which a
    /// tilt moves differently, so pairs wholly after it do too. The model keeps the drift it
    /// had learnt before the slip (its rate and steps extrapolate) until the session ends; the
    /// light sweeps still watch the gain's level. An earlier break than the one held moves it.
    /// Returns the rate alarm's change, if the refit without those pairs makes one: no later
    /// pair refits the model again.
    pub(crate) fn add_pose_break(&mut self, t_h: f64) -> Vec<DriftEvent> {
        if !t_h.is_finite() || self.pose_break.is_some_and(|t| t <= t_h) {
            return Vec::new();
        }
        self.pose_break = Some(t_h);
        let before = self.obs.len();
        self.obs.retain(|o| o.t_b_h < t_h);
        self.index = BucketIndex::rebuild(&self.obs);
        self.left_out += before - self.obs.len();
        if self.obs.len() < self.spec.min_pairs {
            // too few pairs before the slip for a rate of their own
            self.estimate = None;
            return Vec::new();
        }
        self.refit_now()
    }

    /// Refit at once after the model changed (a step or a pose break): the new estimate, once
    /// there are enough pairs, and the rate alarm's change, if any.
    fn refit_now(&mut self) -> Vec<DriftEvent> {
        if self.obs.len() < self.spec.min_pairs {
            return Vec::new();
        }
        match self.fit() {
            Some(est) => {
                self.estimate = Some(est);
                self.rate_events(est)
            }
            None => Vec::new(),
        }
    }

    /// A gain step at `t_h` (hours), found by another source: from now on the model is
    /// ln g(t) = r·t + Σ s_k·[t ≥ τ_k], so the step neither bends the rate nor stays in the
    /// corrected output. Refits at once when there are enough pairs.
    pub(crate) fn add_step(&mut self, t_h: f64) {
        if !t_h.is_finite() || self.step_times.iter().any(|&t| (t - t_h).abs() < 1e-9) {
            return;
        }
        self.step_times.push(t_h);
        self.step_times.sort_by(f64::total_cmp);
        if self.obs.len() >= self.spec.min_pairs {
            if let Some(est) = self.fit() {
                self.estimate = Some(est);
            }
        }
    }

    /// A step term at `t_h` that turned out not to be the lamp's (a joint slip named after it)
    /// leaves the model; refits at once. Returns the rate alarm's change, if any.
    pub(crate) fn remove_step(&mut self, t_h: f64) -> Vec<DriftEvent> {
        let before = self.step_times.len();
        self.step_times.retain(|&t| (t - t_h).abs() >= 1e-9);
        if self.step_times.len() == before {
            return Vec::new();
        }
        self.step_effects.retain(|s| (s.t_h - t_h).abs() >= 1e-9);
        self.refit_now()
    }

    /// The fitted steps (empty without known step times).
    pub(crate) fn steps(&self) -> &[StepEffect] {
        &self.step_effects
    }

    /// ln g(t) relative to t = 0 and its standard error (rate and steps, covariances left
    /// out), once there is an estimate.
    pub(crate) fn ln_gain_at(&self, t_h: f64) -> Option<(f64, f64)> {
        let e = self.estimate?;
        let v = self.gain_path()?.ln_at_h(t_h);
        let mut var = (t_h * e.se_pct_per_h / 100.0).powi(2);
        for st in self.step_effects.iter().filter(|st| st.t_h <= t_h) {
            var += st.se * st.se;
        }
        Some((v, var.sqrt()))
    }

    /// The fitted gain path ln g(t), once there is an estimate.
    pub(crate) fn gain_path(&self) -> Option<GainPath> {
        let e = self.estimate?;
        Some(GainPath {
            rate_per_h: e.rate_pct_per_h / 100.0,
            steps: self
                .step_effects
                .iter()
                .map(|s| (s.t_h, s.ln_size))
                .collect(),
        })
    }

    pub(crate) fn estimate(&self) -> Option<DriftEstimate> {
        self.estimate
    }
    /// Add one pair; returns the events it caused.
    pub(crate) fn add(&mut self, mut o: PairObservation) -> Vec<DriftEvent> {
        let mut ev = Vec::new();
        // a light azimuth that is not finite carries no pattern: its columns are left at 0, so
        // one bad direction cannot make the pattern-robust fit fail for the rest of the run
        if !o.light_az.iter().all(|a| a.is_finite()) {
            o.light_az = [0.0; 2];
        }
        if !(o.d.is_finite()
            && o.t_a_h.is_finite()
            && o.t_b_h.is_finite()
            && o.sigma.is_finite()
            && o.sigma >= 0.0)
        {
            return ev;
        }
        if self.pose_break.is_some_and(|tau| o.t_b_h >= tau) {
            self.left_out += 1;
            return ev;
        }
        // CUSUM on the standardized residual of the new pair against the current fit
        // (only in buckets whose effect is known from enough pairs; the prediction error of a
        // new pair includes the uncertainty of its bucket's effect)
        if let (Some(est), Some(&(beta, nb))) = (self.estimate, self.beta.get(&o.bucket)) {
            if self.spec.step_detection
                && est.residual_scale > 0.0
                && nb >= MIN_BUCKET_PAIRS
                && self.obs.len() >= self.spec.cusum_burn_in
            {
                let r = est.rate_pct_per_h / 100.0;
                let bucket_sd = self
                    .bucket_scale
                    .get(&o.bucket)
                    .copied()
                    .unwrap_or(est.residual_scale)
                    .max(est.residual_scale * 0.25);
                let sd =
                    (bucket_sd * bucket_sd * (1.0 + 1.0 / nb as f64) + o.sigma * o.sigma).sqrt();
                let pattern = self.mount.map_or(0.0, |m| m.ln_effect(&o.mount));
                let z = ((o.d - r * (o.t_b_h - o.t_a_h) - beta - pattern) / sd).clamp(-4.0, 4.0);
                self.cusum_hi = (self.cusum_hi + z - self.spec.cusum_k).max(0.0);
                self.cusum_lo = (self.cusum_lo - z - self.spec.cusum_k).max(0.0);
                self.cusum_n += 1;
                let (stat, dir) = if self.cusum_hi >= self.cusum_lo {
                    (self.cusum_hi, 1)
                } else {
                    (self.cusum_lo, -1)
                };
                if stat > self.h {
                    ev.push(DriftEvent::Step {
                        direction: dir,
                        statistic: stat,
                        threshold: self.h,
                        pairs_since_reset: self.cusum_n,
                    });
                    self.cusum_hi = 0.0;
                    self.cusum_lo = 0.0;
                    self.cusum_n = 0;
                }
            }
        }
        self.index.push(o.bucket);
        self.obs.push(o);
        if self.obs.len() >= self.spec.min_pairs
            && self.obs.len().is_multiple_of(self.spec.refit_every.max(1))
        {
            let fitted = match self.mount_found() {
                Some(f) => {
                    let est = self.keep(f);
                    if let Some(m) = self.mount {
                        ev.push(DriftEvent::MountPattern(m));
                    }
                    Some(est)
                }
                None => self.fit(),
            };
            if let Some(est) = fitted {
                self.estimate = Some(est);
                ev.extend(self.rate_events(est));
            }
        }
        ev
    }
}
