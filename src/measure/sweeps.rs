//! Light-sweep consistency: each completed light direction (its 81 camera directions, in the
//! UBO light-outer order) against the session's earlier sweeps. Isotropic samples only.
//!
//! Why per sweep: on a real sample ln Y is close to
//!   F(θi, θo, |Δφ|) + L(light) + C(camera) + ln g(t),
//! where F is the isotropic BRDF, L a per-light effect (lamp footprint on a square sample), C a
//! per-camera effect (border bleed, the texture under the view) and g the lamp gain. L and C are
//! a large part of the isotropy-class residuals, and consecutive captures share their light, so
//! capture-level tests are overconfident (docs/detectors.md). A light sweep
//! is the natural unit: within one sweep L and g are constant, so
//! - the sweep's *level* (its mean residual against F and C fitted on the earlier sweeps) moves
//!   with the gain: a lamp step shows in the sweep it happens in and in every later one;
//! - the *pattern* across its cameras moves with the pose: a joint offset δ changes ln Y by
//!   s_j·δ, where s_j = ∂ ln Y / ∂q_j is computed from the session's own interpolant (a
//!   `LayeredResampler` over the isotropy classes' fitted effects) through the rig's forward
//!   kinematics. Regressing the sweep's residuals on (1, s₁, s₂) gives the level and an
//!   offset per joint, each with a standard error.
//! - the *size* of a slip, once one is named, comes from a second fit with sensitivities of
//!   a smooth model of the same effects (`smooth_brdf`), whose slopes follow the BRDF's where
//!   the interpolant's are several times too steep; it also carries the wagon's offset and
//!   backlash, so that a pattern of the wagon's is not read into the joints' sizes.
//!
//! Joint 3 turns the sample about its own normal: an isotropic BRDF does not see it, so it is
//! not attributable here (nor does it spoil the BRDF); only the encoder check guards it.
//!
//! Each statistic is standardised by its own robust scale over earlier sweeps (the level per θi
//! layer: the footprint nuisance grows with θi), clipped, and fed to one-sided CUSUMs whose
//! threshold comes from the average run length for the false-alarm budget. An alarm also needs
//! the estimate beyond a tolerance (an offset in degrees, a level in %) and is raised once per
//! θi layer, kind and sign.

use super::alarm::{action, Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use super::drift::{GainPath, MountPattern};
use super::geometry::Vec3;
use super::kinematics::{Pose, Rig};
use super::resample::{LayeredResampler, ResampleSpec, Sample};
use super::smooth_brdf::{Node, SmoothBrdf};
use super::stats::{cusum_threshold, median_sorted, robust_scale_about_zero, Cusum};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::collections::{HashMap, HashSet};
use std::f64::consts::TAU;

/// `[checks.sweeps]` in the config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepSpec {
    /// Run the light-sweep checks (isotropic samples in a light-outer order only).
    pub enabled: bool,
    /// A joint offset is alarmed only when its estimate exceeds this (degrees).
    pub joint_tolerance_deg: f64,
    /// A gain level shift is alarmed only when it exceeds this (%); with drift probes enabled
    /// the level test is left out (the probes measure steps directly).
    pub level_tolerance_pct: f64,
    /// CUSUM reference value k, in robust standard deviations of the statistic.
    pub cusum_k: f64,
    /// Standardised statistics are clipped to ± this before the CUSUM (one odd sweep cannot
    /// raise an alarm by itself).
    pub clip: f64,
    /// At most one false alarm in this many fault-free runs (sets the CUSUM thresholds).
    pub false_alarm_runs: f64,
    /// Earlier sweeps with a statistic before a joint CUSUM runs.
    pub min_sweeps: usize,
    /// Earlier sweeps of the same θi layer before the level test uses the layer's own scale
    /// (alone from `OWN_SCALE_SWEEPS` on, the smaller of it and the lent one before). A layer
    /// that a lower one lends a scale to is tested from its first sweep with a level; one
    /// without (the first layers of a run) waits for this many.
    pub min_layer_sweeps: usize,
    /// A sweep is tested when this many of its captures have an earlier isotropy class member.
    pub min_captures: usize,
    /// Half-width of the central difference for ∂ ln Y / ∂q_j (degrees).
    pub sensitivity_step_deg: f64,
}

impl Default for SweepSpec {
    fn default() -> Self {
        SweepSpec {
            enabled: true,
            joint_tolerance_deg: 0.25,
            level_tolerance_pct: 1.0,
            cusum_k: 1.0,
            clip: 4.0,
            false_alarm_runs: 20.0,
            min_sweeps: 8,
            min_layer_sweeps: 2,
            min_captures: 12,
            sensitivity_step_deg: 1.0,
        }
    }
}

/// One capture as the sweep checks keep it.
#[derive(Debug, Clone)]
pub(crate) struct SweepCapture {
    pub idx: u64,
    pub t: f64,
    pub light: usize,
    pub camera: usize,
    /// Isotropy class (any stable key).
    pub class: (i64, i64, i64),
    /// θi of the light's layer (millidegrees).
    pub layer: i64,
    /// Nominal directions (sample frame) and the commanded pose.
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub cmd: [f64; 4],
    /// The wagon's last commanded direction of motion before this capture (+1, −1; 0 before
    /// it first moved): a backlash lag is against it.
    pub wagon_dir: f64,
    /// Luminance Y (> 0).
    pub y: f64,
    /// `measure::drift::mount_coordinates` of the nominal directions.
    pub mount: [f64; 4],
}

/// One joint's fit in a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointFit {
    pub joint: usize,
    pub offset_deg: f64,
    pub se_deg: f64,
    /// Standardised statistic fed to the CUSUM (none while there are too few earlier sweeps).
    pub z: Option<f64>,
    /// The larger of the two one-sided CUSUMs after this sweep, and its threshold.
    pub cusum: f64,
}

/// One line of `sweeps.jsonl`: a completed light sweep against the earlier ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRecord {
    pub light: usize,
    /// The sweep's last capture.
    pub idx: u64,
    pub t: f64,
    /// Captures with an earlier member of their isotropy class (used in the fit).
    pub captures: usize,
    /// The sweep's gain level against the earlier sweeps (%), its standard error and statistic.
    pub level_pct: f64,
    /// The level the layer's azimuthal pattern predicts for this light (%): the level test
    /// judges `level_pct` less this.
    #[serde(default)]
    pub level_expected_pct: f64,
    pub level_se_pct: f64,
    pub level_z: Option<f64>,
    pub level_cusum: f64,
    pub joints: Vec<JointFit>,
    /// Residual standard deviation of the fit (ln units).
    pub residual_sd: f64,
    pub thresholds: [f64; 2],
    /// θi layers of the interpolant the sensitivities came from, and how often it was built.
    pub model_layers: usize,
    pub model_builds: usize,
}

/// A completed sweep: its captures (indices into the monitor's list) and those of the earlier
/// completed sweeps.
struct Sweep {
    light: usize,
    first_idx: u64,
    last_idx: u64,
    last_t: f64,
    layer: i64,
    first_t: f64,
    current: Vec<usize>,
    past: Vec<usize>,
}

/// What the drift model already explains and the sweeps take out of ln Y first.
struct Known<'a> {
    mount: Option<&'a MountPattern>,
    gain: Option<&'a GainPath>,
}

/// The F + L + C reference: class, light and camera effects (ln units), and which classes have
/// members.
struct Reference {
    class: Vec<f64>,
    light: Vec<f64>,
    camera: Vec<f64>,
    seen: Vec<bool>,
}

impl Reference {
    /// The class effects, NaN for classes without an earlier member.
    fn class_effects(&self) -> Vec<f64> {
        self.class
            .iter()
            .zip(&self.seen)
            .map(|(v, s)| if *s { *v } else { f64::NAN })
            .collect()
    }
}

/// One capture's row of the pattern fits: its residual against the reference, its
/// sensitivities to joint 1, joint 2 and the wagon (NaN where there is none), and the
/// wagon's last direction of motion.
#[derive(Debug, Clone, Copy)]
struct Row {
    e: f64,
    s: [f64; 3],
    wagon_dir: f64,
}

impl Row {
    /// The joints' columns (detection).
    fn joints(&self) -> (f64, [f64; 2]) {
        (self.e, [self.s[0], self.s[1]])
    }

    /// The joints', the wagon's, and the wagon's signed by its direction of motion (a lag b
    /// against it adds b times that column): a slip's size. None without the wagon's.
    fn with_wagon(&self) -> Option<(f64, [f64; 4])> {
        let w = self.s[2];
        w.is_finite()
            .then_some((self.e, [self.s[0], self.s[1], w, -self.wagon_dir * w]))
    }
}

/// Where a sensitivity comes from: the interpolant through the classes' effects, or the
/// smooth least-squares model of them (`smooth_brdf`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Model {
    Interpolant,
    Smooth,
}

/// A sweep's pattern fit: coefficients [λ, b₁, …], residual variance, (XᵀX)⁻¹ when the fit is
/// well conditioned.
struct PatternFit {
    beta: DVector<f64>,
    sigma2: f64,
    inv: Option<DMatrix<f64>>,
}

impl PatternFit {
    /// The standard error of coefficient `j`.
    fn se(&self, j: usize) -> Option<f64> {
        self.inv
            .as_ref()
            .map(|m| (self.sigma2 * m[(j, j)]).max(0.0).sqrt())
    }
}

/// What the level test found: whether it alarmed, where the step starts (controller s), and,
/// when the level change was attributed to a joint, the slip it named (`NamedSlip`).
#[derive(Debug, Clone, Default)]
struct LevelStep {
    alarmed: bool,
    at_s: Option<f64>,
    slip: Option<NamedSlip>,
}

/// A slip named in a sweep: where it is placed (controller s), and the earlier gain steps of its
/// layer it explains (their step terms, controller s).
#[derive(Debug, Clone, Default)]
struct NamedSlip {
    at_s: Option<f64>,
    withdrawn_steps_s: Vec<f64>,
}

/// A joint CUSUM that crossed its threshold.
#[derive(Debug, Clone, Copy)]
struct JointCrossing {
    /// 0 or 1 (arm joint 1 or 2).
    joint: usize,
    statistic: f64,
    mean: f64,
    mean_se: f64,
    sweeps: usize,
    since: u64,
    /// Sweeps behind `mean` (see `SweepMonitor::slip_estimate`), and the CUSUM run's own mean.
    estimate_sweeps: usize,
    run_mean: f64,
    /// For a level change attributed to the joint (`SweepMonitor::attribute_level`): the
    /// level (ln units). Its sweeps' offsets are then the smooth model's.
    attributed_level: Option<f64>,
}

/// The start of the most likely last segment of a mean shift of sign `sign` in equally scaled
/// `values`: the k that maximises sign · Σ_{i≥k} vᵢ / √(n − k) (the likelihood-ratio change
/// point). `None` for no values.
fn change_point(values: &[f64], sign: f64) -> Option<usize> {
    (0..values.len())
        .map(|k| {
            let tail = &values[k..];
            (
                k,
                sign * tail.iter().sum::<f64>() / (tail.len() as f64).sqrt(),
            )
        })
        .filter(|(_, t)| t.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// Where an attributed slip is placed: a CUSUM run often begins a sweep or more before the
/// slip, so at the change point of the run's offsets (`(offset, se, sensitivity, last_idx)`,
/// less the in-control `centre`) in the direction of the departure `offset`; the run's start
/// without one. Placement only: the decision does not look at it.
fn slip_start(run: &[(f64, f64, f64, u64)], centre: f64, offset: f64) -> u64 {
    let centred: Vec<f64> = run.iter().map(|v| v.0 - centre).collect();
    let k = change_point(&centred, offset.signum()).unwrap_or(0);
    run.get(k).or(run.first()).map_or(0, |v| v.3)
}

/// An alarm already raised, which is not raised again: a gain step per sign and θi layer, a
/// positioning alarm per θi layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Latch {
    Level { sign: i8, layer: i64 },
    Joint { layer: i64 },
}

/// The sweep checks of one session.
pub(crate) struct SweepMonitor {
    spec: SweepSpec,
    rig: Rig,
    captures: Vec<SweepCapture>,
    /// Dense class ids in first-seen order.
    class_ids: HashMap<(i64, i64, i64), usize>,
    class_of: Vec<usize>,
    /// The first capture of each class.
    class_first: Vec<usize>,
    completed: Vec<bool>,
    model: Option<LayeredResampler>,
    /// The smooth model of the same nodes, built with the interpolant.
    smooth: Option<SmoothBrdf>,
    model_built_with: usize,
    model_layer_counts: HashMap<i64, usize>,
    model_builds: usize,
    level_history: HashMap<i64, ScaleHistory>,
    joint_history: [ScaleHistory; 2],
    level_cusum: Cusum,
    joint_cusum: [Cusum; 2],
    latched: HashSet<Latch>,
    h_level: f64,
    h_joint: f64,
    last: Option<SweepRecord>,
    tested: usize,
    /// Every completed sweep, in order.
    sweep_starts: Vec<SweepSpan>,
    /// Each light direction's nominal azimuth (radians; NaN until a capture of it is seen).
    light_phi: Vec<f64>,
    /// Per θi layer, the harmonics of the level pattern its level history was judged with.
    level_model: HashMap<i64, usize>,
    /// The last joint slip named: its θi layer, the joint, and the first capture it can have
    /// affected. A level change that begins after it in the same layer is the tilt's.
    slip: Option<(i64, usize, u64)>,
    /// The gain steps raised so far: θi layer, the capture the alarm came at, where the drift
    /// model's step term was placed (seconds) and the level (%).
    level_steps: Vec<(i64, u64, Option<f64>, f64)>,
}

/// Where a completed sweep lies in the session, and the joint offsets its pattern fit gave
/// (NaN where it gave none).
#[derive(Debug, Clone, Copy)]
struct SweepSpan {
    light: usize,
    first_idx: u64,
    last_idx: u64,
    first_t: f64,
    layer: i64,
    /// The joints' offsets of detection's fit (the interpolant's sensitivities).
    offsets: [f64; 2],
    /// The joints' offsets and standard errors of the smooth model's fit, and the sweep's mean
    /// smooth sensitivity to each joint (ln Y per degree): what a level change is attributed
    /// by (`SweepMonitor::attribute_level`). NaN where there is no fit.
    smooth: [(f64, f64); 2],
    smooth_s: [f64; 2],
}

/// What testing one completed sweep gave.
#[derive(Debug, Clone, Default)]
pub(crate) struct SweepOutcome {
    /// The sweep's record (none when it had too few comparable captures).
    pub record: Option<SweepRecord>,
    pub alarms: Vec<Alarm>,
    /// A gain step alarmed in this sweep, placed at the first capture of the sweep where its
    /// CUSUM run began (controller seconds).
    pub step_at_s: Option<f64>,
    /// A joint slip named in this sweep, placed at the first capture of the sweep before the
    /// first that showed it, as the retake list places it (controller seconds).
    pub slip_at_s: Option<f64>,
    /// Earlier gain steps this slip explains (their `step_at_s`): out of the drift model.
    pub withdrawn_steps_s: Vec<f64>,
}

/// The light-sweep checks in the session summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepSummary {
    /// Sweeps tested so far.
    pub tested: usize,
    /// The latest sweep's record.
    pub last: Option<SweepRecord>,
}

/// The in-control history a statistic is scaled by. A value seen while its CUSUM has a run
/// under way is held back, so the sweeps of a developing fault do not inflate the scale they are
/// judged by; the held values join the history when the run dies out, are dropped when it ends
/// in an alarm, and join anyway once `HELD_MAX` have piled up (a lasting new normal).
#[derive(Debug, Clone, Default)]
struct ScaleHistory {
    values: Vec<f64>,
    held: Vec<f64>,
}

const HELD_MAX: usize = 8;

/// A θi layer's level is judged by its own scale history from this many sweeps on, by the
/// layer below's before (`SweepMonitor::prior_level_scale`).
const OWN_SCALE_SWEEPS: usize = 4;
/// Sweeps a lower layer needs before its scale is lent to the layer above.
const PRIOR_MIN_SWEEPS: usize = 4;
/// The lent scale's margin over the tan² growth (the footprint's pattern is not exactly tan²).
const PRIOR_SAFETY: f64 = 2.0;

impl ScaleHistory {
    fn len(&self) -> usize {
        self.values.len()
    }

    fn scale(&self) -> f64 {
        robust_scale_about_zero(&self.values)
    }

    /// Records `v` after its CUSUM was updated: `active` when the CUSUM is above zero after it,
    /// `alarmed` when it raised an alarm.
    fn record(&mut self, v: f64, active: bool, alarmed: bool) {
        if alarmed {
            self.held.clear();
        } else if active && self.held.len() < HELD_MAX {
            self.held.push(v);
        } else {
            self.values.append(&mut self.held);
            self.values.push(v);
        }
    }
}

fn group_means(values: &[f64], groups: &[usize], n: usize) -> Vec<f64> {
    let mut sum = vec![0.0; n];
    let mut count = vec![0usize; n];
    for (v, g) in values.iter().zip(groups) {
        sum[*g] += v;
        count[*g] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, c)| if *c > 0 { s / *c as f64 } else { 0.0 })
        .collect()
}

/// A capture's sensitivity beyond this many robust scales of its sweep's is left out of the fit.
const LEVERAGE_CAP: f64 = 6.0;

/// A slip's size is taken from the smooth model's fit of a sweep only when its standard error
/// is at most this (degrees; twice the joint tolerance); a looser fit falls back to the
/// interpolant's.
const SMOOTH_SE_MAX_DEG: f64 = 0.5;

/// A level crossing is the tilt's, not the lamp's, when the smooth model's offset of a joint
/// over the crossing's sweeps departs from its earlier sweeps' by this many standard
/// deviations (one-sided normal tail 0.13 %), in the direction that explains the level, and
/// by at least the joint tolerance. The deviation counts the earlier sweeps' spread as one
/// shared offset, not as noise that averages out: a layer's nuisance moves consecutive sweeps
/// alike.
const ATTRIBUTION_Z: f64 = 3.0;

/// Residual trimming of the per-sweep fit: passes, and the cut in robust residual scales.
const TRIM_PASSES: usize = 2;
const TRIM_SCALES: f64 = 3.0;

/// Earlier lights of a θi layer before its level pattern is fitted: the 4th harmonic (with a
/// constant: 3 coefficients), then the 2nd as well (5).
const PATTERN_MIN_LIGHTS: [usize; 2] = [6, 10];

/// A θi layer's level pattern at the current light (`SweepMonitor::expected_level`): the level
/// it predicts, the prediction's standard deviation, and its model (`harmonics`: its columns
/// beyond the constant, so a harmonic entering and the borrowed 2nd harmonic entering or
/// leaving each change it).
#[derive(Debug, Clone)]
struct LayerPattern {
    level: f64,
    sd: f64,
    harmonics: usize,
    /// The earlier lights' residuals about the fit, widened by √(n / (n − p)) to stand for
    /// out-of-sample ones: a layer's scale history restarts from them when its model grows.
    residuals: Vec<f64>,
}

/// The layer below lends its 2nd harmonic's phase only when its amplitude is this many
/// standard errors from zero, and only to a layer whose 4th harmonic is as clear.
const BORROW_SIGMAS: f64 = 3.0;

/// The amplitude of a (cos, sin) coefficient pair in units of its standard error along its
/// own direction, from the coefficients `b` and their covariance `cov` (columns `i`, `i + 1`).
/// 0 for a zero amplitude or a zero or non-finite variance (an exact fit has no phase to lend).
fn amplitude_t(b: &DVector<f64>, cov: &DMatrix<f64>, i: usize) -> f64 {
    let (c, s) = (b[i], b[i + 1]);
    let a = c.hypot(s);
    if !(a > 0.0 && a.is_finite()) {
        return 0.0;
    }
    let u = [c / a, s / a];
    let var = u[0] * u[0] * cov[(i, i)]
        + 2.0 * u[0] * u[1] * cov[(i, i + 1)]
        + u[1] * u[1] * cov[(i + 1, i + 1)];
    if !(var > 0.0 && var.is_finite()) {
        return 0.0;
    }
    a / var.sqrt()
}

/// A layer's level pattern fit: the pattern, the coefficients and their covariance.
struct LevelPatternFit {
    pattern: LayerPattern,
    coef: DVector<f64>,
    cov: DMatrix<f64>,
}

/// A layer's level pattern at azimuth `here` from its earlier lights' levels `values` at
/// `azimuths`: least squares on a constant, `harmonics` (cos and sin columns each), and with
/// `borrowed` a 2nd harmonic of that phase ((cos 2φ, sin 2φ) weights) as the last column.
fn pattern_fit(
    azimuths: &[f64],
    values: &[f64],
    harmonics: &[f64],
    borrowed: Option<[f64; 2]>,
    here: f64,
) -> Option<LevelPatternFit> {
    let row = |p: f64| -> Vec<f64> {
        let mut v = vec![1.0];
        for h in harmonics {
            v.push((h * p).cos());
            v.push((h * p).sin());
        }
        if let Some(u) = borrowed {
            v.push(u[0] * (2.0 * p).cos() + u[1] * (2.0 * p).sin());
        }
        v
    };
    let (n, cols) = (
        azimuths.len(),
        1 + 2 * harmonics.len() + borrowed.is_some() as usize,
    );
    if n <= cols || values.len() != n {
        return None;
    }
    let rows: Vec<Vec<f64>> = azimuths.iter().map(|&p| row(p)).collect();
    let x = DMatrix::from_fn(n, cols, |i, j| rows[i][j]);
    let y = DVector::from_column_slice(values);
    let b = x.clone().svd(true, true).solve(&y, 1e-9).ok()?;
    let x0 = DVector::from_vec(row(here));
    let level = x0.dot(&b);
    // the prediction's standard deviation: σ²·(1 + x₀ᵀ(XᵀX)⁻¹x₀)
    let resid = &y - &x * &b;
    let sigma2 = resid.norm_squared() / (n - cols).max(1) as f64;
    let widen = (n as f64 / (n - cols).max(1) as f64).sqrt();
    let inv = (x.transpose() * &x).pseudo_inverse(1e-12).ok()?;
    let sd = (sigma2 * (1.0 + (x0.transpose() * &inv * &x0)[(0, 0)]))
        .max(0.0)
        .sqrt();
    (level.is_finite() && sd.is_finite()).then(|| LevelPatternFit {
        pattern: LayerPattern {
            level,
            sd,
            harmonics: cols - 1,
            residuals: resid.iter().map(|e| e * widen).collect(),
        },
        cov: inv * sigma2,
        coef: b,
    })
}

/// A harmonic is fitted only where the layer's lights sample its period at least this often
/// (the 4th at azimuth steps of 22.5° and less, θi ≥ 45° on the UBO plan; the 2nd at 45°).
const PATTERN_SAMPLES_PER_PERIOD: f64 = 4.0;

/// Back-fitting iterations of the F + L + C reference (converged to < 1e-4 by 30 on UBO runs).
const BACKFIT_ITERATIONS: usize = 30;

impl SweepMonitor {
    /// `lights` is the plan's number of light directions (the looks per run).
    pub(crate) fn new(spec: SweepSpec, rig: Rig, lights: usize) -> Self {
        let looks = lights.max(1) as f64;
        SweepMonitor {
            h_level: cusum_threshold(spec.cusum_k, spec.false_alarm_runs * looks),
            // two joints
            h_joint: cusum_threshold(spec.cusum_k, spec.false_alarm_runs * looks * 2.0),
            spec,
            rig,
            captures: Vec::new(),
            class_ids: HashMap::new(),
            class_of: Vec::new(),
            class_first: Vec::new(),
            completed: vec![false; lights],
            model: None,
            smooth: None,
            model_built_with: 0,
            model_layer_counts: HashMap::new(),
            model_builds: 0,
            level_history: HashMap::new(),
            joint_history: Default::default(),
            level_cusum: Cusum::default(),
            joint_cusum: [Cusum::default(), Cusum::default()],
            latched: HashSet::new(),
            last: None,
            tested: 0,
            sweep_starts: Vec::new(),
            light_phi: vec![f64::NAN; lights],
            level_model: HashMap::new(),
            slip: None,
            level_steps: Vec::new(),
        }
    }

    /// The CUSUM thresholds (level, joints).
    #[cfg(test)]
    fn thresholds(&self) -> (f64, f64) {
        (self.h_level, self.h_joint)
    }

    /// Controller time of the first capture of the sweep that ended at capture `last_idx`.
    fn sweep_start(&self, last_idx: u64) -> Option<f64> {
        self.sweep_starts
            .iter()
            .find(|s| s.last_idx == last_idx)
            .map(|s| s.first_t)
            .filter(|t| t.is_finite())
    }

    /// The first capture of the sweep that ends at `last_idx`.
    fn sweep_first_idx(&self, last_idx: u64) -> u64 {
        self.sweep_starts
            .iter()
            .find(|s| s.last_idx == last_idx)
            .map_or(last_idx, |s| s.first_idx)
    }

    /// The first capture a slip can have affected when the CUSUM run began with the sweep that
    /// ends at `last_idx`: the sweep taken just before it (by capture index, not by when it
    /// completed) may hold the slip's start without showing it (a slip late in a sweep moves
    /// too few of its captures), so its captures count too.
    fn slip_first_idx(&self, last_idx: u64) -> u64 {
        let first = self.sweep_first_idx(last_idx);
        self.sweep_starts
            .iter()
            .filter(|s| s.last_idx < first)
            .max_by_key(|s| s.last_idx)
            .map_or(first, |s| s.first_idx)
    }

    /// Controller time of `slip_first_idx(last_idx)` (seconds).
    fn slip_first_t(&self, last_idx: u64) -> Option<f64> {
        let first = self.slip_first_idx(last_idx);
        self.sweep_starts
            .iter()
            .find(|s| s.first_idx == first)
            .map(|s| s.first_t)
            .filter(|t| t.is_finite())
    }

    pub(crate) fn summary(&self) -> SweepSummary {
        SweepSummary {
            tested: self.tested,
            last: self.last.clone(),
        }
    }

    pub(crate) fn add(&mut self, c: SweepCapture) {
        if !(c.y > 0.0 && c.y.is_finite()) {
            return;
        }
        let n = self.class_ids.len();
        let id = *self.class_ids.entry(c.class).or_insert(n);
        if id == n {
            self.class_first.push(self.captures.len());
        }
        self.class_of.push(id);
        if let Some(phi) = self.light_phi.get_mut(c.light) {
            *phi = c.omega_i.y.atan2(c.omega_i.x);
        }
        self.captures.push(c);
    }

    fn layer_count(&self, layer: i64) -> usize {
        self.captures.iter().filter(|c| c.layer == layer).count()
    }

    /// The interpolant of BRDF-like values (Y / cos θi), rebuilt when the data grew by a
    /// quarter or the current layer doubled. `class_effect` is the F of the back-fit (ln units,
    /// per class id; NaN where a class has no earlier member): each class is one node at its
    /// first member's directions, free of the per-light and per-camera effects (raw captures as
    /// nodes carry those effects into the sensitivities). No reciprocal swaps: F(θi, θo) keeps
    /// the θi-dependent part of the lamp footprint, so a swapped node can be off by tens of per
    /// cent at grazing light.
    fn ensure_model(&mut self, layer: i64, class_effect: &[f64]) {
        let total = self.captures.len();
        let here = self.layer_count(layer);
        let built_here = self.model_layer_counts.get(&layer).copied().unwrap_or(0);
        let stale = self.model.is_none()
            || total as f64 >= 1.25 * self.model_built_with as f64
            || here >= 2 * built_here.max(1);
        if !stale {
            return;
        }
        let mut samples = Vec::with_capacity(self.class_first.len());
        let mut nodes = Vec::with_capacity(self.class_first.len());
        for (&k, fx) in self.class_first.iter().zip(class_effect) {
            if !fx.is_finite() {
                continue;
            }
            let y = fx.exp();
            let c = &self.captures[k];
            let ci = c.omega_i.z;
            if ci <= 1e-3 {
                continue;
            }
            let f = y / ci;
            nodes.push(Node {
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                ln_f: f.ln(),
            });
            samples.push(Sample {
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                value: [f, f, f],
            });
        }
        self.smooth = SmoothBrdf::fit(&nodes);
        if let Ok(m) = LayeredResampler::new(&samples, &ResampleSpec::default()) {
            self.model = Some(m);
            self.model_builds += 1;
            self.model_built_with = total;
            let mut counts = HashMap::new();
            for c in &self.captures {
                *counts.entry(c.layer).or_insert(0) += 1;
            }
            self.model_layer_counts = counts;
        }
    }

    /// ln Y a model expects at a pose (the cosine included).
    fn ln_y(&self, pose: &Pose, model: Model) -> Option<f64> {
        let inc = self.rig.forward(pose).ok()?;
        let ci = inc.omega_i.z;
        if ci <= 1e-3 || inc.omega_o.z <= 1e-3 {
            return None;
        }
        let v = match model {
            Model::Interpolant => {
                let v = self
                    .model
                    .as_ref()?
                    .at(&inc.omega_i, &inc.omega_o)
                    .ok()?
                    .value[1];
                (v > 0.0).then(|| v.ln())?
            }
            Model::Smooth => self.smooth.as_ref()?.ln_f(&inc.omega_i, &inc.omega_o)?,
        };
        let ln_y = v + ci.ln();
        ln_y.is_finite().then_some(ln_y)
    }

    /// ∂ ln Y / ∂q (per degree of the axis's reading) for joints 1 and 2 and the wagon, from
    /// `model`: a central difference, or a one-sided one where the other side leaves the data
    /// (the current θi layer is the top one in a light-outer run, and neither model
    /// extrapolates). `None` when a joint has neither side; the wagon's is NaN then.
    fn sensitivities(&self, cmd: &[f64; 4], model: Model) -> Option<[f64; 3]> {
        let h = self.spec.sensitivity_step_deg;
        // axis 3 is the wagon (cmd[3])
        let pose = |j: usize, d: f64| {
            let mut p = Pose {
                joints_deg: [cmd[0], cmd[1], cmd[2]],
                wagon_deg: cmd[3],
            };
            if j < 3 {
                p.joints_deg[j] = cmd[j] + d;
            } else {
                p.wagon_deg = cmd[3] + d;
            }
            p
        };
        let centre = self.ln_y(&pose(0, 0.0), model)?;
        let slope = |j: usize| match (
            self.ln_y(&pose(j, h), model),
            self.ln_y(&pose(j, -h), model),
        ) {
            (Some(up), Some(down)) => Some((up - down) / (2.0 * h)),
            (Some(up), None) => Some((up - centre) / h),
            (None, Some(down)) => Some((centre - down) / h),
            (None, None) => None,
        };
        // the wagon's only where it is used (the slip's size)
        let wagon = match model {
            Model::Smooth => slope(3).unwrap_or(f64::NAN),
            Model::Interpolant => f64::NAN,
        };
        Some([slope(0)?, slope(1)?, wagon])
    }

    /// The light direction `light` is complete: test its sweep against the earlier ones.
    /// With `mount` (the off-centre mount's pattern, once the drift model carries it), every
    /// luminance is taken less that pattern: it moves the level with the light's azimuth. With
    /// `gain` (the drift model's fitted path), less the gain as well: the level test looks for
    /// steps beyond the modelled drift, and a drift inside a θi layer is not read as part of
    /// the layer's azimuthal pattern, nor a step already fitted as a new one.
    pub(crate) fn light_complete(
        &mut self,
        light: usize,
        level_test: bool,
        mount: Option<&MountPattern>,
        gain: Option<&GainPath>,
    ) -> SweepOutcome {
        let nothing = SweepOutcome::default();
        let Some(done) = self.completed.get_mut(light) else {
            return nothing;
        };
        *done = true;
        let Some(sweep) = self.sweep_of(light) else {
            return nothing;
        };
        self.sweep_starts.push(SweepSpan {
            light,
            first_idx: sweep.first_idx,
            last_idx: sweep.last_idx,
            first_t: sweep.first_t,
            layer: sweep.layer,
            offsets: [f64::NAN; 2],
            smooth: [(f64::NAN, f64::NAN); 2],
            smooth_s: [f64::NAN; 2],
        });
        let known = Known { mount, gain };
        let reference = self.backfit(&sweep.past, &known);
        self.ensure_model(sweep.layer, &reference.class_effects());
        let (all, rows) = self.residuals(&sweep.current, &reference, &known, Model::Interpolant);
        if all.len() < self.spec.min_captures {
            return nothing;
        }
        // the level: the mean residual of every capture with an earlier class member
        let na = all.len() as f64;
        let level = all.iter().sum::<f64>() / na;
        let level_se =
            (all.iter().map(|e| (e - level).powi(2)).sum::<f64>() / (na - 1.0).max(1.0) / na)
                .sqrt();
        let pattern = self.pattern_fit(rows.iter().map(Row::joints).collect());
        self.smooth_offsets(&sweep, &reference, &known);
        let mut rec = SweepRecord {
            light,
            idx: sweep.last_idx,
            t: sweep.last_t,
            captures: all.len(),
            level_pct: 100.0 * level,
            level_expected_pct: 0.0,
            level_se_pct: 100.0 * level_se,
            level_z: None,
            level_cusum: 0.0,
            joints: Vec::new(),
            residual_sd: if pattern.sigma2.is_finite() {
                pattern.sigma2.sqrt()
            } else {
                0.0
            },
            thresholds: [self.h_level, self.h_joint],
            model_layers: 0,
            model_builds: self.model_builds,
        };
        let pattern_fit = self.expected_level(&sweep, &reference);
        let expected = pattern_fit.as_ref().map_or(0.0, |p| p.level);
        rec.level_expected_pct = 100.0 * expected;
        // a layer whose pattern model grew restarts its scale history from the earlier lights'
        // residuals about the new model: the levels judged without the harmonics carry the
        // pattern's swing
        let harmonics = pattern_fit.as_ref().map_or(0, |p| p.harmonics);
        if self
            .level_model
            .insert(sweep.layer, harmonics)
            .is_some_and(|h| h != harmonics)
        {
            let values = pattern_fit
                .as_ref()
                .map(|p| p.residuals.clone())
                .unwrap_or_default();
            self.level_history.insert(
                sweep.layer,
                ScaleHistory {
                    values,
                    held: Vec::new(),
                },
            );
        }
        let mut alarms = Vec::new();
        let level_step = if level_test {
            let floor = pattern_fit.as_ref().map_or(0.0, |p| p.sd);
            self.test_level(
                &sweep,
                (level - expected, level_se, floor),
                &known,
                &mut rec,
                &mut alarms,
            )
        } else {
            LevelStep::default()
        };
        let named = self.test_joints(
            &sweep,
            &pattern,
            level_step.alarmed,
            &known,
            &mut rec,
            &mut alarms,
        );
        let NamedSlip {
            at_s: slip_at_s,
            withdrawn_steps_s,
        } = level_step.slip.clone().or(named).unwrap_or_default();
        rec.model_layers = self
            .model
            .as_ref()
            .map(|m| m.layer_thetas().len())
            .unwrap_or(0);
        rec.model_builds = self.model_builds;
        self.last = Some(rec.clone());
        self.tested += 1;
        SweepOutcome {
            record: Some(rec),
            alarms,
            step_at_s: level_step.at_s,
            slip_at_s,
            withdrawn_steps_s,
        }
    }

    /// The level the sweep's θi layer predicts at its light's azimuth: the earlier lights of the
    /// layer's fitted effects L (the same back-fit, so the same gauge as the level) against
    /// their azimuths, by least squares on a constant and the harmonics a sample's outline
    /// repeats with: the 4th (a square sample's footprint returns every quarter turn), then
    /// the 2nd as well (a rectangle's, every half turn), each once `PATTERN_MIN_LIGHTS` earlier
    /// lights of the layer are in and the layer samples its period at least
    /// `PATTERN_SAMPLES_PER_PERIOD` times. (The 1st harmonic is an off-centre mount's, modelled
    /// by the drift stage.) At grazing light the pattern is as large as the steps the test looks
    /// for (±2 % at θi = 75° on the realistic preset), and consecutive sweeps share it, so
    /// unmodelled it adds up in the CUSUM. `None` while no harmonic is fitted.
    fn expected_level(&self, sweep: &Sweep, r: &Reference) -> Option<LayerPattern> {
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let here = phi(sweep.light);
        if !here.is_finite() {
            return None;
        }
        let (lights, step) = self.layer_lights(sweep, sweep.layer, r);
        let harmonics: Vec<f64> = [(4.0, PATTERN_MIN_LIGHTS[0]), (2.0, PATTERN_MIN_LIGHTS[1])]
            .into_iter()
            .filter(|&(h, min)| lights.len() >= min && TAU / h >= PATTERN_SAMPLES_PER_PERIOD * step)
            .map(|(h, _)| h)
            .collect();
        if harmonics.is_empty() {
            return None;
        }
        let values: Vec<f64> = lights.iter().map(|&l| r.light[l]).collect();
        let azimuths: Vec<f64> = lights.iter().map(|&l| phi(l)).collect();
        // while the layer is too short an arc to fit its own 2nd harmonic, it takes the 2nd
        // harmonic with the phase of the layer below, its amplitude alone fitted, if with it
        // the layer's outline pattern (the 4th harmonic) stands out (`BORROW_SIGMAS`). (A free
        // 2nd harmonic on less than half its period, or a borrowed one in a layer without an
        // outline pattern, takes up a step instead.)
        if harmonics == [4.0] {
            if let Some(u) = self.second_harmonic_below(sweep, r) {
                if let Some(f) = pattern_fit(&azimuths, &values, &harmonics, Some(u), here) {
                    if amplitude_t(&f.coef, &f.cov, 1) >= BORROW_SIGMAS {
                        return Some(f.pattern);
                    }
                }
            }
        }
        pattern_fit(&azimuths, &values, &harmonics, None, here).map(|f| f.pattern)
    }

    /// The phase of the 2nd harmonic of the θi layer right below the sweep's, as the unit
    /// vector of its (cos 2φ, sin 2φ) coefficients: that layer's earlier lights' effects L
    /// fitted on a constant, the 4th harmonic where it samples it, and the 2nd. A sample's
    /// outline keeps its orientation from layer to layer, so its 2nd harmonic keeps its phase
    /// while its amplitude grows towards grazing. `None` unless the layer below has
    /// `PATTERN_MIN_LIGHTS[1]` lights, samples the 2nd harmonic's period
    /// `PATTERN_SAMPLES_PER_PERIOD` times, and its 2nd harmonic is `BORROW_SIGMAS` standard
    /// errors from zero.
    fn second_harmonic_below(&self, sweep: &Sweep, r: &Reference) -> Option<[f64; 2]> {
        let below = sweep
            .past
            .iter()
            .map(|&k| self.captures[k].layer)
            .filter(|&l| l < sweep.layer)
            .max()?;
        let (lights, step) = self.layer_lights(sweep, below, r);
        if lights.len() < PATTERN_MIN_LIGHTS[1] || TAU / 2.0 < PATTERN_SAMPLES_PER_PERIOD * step {
            return None;
        }
        let harmonics: &[f64] = if TAU / 4.0 >= PATTERN_SAMPLES_PER_PERIOD * step {
            &[2.0, 4.0]
        } else {
            &[2.0]
        };
        if lights.len() <= 1 + 2 * harmonics.len() {
            return None;
        }
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let azimuths: Vec<f64> = lights.iter().map(|&l| phi(l)).collect();
        let values: Vec<f64> = lights.iter().map(|&l| r.light[l]).collect();
        let f = pattern_fit(&azimuths, &values, harmonics, None, 0.0)?;
        let amplitude = f.coef[1].hypot(f.coef[2]);
        (amplitude_t(&f.coef, &f.cov, 1) >= BORROW_SIGMAS)
            .then(|| [f.coef[1] / amplitude, f.coef[2] / amplitude])
    }

    /// The earlier lights of θi layer `layer` with a finite azimuth and a finite effect L
    /// (sorted), and the layer's azimuth step: the smallest gap between their azimuths.
    fn layer_lights(&self, sweep: &Sweep, layer: i64, r: &Reference) -> (Vec<usize>, f64) {
        let phi = |l: usize| self.light_phi.get(l).copied().unwrap_or(f64::NAN);
        let mut lights: Vec<usize> = sweep
            .past
            .iter()
            .filter(|&&k| self.captures[k].layer == layer)
            .map(|&k| self.captures[k].light)
            .collect();
        lights.sort_unstable();
        lights.dedup();
        lights.retain(|&l| phi(l).is_finite() && r.light.get(l).is_some_and(|v| v.is_finite()));
        let mut az: Vec<f64> = lights.iter().map(|&l| phi(l).rem_euclid(TAU)).collect();
        az.sort_by(f64::total_cmp);
        let step = az
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|g| *g > 1e-6)
            .fold(f64::INFINITY, f64::min);
        (lights, step)
    }

    /// The captures of a just completed sweep and of the earlier completed ones.
    fn sweep_of(&self, light: usize) -> Option<Sweep> {
        let current: Vec<usize> = (0..self.captures.len())
            .filter(|&k| self.captures[k].light == light)
            .collect();
        let past: Vec<usize> = (0..self.captures.len())
            .filter(|&k| {
                let l = self.captures[k].light;
                l != light && self.completed.get(l).copied().unwrap_or(false)
            })
            .collect();
        let &last = current.iter().max_by_key(|&&k| self.captures[k].idx)?;
        let first_idx = current.iter().map(|&k| self.captures[k].idx).min()?;
        let first_t = current
            .iter()
            .map(|&k| self.captures[k].t)
            .fold(f64::INFINITY, f64::min);
        Some(Sweep {
            light,
            first_idx,
            last_idx: self.captures[last].idx,
            last_t: self.captures[last].t,
            layer: self.captures[last].layer,
            first_t,
            current,
            past,
        })
    }

    /// ln Y of capture `k`, less what the drift model already explains.
    fn ln_y_of(&self, k: usize, known: &Known) -> f64 {
        let c = &self.captures[k];
        c.y.ln()
            - known.mount.map_or(0.0, |m| m.ln_effect(&c.mount))
            - known.gain.map_or(0.0, |g| g.ln_at(c.t))
    }

    /// The F + L + C reference over the earlier sweeps, by back-fitting group means.
    fn backfit(&self, past: &[usize], known: &Known) -> Reference {
        let n_class = self.class_ids.len();
        let n_dir = self.completed.len();
        let y: Vec<f64> = past.iter().map(|&k| self.ln_y_of(k, known)).collect();
        let cls: Vec<usize> = past.iter().map(|&k| self.class_of[k]).collect();
        let lig: Vec<usize> = past.iter().map(|&k| self.captures[k].light).collect();
        let cam: Vec<usize> = past
            .iter()
            .map(|&k| self.captures[k].camera.min(n_dir - 1))
            .collect();
        let mut f = vec![0.0; n_class];
        let mut l = vec![0.0; n_dir];
        let mut c = vec![0.0; n_dir];
        let mut work = vec![0.0; y.len()];
        for _ in 0..BACKFIT_ITERATIONS {
            for i in 0..y.len() {
                work[i] = y[i] - l[lig[i]] - c[cam[i]];
            }
            f = group_means(&work, &cls, n_class);
            for i in 0..y.len() {
                work[i] = y[i] - f[cls[i]] - c[cam[i]];
            }
            l = group_means(&work, &lig, n_dir);
            for i in 0..y.len() {
                work[i] = y[i] - f[cls[i]] - l[lig[i]];
            }
            c = group_means(&work, &cam, n_dir);
        }
        let mut seen = vec![false; n_class];
        for &k in &cls {
            seen[k] = true;
        }
        Reference {
            class: f,
            light: l,
            camera: c,
            seen,
        }
    }

    /// The current sweep's residuals against the reference (captures whose class has an
    /// earlier member), and the rows of those with sensitivities from `model`.
    fn residuals(
        &self,
        current: &[usize],
        r: &Reference,
        known: &Known,
        model: Model,
    ) -> (Vec<f64>, Vec<Row>) {
        let n_dir = self.completed.len();
        let mut rows: Vec<Row> = Vec::new();
        let mut all: Vec<f64> = Vec::new();
        for &k in current {
            let cap = &self.captures[k];
            if !r.seen[self.class_of[k]] {
                continue;
            }
            let e = self.ln_y_of(k, known)
                - r.class[self.class_of[k]]
                - r.camera[cap.camera.min(n_dir - 1)];
            all.push(e);
            if let Some(s) = self.sensitivities(&cap.cmd, model) {
                rows.push(Row {
                    e,
                    s,
                    wagon_dir: cap.wagon_dir,
                });
            }
        }
        (all, rows)
    }

    /// The pattern: e = λ + Σ b_j s_j by SVD least squares over the rows. Rows whose
    /// sensitivity is far out of line with the sweep's others are left out first: they sit
    /// where the interpolant is least sure (a lobe's peak, a layer's edge) and, as
    /// high-leverage points, would pull the slope towards their own error. Then the fit is
    /// trimmed twice of rows beyond 3 robust residual scales (a capture the interpolant gets
    /// wrong, a bad frame) and refitted.
    fn pattern_fit<const N: usize>(&self, mut rows: Vec<(f64, [f64; N])>) -> PatternFit {
        let caps: Vec<f64> = (0..N)
            .map(|j| {
                let v: Vec<f64> = rows.iter().map(|r| r.1[j]).collect();
                let cap = LEVERAGE_CAP * robust_scale_about_zero(&v);
                // most sensitivities exactly 0 (or none): no cap rather than a cap at 0
                if cap > 0.0 {
                    cap
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        rows.retain(|r| r.1.iter().zip(&caps).all(|(v, cap)| v.abs() <= *cap));
        let p = N + 1;
        let mut fit = PatternFit {
            beta: DVector::zeros(p),
            sigma2: f64::NAN,
            inv: None,
        };
        for pass in 0..=TRIM_PASSES {
            let n = rows.len();
            if n < self.spec.min_captures {
                // too few rows left after a trim: the previous pass's fit stands
                if pass == 0 {
                    fit.inv = None;
                }
                break;
            }
            let x = DMatrix::from_fn(n, p, |i, j| if j == 0 { 1.0 } else { rows[i].1[j - 1] });
            let yv = DVector::from_iterator(n, rows.iter().map(|r| r.0));
            let svd = x.clone().svd(true, true);
            let Ok(b) = svd.solve(&yv, 1e-12) else {
                if pass == 0 {
                    fit.inv = None;
                }
                break;
            };
            let resid = &yv - &x * &b;
            fit.sigma2 = resid.norm_squared() / n.saturating_sub(p).max(1) as f64;
            let cond = svd.singular_values.max() / svd.singular_values.min().max(1e-300);
            fit.inv = if cond < 1e8 {
                (x.transpose() * &x).try_inverse()
            } else {
                None
            };
            fit.beta = b;
            let cut = TRIM_SCALES * robust_scale_about_zero(resid.as_slice());
            if !(cut > 0.0) || resid.iter().all(|r| r.abs() <= cut) {
                break;
            }
            let mut keep = resid.iter().map(|r| r.abs() <= cut);
            rows.retain(|_| keep.next().unwrap_or(false));
        }
        fit
    }

    /// The level against the earlier sweeps of the same θi layer: its CUSUM, and a `gain-step`
    /// alarm (once per sign and layer) when it crosses with a large enough mean and no joint's
    /// pattern explains it. `level` is the sweep's level less the layer pattern's prediction
    /// (ln units), with the level's standard error and the prediction's SD.
    fn test_level(
        &mut self,
        sweep: &Sweep,
        (level, level_se, pattern_sd): (f64, f64, f64),
        known: &Known,
        rec: &mut SweepRecord,
        alarms: &mut Vec<Alarm>,
    ) -> LevelStep {
        let (k, clip, layer) = (self.spec.cusum_k, self.spec.clip, sweep.layer);
        let mut step = LevelStep::default();
        let prior = self.prior_level_scale(layer);
        let hist = self.level_history.entry(layer).or_default();
        let own = hist.len();
        // a layer's own scale once it has `OWN_SCALE_SWEEPS` sweeps; before, the smaller of its
        // own and the layer below's grown to this θi (`prior_level_scale`), and the latter alone
        // before `min_layer_sweeps`: a step in a layer's first sweeps would otherwise set the
        // scale it is judged by
        let base = if own >= OWN_SCALE_SWEEPS.max(self.spec.min_layer_sweeps) {
            Some(hist.scale())
        } else if own >= self.spec.min_layer_sweeps {
            Some(prior.map_or(hist.scale(), |p| p.min(hist.scale())))
        } else {
            prior
        };
        let mut tested = false;
        if let Some(base) = base.filter(|_| level_se.is_finite()) {
            tested = true;
            let scale = base.max(2.0 * level_se).max(pattern_sd).max(1e-3);
            let z = (level / scale).clamp(-clip, clip);
            rec.level_z = Some(z);
            self.level_cusum.add(z, k, level, scale, sweep.last_idx);
            let cs = &self.level_cusum;
            for (sign, stat, run) in [(1i8, cs.up, cs.up_run), (-1i8, cs.down, cs.down_run)] {
                let mean = if run.n > 0 {
                    run.sum / run.n as f64
                } else {
                    0.0
                };
                if stat > self.h_level
                    && 100.0 * f64::from(sign) * mean >= self.spec.level_tolerance_pct
                    && self.latched.insert(Latch::Level { sign, layer })
                {
                    let from_idx = self.sweep_first_idx(run.start);
                    // a tilt changes cos θi and the footprint over whole sweeps: a level change
                    // that begins after a slip named in this layer is attributed to the slip
                    // and is no lamp step for the drift model
                    if let Some((_, joint, slip_idx)) = self
                        .slip
                        .filter(|&(l, _, first)| l == layer && from_idx >= first)
                    {
                        alarms.push(
                            Alarm::new(
                                AlarmKind::Positioning,
                                Severity::Info,
                                AlarmCode::LevelAfterSlip,
                                format!(
                                    "light sweep {} (captures up to {}) and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}°, beginning after joint {joint} was named (captures from {slip_idx}): read as the tilt's, not as a lamp step, and not taken into the drift model",
                                    sweep.light,
                                    sweep.last_idx,
                                    run.n.saturating_sub(1),
                                    100.0 * mean,
                                    layer as f64 / 1000.0,
                                ),
                            )
                            .at(Some(sweep.last_idx), Some(sweep.last_t))
                            .with(json!({"source": "light sweeps", "joint": joint, "level_pct": 100.0 * mean, "sweeps": run.n, "since_idx": run.start, "slip_from_idx": slip_idx, "statistic": stat, "threshold": self.h_level}))
                            .advise(
                                "Nothing more than for the joint alarm: check the sample clamp and the joint; these captures are already on the retake list. A level change that persists after the joint is fixed is the lamp's.",
                                Some(Affects::Since { from_idx: slip_idx, handling: Handling::Retake }),
                            ),
                        );
                        self.level_cusum.reset();
                        step.alarmed = true;
                        break;
                    }
                    // a tilt changes cos θi and the footprint as a lamp step would: the level is
                    // the lamp's only when no joint's pattern explains it (a layer that has named
                    // its slip keeps to one positioning alarm)
                    if let Some(x) = self
                        .attribute_level(layer, mean, run.start)
                        .filter(|_| !self.latched.contains(&Latch::Joint { layer }))
                    {
                        let x = self.slip_estimate(x, known);
                        step.slip = Some(self.name_slip(sweep, &x, rec, alarms));
                        self.level_cusum.reset();
                        step.alarmed = true;
                        break;
                    }
                    alarms.push(
                        Alarm::new(
                            AlarmKind::Drift,
                            Severity::Warning,
                            AlarmCode::GainStep,
                            format!(
                                "the gain level stepped {}: light sweep {} (captures up to {}) and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}° beyond the modelled drift (CUSUM {stat:.1} > {:.1}; from isotropy classes, no probes); the step's size is fitted from the isotropy classes from now on",
                                if sign > 0 { "up" } else { "down" },
                                sweep.light,
                                sweep.last_idx,
                                run.n.saturating_sub(1),
                                100.0 * mean,
                                layer as f64 / 1000.0,
                                self.h_level
                            ),
                        )
                        .at(Some(sweep.last_idx), Some(sweep.last_t))
                        .with(json!({"source": "light sweeps", "level_pct": 100.0 * mean, "sweeps": run.n, "since_idx": run.start, "since_t": self.sweep_start(run.start), "statistic": stat, "threshold": self.h_level}))
                        // the drift model takes the step from the start of that sweep
                        .advise(action::GAIN_STEP, Some(Affects::Since { from_idx: self.sweep_first_idx(run.start), handling: Handling::Corrected })),
                    );
                    step.at_s = self.sweep_start(run.start);
                    self.level_steps
                        .push((layer, sweep.last_idx, step.at_s, 100.0 * mean));
                    self.level_cusum.reset();
                    step.alarmed = true;
                    break;
                }
            }
            rec.level_cusum = self.level_cusum.max();
        }
        let active = tested && self.level_cusum.max() > 0.0;
        if let Some(hist) = self.level_history.get_mut(&layer) {
            hist.record(level, active, step.alarmed);
        }
        step
    }

    /// The level scale a θi layer with fewer than `OWN_SCALE_SWEEPS` sweeps is judged by: the
    /// robust scale of the nearest lower layer (θi ≥ 5°) with `PRIOR_MIN_SWEEPS` sweeps, times
    /// tan²θi / tan²θ_below (the lamp footprint's effect on a sweep's level grows towards
    /// grazing) and `PRIOR_SAFETY`. `None` without such a layer.
    fn prior_level_scale(&self, layer: i64) -> Option<f64> {
        let (&below, hist) = self
            .level_history
            .iter()
            .filter(|(&l, h)| l < layer && l >= 5000 && h.len() >= PRIOR_MIN_SWEEPS)
            .max_by_key(|(&l, _)| l)?;
        let tan2 = |l: i64| (l as f64 / 1000.0).to_radians().tan().powi(2);
        let growth = tan2(layer) / tan2(below);
        let s = hist.scale() * growth * PRIOR_SAFETY;
        (s.is_finite() && s > 0.0).then_some(s)
    }

    /// The joints: both CUSUMs are updated first; when one or both cross, the alarm names the
    /// joint with the larger statistic (one positioning alarm per θi layer). A sweep whose level
    /// stepped (`level_alarmed`: a lamp step part-way through it looks like a pattern across its
    /// cameras) raises no positioning alarm; the CUSUMs carry on, so a real offset is named at
    /// the next sweep. When it names a joint: the time the slip is placed at (seconds), and
    /// the earlier gain steps of its layer raised after the slip's first capture, which the
    /// slip explains (each withdrawn with an info alarm; their step terms, in seconds).
    fn test_joints(
        &mut self,
        sweep: &Sweep,
        pattern: &PatternFit,
        level_alarmed: bool,
        known: &Known,
        rec: &mut SweepRecord,
        alarms: &mut Vec<Alarm>,
    ) -> Option<NamedSlip> {
        let (k, clip) = (self.spec.cusum_k, self.spec.clip);
        let mut crossing: Option<JointCrossing> = None;
        for j in 0..2 {
            let b = pattern.beta[j + 1];
            let Some(bse) = pattern.se(j + 1).filter(|v| v.is_finite() && *v > 0.0) else {
                continue;
            };
            if let Some(span) = self.sweep_starts.last_mut() {
                span.offsets[j] = b;
            }
            let mut fit = JointFit {
                joint: j + 1,
                offset_deg: b,
                se_deg: bse,
                z: None,
                cusum: 0.0,
            };
            let hist = &self.joint_history[j];
            if hist.len() >= self.spec.min_sweeps {
                let nuisance = hist.scale();
                let scale = (bse * bse + nuisance * nuisance).sqrt();
                if scale > 0.0 {
                    let z = (b / scale).clamp(-clip, clip);
                    fit.z = Some(z);
                    self.joint_cusum[j].add(z, k, b, scale, sweep.last_idx);
                    let cs = &self.joint_cusum[j];
                    for (sign, stat, run) in [(1.0, cs.up, cs.up_run), (-1.0, cs.down, cs.down_run)]
                    {
                        if run.n == 0 {
                            continue;
                        }
                        let (mean, mean_se) = run.mean_and_se();
                        if stat > self.h_joint
                            && sign * mean >= self.spec.joint_tolerance_deg
                            && crossing.is_none_or(|c| stat > c.statistic)
                        {
                            crossing = Some(JointCrossing {
                                joint: j,
                                statistic: stat,
                                mean,
                                mean_se,
                                sweeps: run.n,
                                since: run.start,
                                estimate_sweeps: run.n,
                                run_mean: mean,
                                attributed_level: None,
                            });
                        }
                    }
                    fit.cusum = cs.max();
                }
            }
            rec.joints.push(fit);
        }
        let crossing = if level_alarmed {
            None
        } else {
            crossing.map(|x| self.slip_estimate(x, known))
        };
        // a crossing in a layer that already has its positioning alarm restarts the CUSUMs
        // without a second alarm (the operator has it; the next layer may raise one again)
        let mut named = None;
        if let Some(x) = &crossing {
            if !self.latched.contains(&Latch::Joint { layer: sweep.layer }) {
                named = Some(self.name_slip(sweep, x, rec, alarms));
            }
            for c in self.joint_cusum.iter_mut() {
                c.reset();
            }
            for f in rec.joints.iter_mut() {
                f.cusum = 0.0;
            }
        }
        for f in &rec.joints {
            let j = f.joint - 1;
            let active = f.z.is_some() && self.joint_cusum[j].max() > 0.0;
            self.joint_history[j].record(f.offset_deg, active, crossing.is_some());
        }
        named
    }

    /// Names the slip `x` in `sweep` (its layer's one positioning alarm): the alarm, the slip's
    /// place for the drift model, and the withdrawal of the gain steps of its layer raised
    /// after the slip's first capture, which the slip explains (each with an info alarm).
    fn name_slip(
        &mut self,
        sweep: &Sweep,
        x: &JointCrossing,
        rec: &SweepRecord,
        alarms: &mut Vec<Alarm>,
    ) -> NamedSlip {
        self.latched.insert(Latch::Joint { layer: sweep.layer });
        alarms.push(self.joint_alarm(sweep, x, rec));
        let at_s = self.slip_first_t(x.since);
        let slip_idx = self.slip_first_idx(x.since);
        self.slip = Some((sweep.layer, x.joint + 1, slip_idx));
        // a level change raised after the slip began, in its layer, was the tilt's
        let (explained, kept): (Vec<_>, Vec<_>) = self
            .level_steps
            .iter()
            .partition(|&&(l, idx, _, _)| l == sweep.layer && idx >= slip_idx);
        self.level_steps = kept;
        let mut withdrawn_steps_s = Vec::new();
        for (_, idx, step_at_s, level) in explained {
            alarms.push(
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Info,
                    AlarmCode::GainStepWithdrawn,
                    format!(
                        "the gain step raised at capture {idx} ({level:+.2} %) came after joint {} began to slip (captures from {slip_idx}): it is read as the tilt's, not the lamp's, and leaves the drift model",
                        x.joint + 1
                    ),
                )
                .at(Some(sweep.last_idx), Some(sweep.last_t))
                .with(json!({"source": "light sweeps", "joint": x.joint + 1, "step_idx": idx, "level_pct": level, "slip_from_idx": slip_idx}))
                .advise(
                    "Nothing more than for the joint alarm: check the sample clamp and the joint; these captures are on the retake list and the corrected colours no longer divide that step out.",
                    Some(Affects::Since { from_idx: slip_idx, handling: Handling::Retake }),
                ),
            );
            withdrawn_steps_s.extend(step_at_s);
        }
        for c in self.joint_cusum.iter_mut() {
            c.reset();
        }
        NamedSlip {
            at_s,
            withdrawn_steps_s,
        }
    }

    /// The smooth model's fit of the sweep just completed (the last span): each joint's offset
    /// with its standard error, and the mean sensitivity. Kept for `attribute_level`.
    fn smooth_offsets(&mut self, sweep: &Sweep, reference: &Reference, known: &Known) {
        let (_, rows) = self.residuals(&sweep.current, reference, known, Model::Smooth);
        if rows.len() < self.spec.min_captures {
            return;
        }
        let n = rows.len() as f64;
        let fit = self.pattern_fit(rows.iter().map(Row::joints).collect());
        let mut smooth = [(f64::NAN, f64::NAN); 2];
        let mut smooth_s = [f64::NAN; 2];
        for j in 0..2 {
            if let Some(se) = fit.se(j + 1).filter(|v| v.is_finite() && *v > 0.0) {
                smooth[j] = (fit.beta[j + 1], se);
            }
            smooth_s[j] = rows.iter().map(|r| r.s[j]).sum::<f64>() / n;
        }
        if let Some(span) = self.sweep_starts.last_mut() {
            span.smooth = smooth;
            span.smooth_s = smooth_s;
        }
    }

    /// Whether the level change of mean `level` (ln units) in θi layer `layer`, over the sweeps
    /// from capture `since` on, is a joint's tilt. Each joint's smooth-model offset over those
    /// sweeps but the first is compared with the layer's earlier sweeps (or every earlier sweep while the
    /// layer has fewer than `min_sweeps`): its median is the in-control offset and its robust
    /// scale the nuisance. The tilt that would make the level is the level over the sweeps'
    /// mean sensitivity. A joint whose departure points the same way, by `ATTRIBUTION_Z` and
    /// the joint tolerance, takes the level (the larger departure of the two). Only sweeps
    /// whose smooth fit is within `SMOOTH_SE_MAX_DEG` count, so a layer the model does not know
    /// yet attributes nothing. A lamp step leaves the joints' offsets where they were.
    fn attribute_level(&self, layer: i64, level: f64, since: u64) -> Option<JointCrossing> {
        let usable = |v: (f64, f64)| v.0.is_finite() && v.1 > 0.0 && v.1 <= SMOOTH_SE_MAX_DEG;
        let mut best: Option<JointCrossing> = None;
        for j in 0..2 {
            // the crossing's first sweep is left out: a lamp step part-way through a sweep
            // splits its cameras into two levels, a pattern across them that a joint's
            // sensitivity can follow (so a crossing of a single sweep stays the lamp's)
            let run: Vec<(f64, f64, f64, u64)> = self
                .sweep_starts
                .iter()
                .filter(|s| s.last_idx >= since && usable(s.smooth[j]))
                .map(|s| (s.smooth[j].0, s.smooth[j].1, s.smooth_s[j], s.last_idx))
                .skip(1)
                .collect();
            if run.is_empty() {
                continue;
            }
            let earlier = |same_layer: bool| -> Vec<f64> {
                let mut v: Vec<f64> = self
                    .sweep_starts
                    .iter()
                    .filter(|s| s.last_idx < since && usable(s.smooth[j]))
                    .filter(|s| !same_layer || s.layer == layer)
                    .map(|s| s.smooth[j].0)
                    .collect();
                v.sort_by(f64::total_cmp);
                v
            };
            let mut before = earlier(true);
            if before.len() < self.spec.min_sweeps {
                before = earlier(false);
            }
            if before.len() < self.spec.min_sweeps {
                continue;
            }
            let centre = median_sorted(&before);
            let centred: Vec<f64> = before.iter().map(|v| v - centre).collect();
            let nuisance = robust_scale_about_zero(&centred);
            // the decision rests on every sweep of the crossing, as the level's did: judged from
            // a change point picked for its departure, a lone nuisance sweep would pass
            let n = run.len() as f64;
            let offset = run.iter().map(|v| v.0).sum::<f64>() / n - centre;
            let se = run.iter().map(|v| v.1 * v.1).sum::<f64>().sqrt() / n;
            let sensitivity = run.iter().map(|v| v.2).sum::<f64>() / n;
            let implied = level / sensitivity;
            let z = offset.abs() / (se * se + nuisance * nuisance).sqrt();
            if implied.is_finite()
                && implied * offset > 0.0
                && z >= ATTRIBUTION_Z
                && offset.abs() >= self.spec.joint_tolerance_deg
                && best.is_none_or(|b| z > b.statistic)
            {
                best = Some(JointCrossing {
                    joint: j,
                    statistic: z,
                    mean: offset,
                    mean_se: se,
                    sweeps: run.len(),
                    since: slip_start(&run, centre, offset),
                    estimate_sweeps: run.len(),
                    run_mean: offset,
                    attributed_level: Some(level),
                });
            }
        }
        best
    }

    /// The slip's size from the sweeps that show it, each against a reference that holds none
    /// of them. The CUSUM run's own mean underestimates it twice over: a run starts at the first
    /// positive excursion, often a sweep or two before the slip, and each of its later sweeps is
    /// compared with class effects F that already average in the slipped captures before it
    /// (a class's first members after the slip hide it completely). So the run is cut at its
    /// change point (`change_point` on the sweeps' offsets), and every sweep from there on is
    /// fitted again against the F + L + C reference of the captures taken before the sweep
    /// preceding the change point (`slip_first_idx`); the estimate is the mean of those fits
    /// from their own change point. Where no refit is possible (too few captures with a class
    /// member before the cut) it is the mean of the run's own offsets from their change point.
    /// Detection is unchanged: only the alarm's size and its standard error come from here.
    fn slip_estimate(&self, mut x: JointCrossing, known: &Known) -> JointCrossing {
        let j = x.joint;
        let sign = if x.mean < 0.0 { -1.0 } else { 1.0 };
        // the offsets the crossing was found in: detection's, or for an attributed level the
        // smooth model's
        let offset = |s: &SweepSpan| match x.attributed_level {
            Some(_) if s.smooth[j].1 <= SMOOTH_SE_MAX_DEG => s.smooth[j].0,
            Some(_) => f64::NAN,
            None => s.offsets[j],
        };
        let run: Vec<SweepSpan> = self
            .sweep_starts
            .iter()
            .filter(|s| s.last_idx >= x.since && offset(s).is_finite())
            .copied()
            .collect();
        let values: Vec<f64> = run.iter().map(offset).collect();
        let Some(k) = change_point(&values, sign) else {
            return x;
        };
        let mean_of = |v: &[(f64, f64)]| {
            let m = v.len() as f64;
            (
                v.iter().map(|r| r.0).sum::<f64>() / m,
                v.iter().map(|r| r.1 * r.1).sum::<f64>().sqrt() / m,
            )
        };
        // the sweep taken before the change point may hold the slip's start without showing it
        // (`slip_first_idx`), so the reference stops before it too
        let cut = self.slip_first_idx(run[k].last_idx);
        let past: Vec<usize> = (0..self.captures.len())
            .filter(|&i| {
                let c = &self.captures[i];
                c.idx < cut && self.completed.get(c.light).copied().unwrap_or(false)
            })
            .collect();
        let reference = self.backfit(&past, known);
        let refits: Vec<(f64, f64)> = run[k..]
            .iter()
            .filter_map(|s| {
                let current: Vec<usize> = (0..self.captures.len())
                    .filter(|&i| self.captures[i].light == s.light)
                    .collect();
                // the size from the smooth model's sensitivities, the wagon's among them; where
                // that fit is too loose (a θi layer with too few lights for the model to know
                // its slope in θi), the interpolant's
                let (_, rows) = self.residuals(&current, &reference, known, Model::Smooth);
                let fit = self.pattern_fit(rows.iter().filter_map(Row::with_wagon).collect());
                let smooth = fit
                    .se(j + 1)
                    .filter(|v| v.is_finite() && *v > 0.0 && *v <= SMOOTH_SE_MAX_DEG)
                    .map(|se| (fit.beta[j + 1], se));
                smooth.or_else(|| {
                    let (_, rows) = self.residuals(&current, &reference, known, Model::Interpolant);
                    let fit = self.pattern_fit(rows.iter().map(Row::joints).collect());
                    let se = fit.se(j + 1).filter(|v| v.is_finite() && *v > 0.0)?;
                    Some((fit.beta[j + 1], se))
                })
            })
            .collect();
        let refitted: Vec<f64> = refits.iter().map(|r| r.0).collect();
        let (used, se_fallback) = match change_point(&refitted, sign) {
            Some(k2) => (refits[k2..].to_vec(), None),
            None => (
                values[k..].iter().map(|&v| (v, 0.0)).collect(),
                Some(x.mean_se),
            ),
        };
        let (mean, se) = mean_of(&used);
        if mean.is_finite() && sign * mean > 0.0 {
            x.mean = mean;
            x.mean_se = se_fallback.unwrap_or(se);
            x.estimate_sweeps = used.len();
        }
        x
    }

    fn joint_alarm(&self, sweep: &Sweep, x: &JointCrossing, rec: &SweepRecord) -> Alarm {
        let from_idx = self.slip_first_idx(x.since);
        let other: Vec<serde_json::Value> = rec
            .joints
            .iter()
            .filter(|f| f.joint != x.joint + 1)
            .map(|f| json!({"joint": f.joint, "offset_deg": f.offset_deg, "se_deg": f.se_deg, "cusum": f.cusum}))
            .collect();
        let threshold = if x.attributed_level.is_some() {
            ATTRIBUTION_Z
        } else {
            self.h_joint
        };
        let mut evidence = json!({"joint": x.joint + 1, "offset_deg": x.mean, "se_deg": x.mean_se, "estimate_sweeps": x.estimate_sweeps, "run_mean_deg": x.run_mean, "sweeps": x.sweeps, "since_idx": x.since, "statistic": x.statistic, "threshold": threshold, "other_joints": other});
        if let Some(level) = x.attributed_level {
            evidence["attributed_level_pct"] = json!(100.0 * level);
        }
        let size = format!(
            "joint {} looks offset by about {:+.2}° (± {:.2}°, from {} light sweep(s) against the captures before the slip)",
            x.joint + 1,
            x.mean,
            x.mean_se,
            x.estimate_sweeps
        );
        Alarm::new(
            AlarmKind::Positioning,
            Severity::Warning,
            AlarmCode::JointOffsetSuspected,
            match x.attributed_level {
                Some(level) => format!(
                    "{size}: light sweep {} and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}°, and that joint's pattern across their cameras departs from the earlier sweeps' by {:.1} standard deviations (threshold {ATTRIBUTION_Z}) in the direction that explains the level, while the encoders agree with the commands: read as the tilt's, not as a lamp step, and not taken into the drift model; a slipped joint or a moved sample is likely",
                    sweep.light,
                    x.sweeps.saturating_sub(1),
                    100.0 * level,
                    sweep.layer as f64 / 1000.0,
                    x.statistic,
                ),
                None => format!(
                    "{size}: the pattern across the cameras of light sweep {} and the {} before it follows that joint's sensitivity while the encoders agree with the commands; a slipped joint or a moved sample is likely (CUSUM {:.1} > {:.1})",
                    sweep.light,
                    x.sweeps.saturating_sub(1),
                    x.statistic,
                    self.h_joint
                ),
            },
        )
        .at(Some(sweep.last_idx), Some(sweep.last_t))
        .with(evidence)
        .advise(
            &format!(
                "Pause the run; check the sample clamp and arm joint {} (re-home the joint if it slipped, re-seat the sample if it moved), then resume; every capture since {from_idx} (the light sweep before the first one that showed it) is on the retake list.",
                x.joint + 1,
            ),
            Some(Affects::Since { from_idx, handling: Handling::Retake }),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_change_point_starts_the_shifted_tail() {
        // a CUSUM run that began on two small excursions before the shift
        assert_eq!(change_point(&[0.2, 0.05, 0.7, 0.9], 1.0), Some(2));
        assert_eq!(change_point(&[-0.2, -0.05, -0.7, -0.9], -1.0), Some(2));
        // a shift held from the start keeps every value; one late outlier alone is not a tail
        assert_eq!(change_point(&[1.0, 1.1, 0.9, 1.0], 1.0), Some(0));
        assert_eq!(change_point(&[0.9, 1.0, 1.0, 1.3], 1.0), Some(0));
        // the other sign's tail is not taken
        assert_eq!(change_point(&[0.8, 0.9, -0.1], -1.0), Some(2));
        assert_eq!(change_point(&[], 1.0), None);
        assert_eq!(change_point(&[f64::NAN, 1.0], 1.0), Some(1));
    }

    #[test]
    fn scale_history_holds_back_a_developing_run() {
        let mut h = ScaleHistory::default();
        for v in [0.1, -0.2, 0.15] {
            h.record(v, false, false);
        }
        let before = h.scale();
        // a run under way: held, the scale is unchanged
        h.record(3.0, true, false);
        h.record(3.5, true, false);
        assert_eq!(h.len(), 3);
        assert_eq!(h.scale(), before);
        // the run ends in an alarm: the held values are dropped
        h.record(4.0, false, true);
        assert_eq!(h.len(), 3);
        // a run that dies out joins the history
        h.record(0.3, true, false);
        h.record(-0.1, false, false);
        assert_eq!(h.len(), 5);
        // a lasting new normal joins after HELD_MAX
        for _ in 0..HELD_MAX + 1 {
            h.record(1.0, true, false);
        }
        assert!(h.len() > 5);
    }

    /// A monitor whose completed sweeps carry the given smooth fits of joint 1 (offset, its
    /// standard error, mean sensitivity in ln Y per degree), one sweep of 81 captures each in
    /// θi layer `layer`; joint 2's fits are steady at zero.
    fn with_smooth_fits(fits: &[(i64, f64, f64, f64)]) -> SweepMonitor {
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig, fits.len());
        for (k, &(layer, b, se, s)) in fits.iter().enumerate() {
            let first_idx = 81 * k as u64;
            m.sweep_starts.push(SweepSpan {
                light: k,
                first_idx,
                last_idx: first_idx + 80,
                first_t: 7.0 * first_idx as f64,
                layer,
                offsets: [0.0; 2],
                smooth: [(b, se), (0.01 * (k % 3) as f64, 0.05)],
                smooth_s: [s, 0.002],
            });
        }
        m
    }

    #[test]
    fn a_level_change_that_a_joints_pattern_explains_is_the_tilts_and_a_lamp_step_is_not() {
        // 10 in-control sweeps at θi = 60° (joint 1's offset 0 ± 0.05°), then 3 that read +0.8°:
        // a tilt of +0.8° with a mean sensitivity of −1 %/° lowers the level by 0.8 %
        let earlier: Vec<(i64, f64, f64, f64)> = (0..10)
            .map(|k| (60_000, 0.05 * ((k % 5) as f64 - 2.0) / 2.0, 0.07, -0.01))
            .collect();
        let tilted = |b: f64| {
            let mut v = earlier.clone();
            v.extend([(60_000, b, 0.07, -0.01); 3]);
            with_smooth_fits(&v)
        };
        let since = 81 * 10;
        let m = tilted(0.8);
        let x = m.attribute_level(60_000, -0.008, since).unwrap();
        assert_eq!(x.joint, 0);
        assert!((x.mean - 0.8).abs() < 0.05, "{x:?}");
        assert!(x.statistic >= ATTRIBUTION_Z && x.attributed_level == Some(-0.008));
        // judged without the crossing's first sweep (it may hold a lamp step part-way), and
        // placed at the first sweep judged: the retake list starts a sweep before it
        assert_eq!(x.since, since + 81 + 80);
        // the same sweeps with a rising level: the tilt would lower it, so it is the lamp's
        assert!(m.attribute_level(60_000, 0.008, since).is_none());
        // a lamp step leaves the pattern where it was
        assert!(tilted(0.02)
            .attribute_level(60_000, -0.015, since)
            .is_none());
        // a lamp step part-way through the crossing's first sweep puts a pattern into that
        // sweep alone: the lamp's
        let mut v = earlier.clone();
        v.extend([(60_000, 0.8, 0.07, -0.01), (60_000, 0.01, 0.07, -0.01)]);
        assert!(with_smooth_fits(&v)
            .attribute_level(60_000, -0.008, since)
            .is_none());
        // a departure below the joint tolerance is not a slip however significant
        assert!(tilted(0.2).attribute_level(60_000, -0.002, since).is_none());
        // a layer whose pattern swings by ±0.6° from sweep to sweep (a square footprint at
        // grazing light) takes a level for the tilt's only well beyond that swing
        let swinging: Vec<(i64, f64, f64, f64)> = (0..10)
            .map(|k| (75_000, 0.6 * (k as f64 * 1.3).sin(), 0.07, -0.05))
            .chain([(75_000, 0.8, 0.07, -0.05); 3])
            .collect();
        assert!(with_smooth_fits(&swinging)
            .attribute_level(75_000, -0.04, since)
            .is_none());
        // too few earlier sweeps with a usable fit (a layer the model does not know yet, and
        // nothing before it): nothing is attributed
        let loose: Vec<(i64, f64, f64, f64)> = (0..10)
            .map(|_| (60_000, 0.0, 0.9, -0.01))
            .chain([(60_000, 0.8, 0.07, -0.01); 3])
            .collect();
        assert!(with_smooth_fits(&loose)
            .attribute_level(60_000, -0.008, since)
            .is_none());
    }

    #[test]
    fn bad_luminance_unknown_lights_and_empty_sweeps_give_nothing() {
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig, 81);
        for (k, y) in [f64::NAN, f64::INFINITY, 0.0, -1.0, 1e-300]
            .iter()
            .enumerate()
        {
            m.add(SweepCapture {
                idx: k as u64,
                t: 7.0 * k as f64,
                light: 0,
                camera: k,
                class: (0, 0, k as i64),
                layer: 0,
                omega_i: Vec3::new(0.0, 0.0, 1.0),
                omega_o: Vec3::new(0.0, 0.0, 1.0),
                cmd: [0.0; 4],
                wagon_dir: 0.0,
                y: *y,
                mount: [0.0; 4],
            });
        }
        // only the positive finite value is kept
        assert_eq!(m.captures.len(), 1);
        let o = m.light_complete(0, true, None, None);
        assert!(o.record.is_none() && o.alarms.is_empty() && o.step_at_s.is_none());
        // a light the plan does not have, and a light with no capture at all
        let o = m.light_complete(500, true, None, None);
        assert!(o.record.is_none() && o.alarms.is_empty());
        let o = m.light_complete(7, true, None, None);
        assert!(o.record.is_none() && o.alarms.is_empty());
        assert_eq!(m.summary().tested, 0);
    }

    #[test]
    fn an_amplitude_is_judged_along_its_own_direction_and_a_degenerate_one_lends_no_phase() {
        // coefficients (const, cos, sin) = (1, 3, 4): amplitude 5 along (0.6, 0.8)
        let b = DVector::from_vec(vec![1.0, 3.0, 4.0]);
        let cov = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 0.25, 4.0]));
        // variance along (0.6, 0.8): 0.36·0.25 + 0.64·4 = 2.65
        assert!((amplitude_t(&b, &cov, 1) - 5.0 / 2.65f64.sqrt()).abs() < 1e-12);
        let zero = DVector::from_vec(vec![1.0, 0.0, 0.0]);
        assert_eq!(amplitude_t(&zero, &cov, 1), 0.0);
        // an exact fit (no variance) or a broken one has no phase to lend
        assert_eq!(amplitude_t(&b, &DMatrix::zeros(3, 3), 1), 0.0);
        let nan = DMatrix::from_element(3, 3, f64::NAN);
        assert_eq!(amplitude_t(&b, &nan, 1), 0.0);
        // too few lights for the model: no pattern
        assert!(pattern_fit(&[0.0, 1.0, 2.0], &[0.0; 3], &[4.0], None, 0.5).is_none());
    }

    /// The lent scale: the nearest lower layer with enough sweeps, grown by tan²θi; none from
    /// the pole's layer or from a layer with too few sweeps.
    #[test]
    fn a_layer_borrows_the_scale_of_the_nearest_lower_layer_grown_by_tan_squared() {
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig, 81);
        let history = |v: f64, n: usize| ScaleHistory {
            values: [v, -v].repeat(n.div_ceil(2))[..n].to_vec(),
            held: Vec::new(),
        };
        m.level_history.insert(0, history(0.001, 10));
        assert_eq!(m.prior_level_scale(15_000), None);
        m.level_history
            .insert(30_000, history(0.002, PRIOR_MIN_SWEEPS - 1));
        assert_eq!(m.prior_level_scale(45_000), None);
        m.level_history
            .insert(15_000, history(0.002, PRIOR_MIN_SWEEPS));
        let tan2 = |d: f64| d.to_radians().tan().powi(2);
        let want =
            0.002 * crate::measure::stats::MAD_TO_SIGMA * tan2(45.0) / tan2(15.0) * PRIOR_SAFETY;
        let got = m.prior_level_scale(45_000).unwrap();
        assert!((got / want - 1.0).abs() < 1e-9, "{got} {want}");
        // a layer lends only upwards
        assert_eq!(m.prior_level_scale(15_000), None);
    }

    #[test]
    fn thresholds_follow_the_false_alarm_budget() {
        let rig = Rig::new(Default::default()).unwrap();
        let m = SweepMonitor::new(SweepSpec::default(), rig.clone(), 81);
        let (hl, hj) = m.thresholds();
        assert!(hj > hl && hl > 2.0, "{hl} {hj}");
        let strict = SweepMonitor::new(
            SweepSpec {
                false_alarm_runs: 200.0,
                ..SweepSpec::default()
            },
            rig,
            81,
        );
        assert!(strict.thresholds().0 > hl);
    }
}

#[cfg(test)]
mod model_tests {
    use super::*;
    use crate::measure::geometry::Spherical;
    use crate::measure::kinematics::Incidence;
    use crate::measure::plan::{PlanDirection, SamplingPlan};

    /// A smooth isotropic BRDF: Lambert plus a Phong lobe about the mirror direction.
    pub(super) fn brdf(wi: &Vec3, wo: &Vec3) -> f64 {
        let m = Vec3::new(-wi.x, -wi.y, wi.z);
        0.3 + 2.0 * m.dot(wo).max(0.0).powi(4)
    }

    /// The nominal directions and the rig's pose of a plan entry (none where it cannot reach).
    pub(super) fn plan_pose(
        rig: &Rig,
        l: &PlanDirection,
        c: &PlanDirection,
    ) -> Option<(Incidence, Pose)> {
        let inc = Incidence {
            omega_i: Spherical::from_deg(l.theta_deg, l.phi_deg).to_vector(),
            omega_o: c.spherical().to_vector(),
        };
        let pose = rig.inverse(&inc).ok()?;
        Some((inc, pose))
    }

    fn session() -> (SweepMonitor, Vec<SweepCapture>, Rig) {
        let plan = SamplingPlan::ubo();
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig.clone(), plan.direction_count());
        let dirs = plan.directions().to_vec();
        let mut caps = Vec::new();
        for e in 0..plan.capture_count() {
            let pe = plan.entry(e).unwrap();
            let (l, c) = (dirs[pe.light], dirs[pe.camera]);
            let Some((inc, pose)) = plan_pose(&rig, &l, &c) else {
                continue;
            };
            let y = brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z;
            let cap = SweepCapture {
                idx: e as u64,
                t: 7.0 * e as f64,
                light: pe.light,
                camera: pe.camera,
                class: (0, 0, e as i64),
                layer: (l.theta_deg * 1000.0).round() as i64,
                omega_i: inc.omega_i,
                omega_o: inc.omega_o,
                cmd: [
                    pose.joints_deg[0],
                    pose.joints_deg[1],
                    pose.joints_deg[2],
                    pose.wagon_deg,
                ],
                wagon_dir: 0.0,
                y,
                mount: [0.0; 4],
            };
            m.add(cap.clone());
            caps.push(cap);
        }
        (m, caps, rig)
    }

    #[test]
    fn sensitivities_follow_the_true_brdf() {
        let (mut m, caps, rig) = session();
        // every capture is its own class here: its effect is its own ln Y
        let effects: Vec<f64> = caps.iter().map(|c| c.y.ln()).collect();
        m.ensure_model(60_000, &effects);
        let truth = |cmd: &[f64; 4], j: usize| {
            let f = |d: f64| {
                let mut p = Pose {
                    joints_deg: [cmd[0], cmd[1], cmd[2]],
                    wagon_deg: cmd[3],
                };
                p.joints_deg[j] += d;
                let inc = rig.forward(&p).unwrap();
                (brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z).ln()
            };
            (f(1.0) - f(-1.0)) / 2.0
        };
        let (mut num, mut den_m, mut den_t, mut n) = (0.0, 0.0, 0.0, 0);
        for cap in caps.iter().step_by(7) {
            if cap.omega_i.z < 0.3 || cap.omega_o.z < 0.3 {
                continue;
            }
            let Some(s) = m.sensitivities(&cap.cmd, Model::Interpolant) else {
                continue;
            };
            for j in 0..2 {
                let t = truth(&cap.cmd, j);
                num += s[j] * t;
                den_m += s[j] * s[j];
                den_t += t * t;
            }
            n += 1;
        }
        let corr = num / (den_m * den_t).sqrt();
        eprintln!(
            "n {n} corr {corr:.3} rms model {:.4} rms truth {:.4}",
            (den_m / n as f64).sqrt(),
            (den_t / n as f64).sqrt()
        );
        assert!(corr > 0.9, "{corr}");
    }
}

/// Whole synthetic sessions through the monitor: a smooth isotropic BRDF on the UBO plan, a
/// per-light footprint effect, 1 % capture noise, and one fault from `onset`.
#[cfg(test)]
mod session_tests {
    use super::model_tests::{brdf, plan_pose};
    use super::*;
    use crate::measure::geometry::azimuth_difference_deg;
    use crate::measure::plan::SamplingPlan;

    #[derive(Clone, Copy)]
    enum Fault {
        None,
        /// (joint index 0-based, degrees)
        Joint(usize, f64),
        /// gain factor
        Step(f64),
    }

    /// A deterministic standard normal draw (splitmix64 + Box–Muller).
    fn normal(seed: u64, k: u64) -> f64 {
        let mix = |mut z: u64| {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let a = mix(seed.wrapping_mul(1_000_003).wrapping_add(2 * k));
        let b = mix(a ^ 0x5555);
        let u1 = ((a >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
        let u2 = ((b >> 11) as f64) / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Runs the session up to (and including) light sweep `last_light`; returns the records
    /// and the alarms, each with the plan entry it was raised at.
    fn run(
        fault: Fault,
        onset: usize,
        last_light: usize,
        seed: u64,
        level_test: bool,
    ) -> (Vec<SweepRecord>, Vec<Alarm>) {
        run_outlined(fault, onset, last_light, seed, level_test, (0.0, 0.0))
    }

    /// `run` on a sample whose outline shapes the lamp's footprint: every light's level moves
    /// by `outline`·tan²θi·(cos 4φi + 0.4 cos 2φi), a square's quarter-turn pattern with a
    /// rectangle's half-turn one (1.8 % and 0.7 % at θi = 75° for 0.0013).
    fn run_outlined(
        fault: Fault,
        onset: usize,
        last_light: usize,
        seed: u64,
        level_test: bool,
        outline: (f64, f64),
    ) -> (Vec<SweepRecord>, Vec<Alarm>) {
        let (_, records, alarms) = simulate(fault, onset, last_light, seed, level_test, outline);
        (records, alarms)
    }

    /// `run_outlined`, and the monitor as the session left it.
    fn simulate(
        fault: Fault,
        onset: usize,
        last_light: usize,
        seed: u64,
        level_test: bool,
        (outline, second): (f64, f64),
    ) -> (SweepMonitor, Vec<SweepRecord>, Vec<Alarm>) {
        let plan = SamplingPlan::ubo();
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig.clone(), plan.direction_count());
        let dirs = plan.directions().to_vec();
        let (mut records, mut alarms) = (Vec::new(), Vec::new());
        let mut current: Option<usize> = None;
        let (mut last_w, mut wagon_dir) = (None::<f64>, 0.0);
        for e in 0..plan.capture_count() {
            let pe = plan.entry(e).unwrap();
            if current != Some(pe.light) {
                if let Some(done) = current {
                    let o = m.light_complete(done, level_test, None, None);
                    records.extend(o.record);
                    alarms.extend(o.alarms);
                    if done == last_light {
                        break;
                    }
                }
                current = Some(pe.light);
            }
            let (l, c) = (dirs[pe.light], dirs[pe.camera]);
            let Some((inc, pose)) = plan_pose(&rig, &l, &c) else {
                continue;
            };
            if let Some(w) = last_w.filter(|w| *w != pose.wagon_deg) {
                wagon_dir = (pose.wagon_deg - w).signum();
            }
            last_w = Some(pose.wagon_deg);
            let mut actual = pose;
            let mut gain = 1.0;
            if e >= onset {
                match fault {
                    Fault::None => {}
                    Fault::Joint(j, d) => actual.joints_deg[j] += d,
                    Fault::Step(g) => gain = g,
                }
            }
            let Ok(seen) = rig.forward(&actual) else {
                continue;
            };
            if seen.omega_i.z <= 0.0 || seen.omega_o.z <= 0.0 {
                continue;
            }
            let (ti, pi) = (l.theta_deg.to_radians(), l.phi_deg.to_radians());
            let shape =
                outline * ti.tan().powi(2) * ((4.0 * pi).cos() + second * (2.0 * pi - 1.0).cos());
            let footprint = 0.005 * normal(seed ^ 0xF00D, pe.light as u64) + shape;
            let y = brdf(&seen.omega_i, &seen.omega_o)
                * seen.omega_i.z
                * gain
                * (footprint + 0.01 * normal(seed, e as u64)).exp();
            let dphi = if l.theta_deg == 0.0 || c.theta_deg == 0.0 {
                0.0
            } else {
                azimuth_difference_deg(l.phi_deg, c.phi_deg)
            };
            let class = (
                (l.theta_deg * 1000.0).round() as i64,
                (c.theta_deg * 1000.0).round() as i64,
                (dphi * 1000.0).round() as i64,
            );
            m.add(SweepCapture {
                idx: e as u64,
                t: 7.0 * e as f64,
                light: pe.light,
                camera: pe.camera,
                class,
                layer: class.0,
                omega_i: inc.omega_i,
                omega_o: inc.omega_o,
                cmd: [
                    pose.joints_deg[0],
                    pose.joints_deg[1],
                    pose.joints_deg[2],
                    pose.wagon_deg,
                ],
                wagon_dir,
                y,
                mount: [0.0; 4],
            });
        }
        (m, records, alarms)
    }

    /// Mid-run, inside light sweep 46 (the θi = 60° layer's tenth).
    const ONSET: usize = 46 * 81 + 40;
    /// Eight sweeps after the onset.
    const LAST: usize = 54;

    #[test]
    fn a_fault_free_session_raises_nothing() {
        for seed in [1, 2] {
            let (records, alarms) = run(Fault::None, usize::MAX, LAST, seed, true);
            assert!(alarms.is_empty(), "seed {seed}: {alarms:?}");
            assert!(records.len() > 40, "{}", records.len());
            // the joint fits are tested once enough sweeps are behind them
            assert!(records.last().unwrap().joints.iter().all(|f| f.z.is_some()));
        }
    }

    /// The first positioning alarm names the offset joint with the offset's sign. A joint-1
    /// tilt also changes cos θi for the whole sweep, so it may show first as a level change,
    /// which the joint's pattern then claims.
    #[test]
    fn a_joint_offset_from_mid_run_names_that_joint() {
        for (joint, deg, onset) in [
            (1usize, 2.0, ONSET),
            (1, -1.0, ONSET),
            (0, 2.0, ONSET),
            (0, 2.0, 40 * 81 + 40),
        ] {
            let (_, alarms) = run(Fault::Joint(joint, deg), onset, LAST, 1, true);
            let first = alarms
                .iter()
                .find(|a| a.code == AlarmCode::JointOffsetSuspected)
                .unwrap_or_else(|| {
                    panic!(
                        "joint {} {deg}° from {onset}: no positioning alarm in {alarms:?}",
                        joint + 1
                    )
                });
            assert_eq!(first.evidence["joint"], json!(joint + 1), "{first:?}");
            // the size, from the smooth model's sensitivities, within ±30 % of the truth
            let est = first.evidence["offset_deg"].as_f64().unwrap();
            assert!((est / deg - 1.0).abs() <= 0.3, "estimate {est} for {deg}");
            // the estimate comes from the sweeps that show the slip, and says how many; the
            // CUSUM run's own mean stays in the evidence
            let used = first.evidence["estimate_sweeps"].as_u64().unwrap();
            assert!(
                used >= 1 && used <= first.evidence["sweeps"].as_u64().unwrap(),
                "{first:?}"
            );
            assert!(first.evidence["run_mean_deg"].as_f64().unwrap() * deg > 0.0);
            let at = first.idx.unwrap() as usize;
            assert!(at >= onset && at < onset + 4 * 81, "{at}");
            // what to do names the joint; the captures since the run began are retaken
            // (from the sweep before the one that began the CUSUM run: the onset is in it)
            let Some(Affects::Since {
                from_idx,
                handling: Handling::Retake,
            }) = first.affects
            else {
                panic!("{first:?}");
            };
            assert!(from_idx as usize <= onset, "{from_idx} {onset}");
            assert!(from_idx as usize + 2 * 81 > onset, "{from_idx} {onset}");
            assert!(first
                .action
                .as_deref()
                .is_some_and(|s| s.contains(&format!("joint {}", joint + 1))));
            // a tilt is no lamp step: a level change that follows the slip in its layer is the
            // slip's, an info that sends nothing to the drift model, and a gain step raised
            // after the slip began but before the joint was named is withdrawn when it is
            let withdrawn: Vec<u64> = alarms
                .iter()
                .filter(|a| a.code == AlarmCode::GainStepWithdrawn)
                .filter_map(|a| a.evidence["step_idx"].as_u64())
                .collect();
            for a in alarms.iter().filter(|a| a.code == AlarmCode::GainStep) {
                let idx = a.idx.unwrap();
                assert!(idx < first.idx.unwrap(), "{alarms:?}");
                assert_eq!(idx >= from_idx, withdrawn.contains(&idx), "{alarms:?}");
            }
            if joint == 0 && onset == ONSET {
                // this session's tilt moves the level before the interpolant's pattern names the
                // joint: the level crossing is attributed to the joint, and no gain step is raised
                assert!(
                    first.evidence["attributed_level_pct"].as_f64().unwrap() * deg < 0.0,
                    "{first:?}"
                );
                assert!(
                    !alarms
                        .iter()
                        .any(|a| a.code.as_str().starts_with("gain-step")),
                    "{alarms:?}"
                );
            }
            for a in alarms
                .iter()
                .filter(|a| a.code == AlarmCode::LevelAfterSlip)
            {
                assert_eq!(a.severity, Severity::Info);
                assert!(a.idx > first.idx, "{a:?}");
                assert!(matches!(
                    a.affects,
                    Some(Affects::Since {
                        handling: Handling::Retake,
                        ..
                    })
                ));
            }
        }
    }

    /// The slopes a slip's size is fitted with: on the noisy session, the smooth model's
    /// follow the BRDF's (correlation and regression slope near 1, the wagon's too), where the
    /// interpolant's, through one noisy node per class, do not.
    #[test]
    fn the_smooth_models_sensitivities_follow_the_brdf_where_the_interpolants_do_not() {
        let rig = Rig::new(Default::default()).unwrap();
        let truth = |cmd: &[f64; 4], axis: usize| {
            let f = |d: f64| {
                let mut p = Pose {
                    joints_deg: [cmd[0], cmd[1], cmd[2]],
                    wagon_deg: cmd[3],
                };
                if axis < 2 {
                    p.joints_deg[axis] += d;
                } else {
                    p.wagon_deg += d;
                }
                let inc = rig.forward(&p).unwrap();
                (brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z).ln()
            };
            f(0.5) - f(-0.5)
        };
        // (correlation, regression slope of the truth on the model) per axis
        let score = |m: &SweepMonitor, model: Model, axis: usize| {
            let (mut num, mut den_m, mut den_t) = (0.0, 0.0, 0.0);
            for c in m.captures.iter().filter(|c| (41..=48).contains(&c.light)) {
                let Some(s) = m.sensitivities(&c.cmd, model) else {
                    continue;
                };
                if !s[axis].is_finite() {
                    continue;
                }
                let t = truth(&c.cmd, axis);
                num += s[axis] * t;
                den_m += s[axis] * s[axis];
                den_t += t * t;
            }
            (num / (den_m * den_t).sqrt(), num / den_m)
        };
        for seed in [1, 2] {
            let (m, _, _) = simulate(Fault::None, usize::MAX, 48, seed, true, (0.0, 0.0));
            for (model, axes) in [(Model::Smooth, 3), (Model::Interpolant, 2)] {
                for axis in 0..axes {
                    let (corr, slope) = score(&m, model, axis);
                    eprintln!("seed {seed} {model:?} axis {axis}: correlation {corr:.2}, slope {slope:.2}");
                }
            }
            for axis in 0..3 {
                let (corr, slope) = score(&m, Model::Smooth, axis);
                assert!(corr > 0.95, "seed {seed} axis {axis}: {corr}");
                assert!(
                    (0.9..1.1).contains(&slope),
                    "seed {seed} axis {axis}: {slope}"
                );
            }
            for axis in 0..2 {
                let (corr, slope) = score(&m, Model::Interpolant, axis);
                assert!(
                    corr < 0.6 && slope < 0.3,
                    "seed {seed} axis {axis}: {corr} {slope}"
                );
            }
        }
    }

    #[test]
    fn a_square_samples_footprint_at_grazing_light_is_the_layers_pattern_not_a_step() {
        // the last layer (θi = 75°, lights 57–80) swings by ±2.5 % with the light's azimuth
        let (records, alarms) = run_outlined(Fault::None, usize::MAX, 80, 1, true, (0.0013, 0.4));
        assert!(
            alarms.iter().all(|a| a.code != AlarmCode::GainStep),
            "{alarms:?}"
        );
        let late: Vec<&SweepRecord> = records.iter().filter(|r| r.light >= 70).collect();
        assert!(
            late.iter().any(|r| r.level_expected_pct.abs() > 1.0),
            "{late:?}"
        );
        // what is left is the per-light footprint noise of the session (0.5 % SD)
        let left: Vec<f64> = late
            .iter()
            .map(|r| r.level_pct - r.level_expected_pct)
            .collect();
        let rms = (left.iter().map(|v| v * v).sum::<f64>() / left.len() as f64).sqrt();
        assert!(rms < 0.8, "{left:?}");
        // a −3 % step inside that layer, after its pattern is learnt, is still a step
        let onset = 70 * 81 + 40;
        let (_, alarms) = run_outlined(Fault::Step(0.97), onset, 76, 1, true, (0.0013, 0.4));
        let step = alarms
            .iter()
            .find(|a| a.code == AlarmCode::GainStep)
            .unwrap_or_else(|| panic!("no gain step in {alarms:?}"));
        assert!(step.idx.unwrap() <= (74 * 81) as u64, "{step:?}");
    }

    #[test]
    fn a_layer_takes_the_2nd_harmonics_phase_from_the_layer_below_until_it_can_fit_its_own() {
        // an oblong outline: the 2nd harmonic as large as the 4th, with the same phase in
        // every layer, clear in the θi = 60° layer (±0.9 % each) and swinging the level by
        // ±8 % at θi = 75°
        for seed in [1, 2, 3] {
            let (records, alarms) =
                run_outlined(Fault::None, usize::MAX, 68, seed, true, (0.003, 1.0));
            // (the θi = 60° layer's own first lights, whose layer below lends nothing at this
            // outline, are not this test's subject)
            assert!(
                alarms
                    .iter()
                    .all(|a| a.code != AlarmCode::GainStep || a.idx < Some(57 * 81)),
                "seed {seed}: {alarms:?}"
            );
            // from the layer's 7th light to its 10th (its own 2nd harmonic), the prediction
            // follows the 2nd harmonic it cannot fit yet (the 4th alone is off by 5–8 % there)
            let early: Vec<f64> = records
                .iter()
                .filter(|r| (64..=66).contains(&r.light))
                .map(|r| r.level_pct - r.level_expected_pct)
                .collect();
            assert_eq!(early.len(), 3);
            assert!(
                early.iter().all(|e| e.abs() < 3.0),
                "seed {seed}: {early:?}"
            );
        }
        // the 2nd harmonic borrowed on the way does not blunt the layer's step test: a −3 %
        // step once the layer fits its own is caught (one inside the borrowing lights, on a
        // ±8 % swing, is not: the borrowed term's amplitude takes it up)
        let onset = 70 * 81 + 40;
        let (_, alarms) = run_outlined(Fault::Step(0.97), onset, 76, 1, true, (0.003, 1.0));
        assert!(
            alarms.iter().any(|a| a.code == AlarmCode::GainStep
                && a.idx
                    .is_some_and(|i| i as usize >= onset && (i as usize) < onset + 5 * 81)
                && a.evidence["level_pct"].as_f64().is_some_and(|v| v < 0.0)),
            "{alarms:?}"
        );
    }

    /// A step in the second sweep of the θi = 45° layer (lights 19–36): too few of the layer's
    /// own sweeps come before it for a scale of their own, so the layer is judged by the scale
    /// of the layer below, and the step's sweeps do not set the scale they are judged by. (±5 %:
    /// this session's 1 % capture noise gives levels several times the simulator's scatter;
    /// judged by the layer's own first sweeps, the same steps raise nothing.)
    #[test]
    fn a_step_at_the_start_of_a_layer_is_judged_by_the_layer_below_and_caught() {
        let onset = 20 * 81 + 80;
        for (gain, sign) in [(0.95, -1.0), (1.05, 1.0)] {
            let (records, alarms) = run(Fault::Step(gain), onset, 26, 1, true);
            let step = alarms
                .iter()
                .find(|a| a.code == AlarmCode::GainStep)
                .unwrap_or_else(|| panic!("{gain}: no gain step in {alarms:?}"));
            let at = step.idx.unwrap_or(u64::MAX);
            assert!(at <= (onset + 300) as u64, "{gain}: at {at}");
            let pct = step.evidence["level_pct"].as_f64().unwrap();
            assert!(sign * pct > 1.0, "{gain}: {pct}");
            // the layer's first sweeps with a level are tested, by the lent scale
            assert!(records.iter().any(|r| r.light == 20 && r.level_z.is_some()));
        }
    }

    #[test]
    fn a_lamp_step_from_mid_run_is_a_gain_step() {
        let (_, alarms) = run(Fault::Step(0.97), ONSET, LAST, 1, true);
        let step = alarms
            .iter()
            .find(|a| a.code == AlarmCode::GainStep)
            .unwrap_or_else(|| panic!("no gain step in {alarms:?}"));
        // the level against the layer's pattern: the pattern, refitted on the sweeps after the
        // step, takes up part of it (the drift model fits the size from the pairs)
        let pct = step.evidence["level_pct"].as_f64().unwrap();
        assert!((-4.0..-1.0).contains(&pct), "{pct}");
        assert_eq!(step.evidence["source"], json!("light sweeps"));
        assert!(
            alarms
                .iter()
                .all(|a| a.code != AlarmCode::JointOffsetSuspected),
            "{alarms:?}"
        );
        // with probes the level test is left out: the same run raises no gain step
        let (records, alarms) = run(Fault::Step(0.97), ONSET, LAST, 1, false);
        assert!(
            alarms.iter().all(|a| a.code != AlarmCode::GainStep),
            "{alarms:?}"
        );
        assert!(records.iter().all(|r| r.level_z.is_none()));
    }
}
