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

use super::geometry::Vec3;
use super::stats::{cusum_threshold, robust_scale_upper};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

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
    pub fn light_separated(&self) -> bool {
        self.rate_inflation <= MAX_RATE_INFLATION
    }

    /// Amplitude (% per unit tan θ) and the azimuth it points to (degrees), light side.
    pub fn light_pct(&self) -> (f64, f64) {
        polar(self.light)
    }

    /// Amplitude (% per unit tan θ) and the azimuth it points to (degrees), camera side.
    pub fn camera_pct(&self) -> (f64, f64) {
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

/// An observation's weight from its own σ relative to the residual scale: 1 / (1 + (σ/scale)²).
/// (`add` admits only finite σ ≥ 0; the floor keeps every bucket's weight positive.)
fn prior_weight(scale: f64, o: &PairObservation) -> f64 {
    if o.sigma > 0.0 && scale > 0.0 {
        (1.0 / (1.0 + (o.sigma / scale).powi(2))).max(1e-12)
    } else {
        1.0
    }
}

/// One IRLS reweighting: the residuals' robust scale (MAD), then Huber weights (c = 1.345 of
/// it) times each observation's prior weight. Returns the scale.
fn huber_reweight(res: &[f64], obs: &[PairObservation], w: &mut [f64]) -> f64 {
    let mut scale = robust_scale_upper(res);
    if !(scale > 0.0) {
        scale = 1e-9;
    }
    let c = 1.345 * scale;
    for ((wi, e), o) in w.iter_mut().zip(res).zip(obs) {
        *wi = prior_weight(scale, o) * if e.abs() <= c { 1.0 } else { c / e.abs() };
    }
    scale
}

/// The robust scale (MAD) of the final residuals per geometry bucket.
fn bucket_scales(buckets: &Buckets, res: &[f64]) -> BTreeMap<(i64, i64), f64> {
    let mut per: Vec<Vec<f64>> = vec![Vec::new(); buckets.keys.len()];
    for (&b, e) in buckets.of.iter().zip(res) {
        per[b].push(e.abs());
    }
    buckets
        .keys
        .iter()
        .zip(per)
        .map(|(k, v)| (*k, robust_scale_upper(&v)))
        .collect()
}

/// The observations' geometry buckets as dense indices, numbered in key order: a fit's
/// per-bucket sums are then vectors, visited in the order a map keyed by bucket would visit
/// them, and every sum is taken in the same order as before (the fits replay to the bit).
struct Buckets {
    /// The buckets, in key order.
    keys: Vec<(i64, i64)>,
    /// Each observation's bucket: an index into `keys`.
    of: Vec<usize>,
}

/// The geometry buckets seen so far, kept beside the observations: each bucket gets an id when
/// first seen, each observation carries its bucket's id, and a fit's `Buckets` (key-order
/// indices) come from a rank table without a tree lookup per observation.
#[derive(Debug, Clone, Default)]
struct BucketIndex {
    ids: BTreeMap<(i64, i64), usize>,
    /// Each observation's bucket id (parallel to `DriftDetector::obs`).
    of_id: Vec<usize>,
}

impl BucketIndex {
    fn push(&mut self, bucket: (i64, i64)) {
        let next = self.ids.len();
        let id = *self.ids.entry(bucket).or_insert(next);
        self.of_id.push(id);
    }

    /// The index of exactly `obs` (after observations were taken out).
    fn rebuild(obs: &[PairObservation]) -> BucketIndex {
        let mut b = BucketIndex::default();
        for o in obs {
            b.push(o.bucket);
        }
        b
    }

    fn buckets(&self) -> Buckets {
        let mut rank = vec![0usize; self.ids.len()];
        let mut keys = Vec::with_capacity(self.ids.len());
        for (pos, (k, &id)) in self.ids.iter().enumerate() {
            rank[id] = pos;
            keys.push(*k);
        }
        Buckets {
            keys,
            of: self.of_id.iter().map(|&id| rank[id]).collect(),
        }
    }
}

impl Buckets {
    /// The bucket effects as the map the detector keeps.
    fn map<T: Copy>(&self, values: &[T]) -> BTreeMap<(i64, i64), T> {
        self.keys
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect()
    }
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
        }
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
    pub(crate) fn add(&mut self, o: PairObservation) -> Vec<DriftEvent> {
        let mut ev = Vec::new();
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

    /// The rate alarm after a refit to `est`: raised when the rate is significant and beyond
    /// the tolerance (once the mount's light half is told apart from it), cleared with
    /// hysteresis.
    fn rate_events(&mut self, est: DriftEstimate) -> Vec<DriftEvent> {
        let (r, se, tol, z) = (
            est.rate_pct_per_h,
            est.se_pct_per_h,
            self.spec.rate_tolerance_pct_per_h,
            self.spec.z,
        );
        let identified = self.mount.is_none() || self.light_separated;
        if !self.rate_alarm && identified && rate_alarm_raised(r, se, tol, z) {
            self.rate_alarm = true;
            vec![DriftEvent::RateSignificant(est)]
        } else if self.rate_alarm && rate_alarm_cleared(r, se, tol, z) {
            self.rate_alarm = false;
            vec![DriftEvent::RateCleared(est)]
        } else {
            Vec::new()
        }
    }

    /// Adopts a design fit: its bucket effects, scales, steps and mount pattern.
    fn keep(&mut self, f: DesignFit) -> DriftEstimate {
        self.beta = f.beta;
        self.bucket_scale = f.bucket_scale;
        self.step_effects = f.step_effects;
        if let Some(m) = f.mount {
            self.mount = Some(m);
            self.light_separated |= m.light_separated();
        }
        f.estimate
    }

    /// While the mount terms are out of the model: whether the camera side of the pattern is
    /// now significant and large enough to bring them in. The camera's half is fitted within
    /// each light sweep, so a gain drift or step cannot pose as it; the light's half can, and
    /// is not tested.
    fn mount_found(&self) -> Option<DesignFit> {
        if !self.spec.mount_terms || self.mount.is_some() {
            return None;
        }
        let f = self.fit_design(true)?;
        let m = f.mount?;
        let (amp, _) = m.camera_pct();
        let lower = amp - self.spec.z * 100.0 * m.camera_se;
        (m.camera_se.is_finite() && lower > self.spec.mount_min_pct).then_some(f)
    }

    /// The off-centre mount's pattern, once it is part of the model.
    pub(crate) fn mount(&self) -> Option<MountPattern> {
        self.mount
    }

    /// IRLS with Huber weights and bucket fixed effects (within-bucket centring).
    fn fit(&mut self) -> Option<DriftEstimate> {
        if self.mount.is_some() || !self.step_times.is_empty() {
            let f = self.fit_design(self.mount.is_some())?;
            return Some(self.keep(f));
        }
        let n = self.obs.len();
        // precision weights from each observation's own uncertainty (equal in the first pass)
        let mut w: Vec<f64> = self.obs.iter().map(|o| prior_weight(0.0, o)).collect();
        let buckets = self.index.buckets();
        let mut r = 0.0;
        let mut beta: Vec<(f64, usize)> = Vec::new();
        let mut scale = 0.0;
        let mut res: Vec<f64> = Vec::new();
        let mut se = f64::INFINITY;
        for _ in 0..5 {
            // weighted bucket means of Δt and d
            let mut acc = vec![(0.0, 0.0, 0.0, 0usize); buckets.keys.len()];
            for ((o, wi), &b) in self.obs.iter().zip(&w).zip(&buckets.of) {
                let e = &mut acc[b];
                e.0 += wi;
                e.1 += wi * (o.t_b_h - o.t_a_h);
                e.2 += wi * o.d;
                e.3 += 1;
            }
            // the bucket means (a bucket whose every observation has zero weight adds nothing)
            let means: Vec<Option<(f64, f64)>> = acc
                .iter()
                .map(|&(sw, sx, sy, _)| (sw > 0.0).then(|| (sx / sw, sy / sw)))
                .collect();
            let (mut sxx, mut sxy) = (0.0, 0.0);
            for ((o, wi), &b) in self.obs.iter().zip(&w).zip(&buckets.of) {
                let Some((mx, my)) = means[b] else {
                    continue;
                };
                let x = (o.t_b_h - o.t_a_h) - mx;
                let y = o.d - my;
                sxx += wi * x * x;
                sxy += wi * x * y;
            }
            if !(sxx > 1e-12) {
                return None;
            }
            r = sxy / sxx;
            beta = acc
                .iter()
                .map(|(sw, sx, sy, nb)| ((sy - r * sx) / sw, *nb))
                .collect();
            res = self
                .obs
                .iter()
                .zip(&buckets.of)
                .map(|(o, &b)| o.d - r * (o.t_b_h - o.t_a_h) - beta[b].0)
                .collect();
            scale = huber_reweight(&res, &self.obs, &mut w);
            // variance of r: σ² / Sxx with the weighted residual variance
            let dof = (n as f64 - beta.len() as f64 - 1.0).max(1.0);
            let sse: f64 = res.iter().zip(&w).map(|(e, wi)| wi * e * e).sum();
            se = ((sse / dof).max(self.spec.scale_floor.powi(2)) / sxx).sqrt();
        }
        self.bucket_scale = bucket_scales(&buckets, &res);
        self.beta = buckets.map(&beta);
        Some(DriftEstimate {
            pairs: n,
            rate_pct_per_h: 100.0 * r,
            se_pct_per_h: 100.0 * se,
            residual_scale: scale,
        })
    }

    /// The same IRLS with one indicator column per known step (a pair spanning τ_k carries
    /// s_k) and, with `mount`, the four mount columns: the centred weighted design solved by
    /// normal equations and their pseudo-inverse, which is also the covariance. Deterministic: fixed passes,
    /// buckets in BTreeMap order. Pure: the caller decides whether to keep the result.
    /// The design, flat: row i is `rows[i * p..(i + 1) * p]`: the time between the pair's
    /// captures, a 1 for each step between them, and the mount columns.
    fn design_rows(&self, mount: bool, p: usize) -> Vec<f64> {
        let mut rows: Vec<f64> = Vec::with_capacity(self.obs.len() * p);
        for o in &self.obs {
            rows.push(o.t_b_h - o.t_a_h);
            for &tau in &self.step_times {
                rows.push(if o.t_a_h < tau && tau <= o.t_b_h {
                    1.0
                } else {
                    0.0
                });
            }
            if mount {
                rows.extend_from_slice(&o.mount);
            }
        }
        rows
    }

    fn fit_design(&self, mount: bool) -> Option<DesignFit> {
        let n = self.obs.len();
        let k = self.step_times.len();
        let p = 1 + k + if mount { 4 } else { 0 };
        let rows = self.design_rows(mount, p);
        let mut w: Vec<f64> = self.obs.iter().map(|o| prior_weight(0.0, o)).collect();
        let buckets = self.index.buckets();
        let nk = buckets.keys.len();
        let mut coef = DVector::<f64>::zeros(p);
        let mut cov = DMatrix::<f64>::zeros(p, p);
        let mut beta: Vec<(f64, usize)> = Vec::new();
        let mut scale = 0.0;
        let mut res: Vec<f64> = Vec::new();
        let mut inflation = 1.0;
        let mut sums = BucketSums::new(nk, p);
        for _ in 0..5 {
            sums.accumulate(&self.obs, &rows, &w, &buckets.of);
            let (acc_w, acc_x, acc_y, acc_n) = (&sums.w, &sums.x, &sums.y, &sums.n);
            let (ata, atb) = sums.normal_equations(&self.obs, &rows, &w, &buckets.of);
            // a step no pair spans yet has a zero column: the pseudo-inverse leaves its
            // coefficient at zero and its variance out
            let pinv = ata.clone().pseudo_inverse(1e-12).ok()?;
            coef = &pinv * &atb;
            if !coef.iter().all(|c| c.is_finite()) {
                return None;
            }
            beta = (0..nk)
                .map(|b| {
                    let sx = &acc_x[b * p..(b + 1) * p];
                    let fx: f64 = (0..p).map(|j| coef[j] * sx[j]).sum();
                    ((acc_y[b] - fx) / acc_w[b], acc_n[b])
                })
                .collect();
            res = self
                .obs
                .iter()
                .zip(rows.chunks_exact(p))
                .zip(&buckets.of)
                .map(|((o, x), &b)| o.d - (0..p).map(|j| coef[j] * x[j]).sum::<f64>() - beta[b].0)
                .collect();
            scale = huber_reweight(&res, &self.obs, &mut w);
            let dof = (n as f64 - beta.len() as f64 - p as f64).max(1.0);
            let sse: f64 = res.iter().zip(&w).map(|(e, wi)| wi * e * e).sum();
            // v · sse / dof in that order, as without a floor: the fits replay to the bit
            let floor = self.spec.scale_floor.powi(2);
            let scaled = |v: f64| {
                if floor > sse / dof {
                    v * floor
                } else {
                    v * sse / dof
                }
            };
            cov = pinv.map(scaled);
            if mount {
                // the rate's variance with the light's two mount columns left out
                let keep: Vec<usize> = (0..p).filter(|&j| j != 1 + k && j != 2 + k).collect();
                let sub = ata.select_rows(keep.iter()).select_columns(keep.iter());
                let v0 = scaled(sub.pseudo_inverse(1e-12).ok()?[(0, 0)]);
                inflation = (cov[(0, 0)] / v0).max(0.0).sqrt();
            }
        }
        let step_effects = self
            .step_times
            .iter()
            .enumerate()
            // a step no pair spans yet (a zero column) is not estimable: left out until it is
            .filter(|(j, _)| cov[(1 + j, 1 + j)] > 0.0 && cov[(1 + j, 1 + j)].is_finite())
            .map(|(j, &t_h)| StepEffect {
                t_h,
                ln_size: coef[1 + j],
                se: cov[(1 + j, 1 + j)].sqrt(),
            })
            .collect();
        let mount = mount.then(|| {
            let m = 1 + k;
            let se = |a: usize, b: usize| cov[(a, a)].max(cov[(b, b)]).max(0.0).sqrt();
            MountPattern {
                light: [coef[m], coef[m + 1]],
                light_se: se(m, m + 1),
                camera: [coef[m + 2], coef[m + 3]],
                camera_se: se(m + 2, m + 3),
                rate_inflation: inflation,
            }
        });
        Some(DesignFit {
            estimate: DriftEstimate {
                pairs: n,
                rate_pct_per_h: 100.0 * coef[0],
                se_pct_per_h: 100.0 * cov[(0, 0)].max(0.0).sqrt(),
                residual_scale: scale,
            },
            beta: buckets.map(&beta),
            bucket_scale: bucket_scales(&buckets, &res),
            step_effects,
            mount,
        })
    }
}

/// What `fit_design` found.
struct DesignFit {
    estimate: DriftEstimate,
    beta: BTreeMap<(i64, i64), (f64, usize)>,
    bucket_scale: BTreeMap<(i64, i64), f64>,
    step_effects: Vec<StepEffect>,
    mount: Option<MountPattern>,
}

/// Per bucket: the sum of weights, the weighted sums of each design column (flat, `p` a
/// bucket) and of d, and the count.
struct BucketSums {
    p: usize,
    w: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    n: Vec<usize>,
}

impl BucketSums {
    fn new(nk: usize, p: usize) -> Self {
        BucketSums {
            p,
            w: vec![0.0; nk],
            x: vec![0.0; nk * p],
            y: vec![0.0; nk],
            n: vec![0; nk],
        }
    }

    /// The weighted bucket sums of every column and of d, anew.
    fn accumulate(&mut self, obs: &[PairObservation], rows: &[f64], w: &[f64], of: &[usize]) {
        let p = self.p;
        self.w.fill(0.0);
        self.x.fill(0.0);
        self.y.fill(0.0);
        self.n.fill(0);
        for (((o, x), wi), &b) in obs.iter().zip(rows.chunks_exact(p)).zip(w).zip(of) {
            self.w[b] += wi;
            let sx = &mut self.x[b * p..(b + 1) * p];
            for j in 0..p {
                sx[j] += wi * x[j];
            }
            self.y[b] += wi * o.d;
            self.n[b] += 1;
        }
    }

    /// The normal equations of the design centred on its bucket means, weighted.
    fn normal_equations(
        &self,
        obs: &[PairObservation],
        rows: &[f64],
        w: &[f64],
        of: &[usize],
    ) -> (DMatrix<f64>, DVector<f64>) {
        let (p, nk) = (self.p, self.w.len());
        let (acc_w, acc_x, acc_y) = (&self.w, &self.x, &self.y);
        // the normal equations of the centred, weighted design, accumulated row by row:
        // p is at most a few columns, so this costs O(n·p²) without an n × p matrix
        let mut ata_flat = vec![0.0; p * p];
        let mut atb_flat = vec![0.0; p];
        let mut xc = vec![0.0; p];
        // the bucket means of every column and of d (a bucket whose every observation has
        // zero weight adds nothing)
        let live: Vec<bool> = acc_w.iter().map(|&sw| sw > 0.0).collect();
        let mean_x: Vec<f64> = (0..nk * p).map(|i| acc_x[i] / acc_w[i / p]).collect();
        let mean_y: Vec<f64> = (0..nk).map(|b| acc_y[b] / acc_w[b]).collect();
        for (((o, x), wi), &b) in obs.iter().zip(rows.chunks_exact(p)).zip(w).zip(of) {
            if !live[b] {
                continue;
            }
            let mx = &mean_x[b * p..(b + 1) * p];
            for j in 0..p {
                xc[j] = x[j] - mx[j];
            }
            let yc = o.d - mean_y[b];
            for j in 0..p {
                // (wi·xc_j)·… is how `wi * xc[j] * x` groups: the same products as before
                let wx = wi * xc[j];
                atb_flat[j] += wx * yc;
                let row = &mut ata_flat[j * p..j * p + j + 1];
                for (a, x) in row.iter_mut().zip(&xc[..=j]) {
                    *a += wx * x;
                }
            }
        }
        let mut ata =
            DMatrix::<f64>::from_fn(p, p, |j, l| if l <= j { ata_flat[j * p + l] } else { 0.0 });
        let atb = DVector::<f64>::from_column_slice(&atb_flat);
        for j in 0..p {
            for l in 0..j {
                ata[(l, j)] = ata[(j, l)];
            }
        }
        (ata, atb)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_alarm_needs_significance_and_size_and_clears_inside_the_tolerance() {
        // significant and beyond the tolerance, either sign
        assert!(rate_alarm_raised(0.5, 0.1, 0.25, 4.0));
        assert!(rate_alarm_raised(-0.5, 0.1, 0.25, 4.0));
        // a lower bound below the tolerance does not hold it back
        assert!(rate_alarm_raised(0.5, 0.12, 0.25, 4.0));
        // beyond the tolerance but not significant; significant but within the tolerance
        assert!(!rate_alarm_raised(0.5, 0.13, 0.25, 4.0));
        assert!(!rate_alarm_raised(0.2, 0.01, 0.25, 4.0));
        // a NaN estimate or error never raises; an infinite tolerance switches it off
        assert!(!rate_alarm_raised(f64::NAN, 0.01, 0.25, 4.0));
        assert!(!rate_alarm_raised(0.5, f64::NAN, 0.25, 4.0));
        assert!(!rate_alarm_raised(0.5, 0.01, f64::INFINITY, 4.0));
        // cleared only when the whole z band is inside the tolerance
        assert!(rate_alarm_cleared(0.05, 0.04, 0.25, 4.0));
        assert!(!rate_alarm_cleared(0.05, 0.06, 0.25, 4.0));
        assert!(!rate_alarm_cleared(f64::NAN, 0.01, 0.25, 4.0));
    }

    #[test]
    fn the_scale_floor_bounds_the_rate_standard_error_of_a_few_quiet_observations() {
        // four probes on a line but for 0.01 % of noise: their own scale would make a
        // 0.04 %/h slope look like several standard errors
        let obs = |i: usize| PairObservation {
            t_a_h: 0.0,
            t_b_h: 0.5 * (i + 1) as f64,
            d: 0.0005 * 0.5 * (i + 1) as f64 + if i.is_multiple_of(2) { 1e-4 } else { -1e-4 },
            bucket: (0, 0),
            sigma: 0.0,
            mount: [0.0; 4],
        };
        let spec = DriftSpec {
            min_pairs: 4,
            refit_every: 1,
            step_detection: false,
            ..DriftSpec::default()
        };
        let fit = |floor: f64| {
            let mut d = DriftDetector::new(DriftSpec {
                scale_floor: floor,
                ..spec.clone()
            });
            for i in 0..4 {
                d.add(obs(i));
            }
            d.estimate().unwrap()
        };
        let (own, floored) = (fit(0.0), fit(0.003));
        assert_eq!(own.rate_pct_per_h, floored.rate_pct_per_h);
        assert!(own.rate_pct_per_h / own.se_pct_per_h > 3.0, "{own:?}");
        // σ ≥ 0.3 %: the SE is at least 0.3 % / √Sxx (Sxx of 0.5, 1, 1.5, 2 h is 1.25 h²)
        let bound = 100.0 * 0.003 / 1.25f64.sqrt();
        assert!(floored.se_pct_per_h >= bound * (1.0 - 1e-9), "{floored:?}");
        assert!(
            floored.rate_pct_per_h / floored.se_pct_per_h < 1.0,
            "{floored:?}"
        );
    }

    #[test]
    fn mount_coordinates_stay_finite_at_grazing_and_bad_directions() {
        let up = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(mount_coordinates(&up, &up), [0.0; 4]);
        // 45° along +x: tan θ = 1
        let d = Vec3::new(1.0, 0.0, 1.0).normalize();
        let m = mount_coordinates(&d, &up);
        assert!((m[0] - 1.0).abs() < 1e-12 && m[1].abs() < 1e-12);
        // grazing and below the horizon: capped at θ = 85° (tan 85° = 11.43), never infinite
        for w in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, -0.2)] {
            let m = mount_coordinates(&w, &up);
            assert!(m.iter().all(|v| v.is_finite() && v.abs() <= 11.5), "{m:?}");
        }
        // a NaN direction contributes nothing
        let nan = Vec3::new(f64::NAN, 0.0, 1.0);
        assert_eq!(mount_coordinates(&nan, &d), [0.0; 4]);
    }

    #[test]
    fn the_gain_path_is_the_rate_and_the_steps_that_have_happened() {
        let g = GainPath {
            rate_per_h: -0.01,
            steps: vec![(2.0, (0.97f64).ln())],
        };
        assert!((g.ln_at(3600.0) + 0.01).abs() < 1e-12);
        assert!((g.ln_at(3.0 * 3600.0) - (-0.03 + (0.97f64).ln())).abs() < 1e-12);
        let bad = GainPath {
            rate_per_h: f64::NAN,
            steps: Vec::new(),
        };
        assert_eq!(bad.ln_at(10.0), 0.0);
    }
    use crate::fixtures::Lcg;

    /// Synthetic pairs with bucket effects, a rate, noise, and an optional step.
    fn run(
        rate_pct: f64,
        step: Option<(f64, f64)>,
        seed: u64,
    ) -> (DriftDetector, Vec<(usize, DriftEvent)>) {
        let mut s = Lcg(seed);
        // refit less often than the default to keep the debug-build test quick
        let mut det = DriftDetector::new(DriftSpec {
            refit_every: 80,
            ..DriftSpec::default()
        });
        let mut events = Vec::new();
        let buckets: Vec<f64> = (0..36).map(|_| 0.04 * s.gauss()).collect();
        let ln_g = |t: f64| {
            let mut v = rate_pct / 100.0 * t;
            if let Some((t0, frac)) = step {
                if t >= t0 {
                    v += (1.0f64 + frac).ln();
                }
            }
            v
        };
        for i in 0..3240 {
            let t_b = 13.0 * (i as f64 + 1.0) / 3240.0;
            let t_a = t_b * s.uniform();
            let b = (s.uniform() * 36.0) as usize;
            let d = ln_g(t_b) - ln_g(t_a) + buckets[b] + 0.015 * s.gauss();
            for e in det.add(PairObservation {
                t_a_h: t_a,
                t_b_h: t_b,
                d,
                bucket: (b as i64, 0),
                sigma: 0.0,
                mount: [0.0; 4],
            }) {
                events.push((i, e));
            }
        }
        (det, events)
    }

    #[test]
    fn a_known_step_is_fitted_and_keeps_the_rate_unbiased() {
        // −1 %/h and a −3 % step at 6.5 h
        let step = (0.97f64).ln();
        let fit = |known: bool| {
            let mut s = Lcg(5);
            let mut det = DriftDetector::new(DriftSpec {
                refit_every: 3000,
                min_pairs: 100,
                step_detection: false,
                ..DriftSpec::default()
            });
            if known {
                det.add_step(6.5);
            }
            for i in 0..3000 {
                let t_b = 13.0 * (i as f64 + 1.0) / 3000.0;
                let t_a = t_b * s.uniform();
                let lg = |t: f64| -0.01 * t + if t >= 6.5 { step } else { 0.0 };
                det.add(PairObservation {
                    t_a_h: t_a,
                    t_b_h: t_b,
                    d: lg(t_b) - lg(t_a) + 0.01 * s.gauss(),
                    bucket: ((i % 5) as i64, 0),
                    sigma: 0.0,
                    mount: [0.0; 4],
                });
            }
            det
        };
        let blind = fit(false);
        let told = fit(true);
        let (rb, rt) = (
            blind.estimate().unwrap().rate_pct_per_h,
            told.estimate().unwrap().rate_pct_per_h,
        );
        assert!((rt + 1.0).abs() < 0.02, "{rt}");
        assert!((rb + 1.0).abs() > 5.0 * (rt + 1.0).abs(), "{rb} {rt}");
        let st = told.steps()[0];
        assert!((st.ln_size - step).abs() < 0.003, "{st:?}");
        assert!(st.se > 0.0 && st.se < 0.003);
        assert!(blind.steps().is_empty());
        assert_eq!(told.steps().len(), 1);
        // the gain curve: the step is in it after 6.5 h, not before
        let (before, _) = told.ln_gain_at(6.4).unwrap();
        let (after, sigma) = told.ln_gain_at(6.6).unwrap();
        assert!(
            (after - before - step + 0.002).abs() < 0.004,
            "{before} {after}"
        );
        assert!(sigma > 0.0 && sigma.is_finite());
        // a step withdrawn (a slip explained it) leaves the model as if never told; one that
        // was never added changes nothing
        let mut withdrawn = fit(true);
        assert!(withdrawn.remove_step(7.0).is_empty());
        assert_eq!(withdrawn.steps().len(), 1);
        withdrawn.remove_step(6.5);
        assert!(withdrawn.steps().is_empty());
        assert_eq!(withdrawn.estimate(), blind.estimate());
        // a step time nobody's pairs span yet changes nothing
        let mut late = fit(true);
        late.add_step(20.0);
        assert!((late.estimate().unwrap().rate_pct_per_h - rt).abs() < 1e-9);
        let (a, b) = (
            late.ln_gain_at(13.0).unwrap(),
            told.ln_gain_at(13.0).unwrap(),
        );
        assert!(
            (a.0 - b.0).abs() < 1e-12 && (a.1 / b.1 - 1.0).abs() < 1e-3,
            "{a:?} {b:?}"
        );
    }

    #[test]
    fn a_pose_break_keeps_a_slips_pattern_out_of_the_rate() {
        // −0.5 %/h; from 6.5 h a tilt moves each bucket's later member by its own amount that
        // grows with the pair's time difference (members at other azimuths move differently)
        let fit = |break_at: Option<f64>, at_pair: usize| {
            let mut s = Lcg(11);
            let mut det = DriftDetector::new(DriftSpec {
                refit_every: 500,
                min_pairs: 100,
                step_detection: false,
                ..DriftSpec::default()
            });
            for i in 0..3000 {
                if i == at_pair {
                    if let Some(t) = break_at {
                        det.add_pose_break(t);
                    }
                }
                let t_b = 13.0 * (i as f64 + 1.0) / 3000.0;
                let t_a = t_b * s.uniform();
                let tilt = if t_b >= 6.5 { 0.004 * (t_b - t_a) } else { 0.0 };
                det.add(PairObservation {
                    t_a_h: t_a,
                    t_b_h: t_b,
                    d: -0.005 * (t_b - t_a) + tilt + 0.005 * s.gauss(),
                    bucket: ((i % 5) as i64, 0),
                    sigma: 0.0,
                    mount: [0.0; 4],
                });
            }
            det
        };
        let rate = |d: &DriftDetector| d.estimate().unwrap().rate_pct_per_h;
        let blind = fit(None, 0);
        assert!((rate(&blind) + 0.5).abs() > 0.1, "{}", rate(&blind));
        // named late (two thirds in): the pairs already taken after the break leave as well
        let told = fit(Some(6.4), 2000);
        assert!((rate(&told) + 0.5).abs() < 0.02, "{}", rate(&told));
        assert_eq!(told.left_out, 3000 - 1476);
        assert_eq!(told.estimate().unwrap().pairs, 1476);
        // a later break than the one held changes nothing; an earlier one moves it
        let mut again = fit(Some(6.4), 2000);
        again.add_pose_break(9.0);
        assert_eq!(again.left_out, told.left_out);
        again.add_pose_break(f64::NAN);
        assert_eq!(again.left_out, told.left_out);
        again.add_pose_break(6.0);
        assert!(again.left_out > told.left_out);
        assert!((rate(&again) + 0.5).abs() < 0.02, "{}", rate(&again));
    }

    #[test]
    fn uncertain_observations_weigh_less() {
        // 2,000 measured pairs with a −1 %/h drift, and 200 whose values follow +5 %/h; with
        // no stated uncertainty the latter pull the rate, with a large one they hardly do
        let fit = |sigma: f64| {
            let mut s = Lcg(11);
            let mut det = DriftDetector::new(DriftSpec {
                refit_every: 2200,
                min_pairs: 100,
                ..DriftSpec::default()
            });
            for i in 0..2200 {
                let t_b = 13.0 * (i as f64 + 1.0) / 2200.0;
                let t_a = t_b * s.uniform();
                let odd = i % 11 == 0;
                let rate = if odd { 0.05 } else { -0.01 };
                let d = rate * (t_b - t_a) + 0.015 * s.gauss();
                det.add(PairObservation {
                    t_a_h: t_a,
                    t_b_h: t_b,
                    d,
                    bucket: (if odd { -1 } else { (i % 7) as i64 }, 0),
                    sigma: if odd { sigma } else { 0.0 },
                    mount: [0.0; 4],
                });
            }
            det.estimate().unwrap().rate_pct_per_h
        };
        let plain = fit(0.0);
        let weighted = fit(0.3);
        assert!((weighted + 1.0).abs() < 0.05, "{weighted}");
        assert!(
            (weighted + 1.0).abs() < (plain + 1.0).abs(),
            "{plain} {weighted}"
        );
        // a non-finite uncertainty: the observation is refused (and cannot stall the fit)
        let mut det = DriftDetector::new(DriftSpec {
            refit_every: 1,
            min_pairs: 3,
            ..DriftSpec::default()
        });
        for (i, sigma) in [0.0, 0.0, 0.0, f64::NAN, f64::INFINITY, 0.0]
            .iter()
            .enumerate()
        {
            let odd = !sigma.is_finite();
            det.add(PairObservation {
                t_a_h: 0.0,
                t_b_h: 1.0 + i as f64,
                d: if odd { 10.0 } else { -0.01 * (1.0 + i as f64) },
                // alone in a bucket of its own, as an interpolated pair often is
                bucket: (if odd { 1 } else { 0 }, 0),
                sigma: *sigma,
                mount: [0.0; 4],
            });
        }
        assert_eq!(det.estimate().unwrap().pairs, 4);
        assert!((det.estimate().unwrap().rate_pct_per_h + 1.0).abs() < 1e-6);
    }

    #[test]
    fn threshold_design_meets_the_false_alarm_budget() {
        let h = cusum_threshold(0.5, 20.0 * 3240.0);
        use crate::measure::stats::cusum_arl0;
        assert!(cusum_arl0(0.5, h) / 2.0 >= 64_800.0);
        assert!(cusum_arl0(0.5, h - 0.02) / 2.0 < 64_800.0);
        assert!(h > 9.0 && h < 11.0, "{h}");
    }

    #[test]
    fn recovers_the_rate_despite_geometry_effects() {
        for (rate, seed) in [(1.0, 1), (-1.0, 2), (0.5, 3)] {
            let (det, events) = run(rate, None, seed);
            let est = det.estimate().unwrap();
            assert!((est.rate_pct_per_h - rate).abs() < 0.05, "{rate}: {est:?}");
            assert!((est.rate_pct_per_h - rate).abs() < 4.0 * est.se_pct_per_h + 1e-3);
            assert!(events
                .iter()
                .any(|(_, e)| matches!(e, DriftEvent::RateSignificant(_))));
        }
    }

    #[test]
    fn a_decay_of_twice_the_tolerance_is_raised_once_significant_before_its_bound_clears() {
        // −0.5 %/h against the 0.25 %/h tolerance: the alarm comes at the first refit where the
        // rate is 4 SEs from zero, and in these runs that is while |r| − 4·SE is still inside the
        // tolerance (the bound rule would have waited)
        let mut earlier = 0;
        for seed in 1..=4 {
            let (_, events) = run(-0.5, None, seed);
            let Some((_, DriftEvent::RateSignificant(e))) = events
                .iter()
                .find(|(_, e)| matches!(e, DriftEvent::RateSignificant(_)))
            else {
                panic!("seed {seed}: no rate alarm: {events:?}");
            };
            assert!(e.rate_pct_per_h < -0.25, "{e:?}");
            assert!(e.rate_pct_per_h.abs() > 4.0 * e.se_pct_per_h, "{e:?}");
            earlier += usize::from(e.rate_pct_per_h.abs() - 4.0 * e.se_pct_per_h <= 0.25);
        }
        assert!(earlier >= 1, "every alarm waited for the bound");
    }

    #[test]
    fn false_alarms_stay_within_the_budget() {
        // designed for at most 1 false alarm in 20 runs; 30 runs may show a few by chance
        let mut runs_with_alarm = 0;
        for seed in 100..130 {
            let (det, events) = run(0.0, None, seed);
            runs_with_alarm += usize::from(!events.is_empty());
            assert!(det.estimate().unwrap().rate_pct_per_h.abs() < 0.05);
            assert!(
                !events
                    .iter()
                    .any(|(_, e)| matches!(e, DriftEvent::RateSignificant(_))),
                "seed {seed}: {events:?}"
            );
        }
        assert!(
            runs_with_alarm <= 4,
            "{runs_with_alarm} of 30 fault-free runs alarmed"
        );
    }

    #[test]
    fn a_step_is_caught_by_the_cusum() {
        let (_, events) = run(0.0, Some((6.5, -0.03)), 5);
        let step = events
            .iter()
            .find(|(_, e)| matches!(e, DriftEvent::Step { .. }));
        let (i, e) = step.expect("a step alarm");
        assert!(*i >= 1620, "not before the step: {i}");
        assert!(matches!(e, DriftEvent::Step { direction: -1, .. }), "{e:?}");
    }
}
