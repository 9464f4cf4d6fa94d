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
//! threshold comes from the average run length for the false-alarm budget. A finding also needs
//! the estimate beyond a tolerance (an offset in degrees, a level in %) and is raised once per
//! θi layer, kind and sign; `crate::checks` words it as an alarm.

use super::drift::{GainPath, MountPattern};
use crate::measure::geometry::Vec3;
use crate::measure::kinematics::{Pose, Rig};
use crate::measure::resample::{LayeredResampler, ResampleSpec, Sample};
use crate::measure::smooth_brdf::{Node, SmoothBrdf};
use crate::measure::stats::{cusum_threshold, median_sorted, robust_scale_about_zero, Cusum};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};
use std::f64::consts::TAU;

mod approach;
mod axis;
mod findings;
mod joints;
mod level;
mod model;
#[cfg(test)]
mod model_tests;
mod recapture;
#[cfg(test)]
mod session_tests;
#[cfg(test)]
mod tests;
mod wagon;
mod wagon_watch;

pub(crate) use findings::{
    ApproachReading, AxisReading, JointSlip, LayerChange, LevelRun, PatternBelow, Recapture,
    RecaptureReading, SweepAt, SweepFinding, WagonBacklash, WagonOffset,
};
pub(crate) use joints::LAYER_CHANGE_Z;
use level::ScaleHistory;
pub(crate) use level::PATTERN_BELOW_Z;
use model::{Model, PatternFit, Reference, Row};
pub(crate) use recapture::{RecaptureNoise, RECAPTURE_WAIT_CAPTURES};
pub(crate) use wagon_watch::{wagon_watch_questions, PoseCheck, WagonWatchSummary};

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
    /// Without probes: `lamp-unstable` when the captures scatter about the isotropy model by
    /// more than this (%, the residual SD of each of `SCATTER_SWEEPS` consecutive judged
    /// sweeps): a lamp whose gain moves from capture to capture (flicker).
    pub unstable_scatter_pct: f64,
    /// On a rig that takes probes: re-capture two poses chosen for the wagon's sensitivity
    /// every this many light sweeps (`wagon_watch`, about 2 captures each; a departure's pose
    /// re-captured from both sides, `approach`, 4 more); 0 leaves it out.
    pub wagon_watch_sweeps: usize,
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
            unstable_scatter_pct: 2.0,
            wagon_watch_sweeps: 3,
        }
    }
}

/// The scatter watch asks this many consecutive judged sweeps to scatter beyond the limit (and
/// all of them to be back under it to clear): one odd sweep cannot raise it, and a lamp
/// flickering from the start is raised at the second sweep judged (on the UBO plan the 30°
/// layer's fifth light, capture 971): the 15° layer's sweeps have no residual SD (too few
/// lights for the joints' pattern fit).
const SCATTER_SWEEPS: usize = 2;
/// A sweep is judged once its layer has this many earlier lights: before, its class effects
/// rest on one or two members and the layer's joint model is new, and a steady lamp's first
/// sweeps of a layer scatter by 2–4 % (the 60° layer on the realistic preset).
const SCATTER_MIN_EARLIER_LIGHTS: usize = 3;
/// The highest θi layer (millidegrees) the scatter watch judges.
const SCATTER_MAX_LAYER_MDEG: i64 = 60_000;
/// `lamp-unstable` is cleared when the scatter is back under the limit divided by this.
const SCATTER_CLEAR: f64 = 1.5;

/// One capture as the sweep checks keep it.
#[derive(Debug, Clone)]
pub(crate) struct SweepCapture {
    pub idx: u64,
    pub t: f64,
    /// Its plan entry (what a re-capture asks for).
    pub entry: usize,
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
    /// `detect::drift::mount_coordinates` of the nominal directions.
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

/// The wagon in one sweep's smooth-model fit (degrees): its offset and its backlash (a lag
/// against the last direction of motion), each with its standard error, and the correlation
/// of the offset's estimate with joint 1's (the wagon moves the camera along the great circle
/// through both directions, joint 1 moves both along it: near −1 they cannot be told apart).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WagonFit {
    pub offset_deg: f64,
    pub offset_se_deg: f64,
    pub backlash_deg: f64,
    pub backlash_se_deg: f64,
    pub corr_joint1: f64,
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
    /// The wagon's offset and backlash as the smooth model's fit of this sweep sees them, with
    /// the joints fitted beside them: what the sweeps can tell of the wagon (its standard
    /// errors are the identifiability the design allows). Not tested; none without a fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wagon: Option<WagonFit>,
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

impl Sweep {
    fn at(&self) -> SweepAt {
        SweepAt {
            light: self.light,
            last_idx: self.last_idx,
            last_t: self.last_t,
            layer_mdeg: self.layer,
        }
    }
}

/// What the drift model already explains and the sweeps take out of ln Y first.
struct Known<'a> {
    mount: Option<&'a MountPattern>,
    gain: Option<&'a GainPath>,
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

/// An alarm already raised, which is not raised again: a gain step per sign and θi layer, a
/// positioning alarm per θi layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Latch {
    Level {
        sign: i8,
        layer: i64,
    },
    Joint {
        layer: i64,
    },
    /// A level crossing the layer below's pattern accounts for (`step-unresolved`, once per
    /// sign and layer).
    LevelUnresolved {
        sign: i8,
        layer: i64,
    },
    /// The wagon's lag, once per run (a property of its drive, not of a layer).
    Wagon,
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
    /// The same sweeps' raw levels (no pattern model taken out), per θi layer: the prior scale
    /// of a layer that has no pattern model yet.
    raw_level_history: HashMap<i64, ScaleHistory>,
    joint_history: [ScaleHistory; 2],
    level_cusum: Cusum,
    joint_cusum: [Cusum; 2],
    /// The wagon's lag per sweep (`wagon`): its in-control history per θi layer and its
    /// one-sided CUSUM.
    wagon_history: HashMap<i64, ScaleHistory>,
    wagon_cusum: Cusum,
    latched: HashSet<Latch>,
    /// The wagon's lag once named: re-captures asked after it are read without it.
    named_lag: Option<recapture::NamedLag>,
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
    /// The residual SDs of the sweeps the scatter watch judges (θi ≤ 60°), with each sweep's
    /// first capture; and whether `lamp-unstable` stands.
    scatter: Vec<(f64, u64)>,
    unstable: bool,
    /// Whether the probes' `lamp-unstable` stands (a probe-taking rig).
    probes_unstable: bool,
    /// Slips are re-captured before they are named (`recapture`), with this noise; None names
    /// them from the sweeps alone.
    recapture: Option<recapture::RecaptureNoise>,
    /// Plan entries not offered for re-capture (the probes' own).
    reserved: Vec<usize>,
    /// A slip waiting for its re-captures.
    pending: Option<recapture::PendingSlip>,
    /// Per θi layer, the patterns the re-captures refuted.
    refuted: HashMap<i64, usize>,
    /// The θi layers that reported a pattern the re-captures could not check (once a layer).
    unverifiable: HashSet<i64>,
    /// The θi layers that reported a pattern their own earlier sweeps do not show begin
    /// (a rig without re-captures; once a layer).
    unresolved: HashSet<i64>,
    /// The wagon's offset from re-captures of two poses (a probe-taking rig).
    wagon_watch: wagon_watch::WagonWatch,
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
    /// The joints' offsets of detection's fit (the interpolant's sensitivities), and their
    /// standard errors.
    offsets: [f64; 2],
    offset_se: [f64; 2],
    /// The joints' offsets and standard errors of the smooth model's fit, and the sweep's mean
    /// smooth sensitivity to each joint (ln Y per degree): what a level change is attributed
    /// by (`SweepMonitor::attribute_level`). NaN where there is no fit.
    smooth: [(f64, f64); 2],
    smooth_s: [f64; 2],
    /// The wagon's offset and its standard error in the same fit with the wagon's columns
    /// (`WagonFit`): what a re-captured pair's change is attributed by (`wagon_watch`).
    wagon_offset: (f64, f64),
    /// The standard error of the sweep's level (ln units; NaN until it is measured).
    level_se: f64,
    /// The columns of the layer pattern its level was taken about (None: the raw level).
    pattern: Option<model::PatternColumns>,
}

/// What testing one completed sweep gave.
#[derive(Debug, Clone, Default)]
pub(crate) struct SweepOutcome {
    /// The sweep's record (none when it had too few comparable captures).
    pub record: Option<SweepRecord>,
    /// What the sweep showed, in the order it was found.
    pub findings: Vec<SweepFinding>,
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
    /// The wagon's re-captured pair (a probe-taking rig with the watch on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wagon_watch: Option<WagonWatchSummary>,
}

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
            raw_level_history: HashMap::new(),
            joint_history: Default::default(),
            level_cusum: Cusum::default(),
            joint_cusum: [Cusum::default(), Cusum::default()],
            wagon_history: HashMap::new(),
            wagon_cusum: Cusum::default(),
            latched: HashSet::new(),
            named_lag: None,
            scatter: Vec::new(),
            unstable: false,
            probes_unstable: false,
            last: None,
            tested: 0,
            sweep_starts: Vec::new(),
            light_phi: vec![f64::NAN; lights],
            level_model: HashMap::new(),
            slip: None,
            level_steps: Vec::new(),
            recapture: None,
            reserved: Vec::new(),
            pending: None,
            refuted: HashMap::new(),
            unverifiable: HashSet::new(),
            unresolved: HashSet::new(),
            wagon_watch: Default::default(),
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

    /// The F + L + C reference of the completed sweeps' captures taken before capture `cut`:
    /// what a slip's or a lag's sweeps are refitted against, so that none of their own
    /// captures is in it.
    fn reference_before(&self, cut: u64, known: &Known) -> Reference {
        let past: Vec<usize> = (0..self.captures.len())
            .filter(|&i| {
                let c = &self.captures[i];
                c.idx < cut && self.completed.get(c.light).copied().unwrap_or(false)
            })
            .collect();
        self.backfit(&past, known)
    }

    /// The captures (indices into the list) of light direction `light`.
    fn captures_of_light(&self, light: usize) -> Vec<usize> {
        (0..self.captures.len())
            .filter(|&i| self.captures[i].light == light)
            .collect()
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
            wagon_watch: self.wagon_watch_summary(),
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
            offset_se: [f64::NAN; 2],
            smooth: [(f64::NAN, f64::NAN); 2],
            smooth_s: [f64::NAN; 2],
            wagon_offset: (f64::NAN, f64::NAN),
            level_se: f64::NAN,
            pattern: None,
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
        if let Some(span) = self.sweep_starts.last_mut() {
            span.level_se = level_se;
        }
        let pattern = self.pattern_fit(rows.iter().map(Row::joints).collect());
        let wagon = self.smooth_offsets(&sweep, &reference, &known);
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
            wagon,
            model_layers: 0,
            model_builds: self.model_builds,
        };
        let pattern_fit = self.expected_level(&sweep, &reference);
        let expected = pattern_fit.as_ref().map_or(0.0, |p| p.level);
        rec.level_expected_pct = 100.0 * expected;
        if let Some(span) = self.sweep_starts.last_mut() {
            span.pattern = pattern_fit.as_ref().map(|p| p.columns);
        }
        // a layer whose pattern model grew restarts its scale history from the earlier lights'
        // residuals about the new model: the levels judged without the harmonics carry the
        // pattern's swing
        let harmonics = pattern_fit.as_ref().map_or(0, |p| p.columns.count() - 1);
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
        let mut findings = Vec::new();
        let level_step = if level_test {
            let floor = pattern_fit.as_ref().map(|p| p.sd);
            self.test_level(
                &sweep,
                (level - expected, level, level_se, floor),
                &reference,
                &known,
                &mut rec,
                &mut findings,
            )
        } else {
            LevelStep::default()
        };
        // the wagon before the joints: its lag also leaves a pattern the joints' fit (which has
        // no lag column) partly takes up, so in a sweep where both cross the wagon is named and
        // the joints' CUSUMs start again
        // while the probes see the lamp flicker every capture has a gain of its own, which
        // makes patterns across a sweep's cameras of its own: the pose is not judged from them
        // (the fits are recorded)
        let named = if self.lamp_unstable() {
            self.record_joint_fits(&pattern, &mut rec);
            None
        } else {
            let hold = level_step.alarmed || level_step.slip.is_some();
            let wagon_named = self.test_wagon(&sweep, wagon, hold, &known, &mut findings);
            let named = self.test_joints(
                &sweep,
                &pattern,
                level_step.alarmed || wagon_named,
                &known,
                &mut rec,
                &mut findings,
            );
            if wagon_named {
                // what the joints' CUSUMs had gathered was the lag's pattern
                for c in self.joint_cusum.iter_mut() {
                    c.reset();
                }
            }
            named
        };
        if level_test {
            self.test_scatter(&sweep, &rec, &mut findings);
        }
        let watched = self.wagon_watch_sweep(&sweep, &known, &mut findings);
        let named = named.or(watched);
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
            findings,
            step_at_s: level_step.at_s,
            slip_at_s,
            withdrawn_steps_s,
        }
    }

    /// Whether the probes' `lamp-unstable` stands: the sweeps' joint and lag tests are then
    /// suspended. The sweeps' own scatter test does not suspend them: a slip's pattern, not in
    /// the model until it is named, raises their residual scatter too.
    fn lamp_unstable(&self) -> bool {
        self.probes_unstable
    }

    /// The probes' `lamp-unstable` was raised (`true`) or cleared: the sweeps' joint and lag
    /// tests are suspended while it stands, and start again from nothing when it is raised
    /// (the flicker began before it was measured).
    pub(crate) fn set_probes_unstable(&mut self, unstable: bool) {
        if unstable && !self.probes_unstable {
            self.restart_pose_tests();
        }
        self.probes_unstable = unstable;
    }

    /// The joints' and the wagon lag's CUSUMs start again.
    fn restart_pose_tests(&mut self) {
        for c in self.joint_cusum.iter_mut() {
            c.reset();
        }
        self.wagon_cusum.reset();
    }

    /// The lamp's capture-to-capture stability without probes. A flickering lamp gives every
    /// capture a gain of its own, which no stationary model of the geometry follows, so the
    /// sweep's residuals about the isotropy model (F + L + C and the joints' patterns) scatter
    /// by about the flicker's SD; a steady lamp leaves the model's misfit and the camera noise.
    /// Judged on the residual SDs of the last `SCATTER_SWEEPS` sweeps, each beyond the limit (one
    /// odd sweep cannot raise it), in the layers up to `SCATTER_MAX_LAYER_MDEG` (at grazing
    /// light a square sample's footprint leaves several per cent of misfit of its own), each
    /// sweep once its layer has `SCATTER_MIN_EARLIER_LIGHTS` earlier lights. Raised when each
    /// is above `unstable_scatter_pct`, cleared when each is below `1 / SCATTER_CLEAR` of it.
    fn test_scatter(&mut self, sweep: &Sweep, rec: &SweepRecord, findings: &mut Vec<SweepFinding>) {
        let sd = rec.residual_sd;
        let earlier_lights = self
            .sweep_starts
            .iter()
            .filter(|s| s.layer == sweep.layer)
            .count()
            .saturating_sub(1);
        if sweep.layer > SCATTER_MAX_LAYER_MDEG
            || earlier_lights < SCATTER_MIN_EARLIER_LIGHTS
            || !(sd > 0.0 && sd.is_finite())
        {
            return;
        }
        self.scatter.push((sd, sweep.first_idx));
        if self.scatter.len() < SCATTER_SWEEPS {
            return;
        }
        let recent = &self.scatter[self.scatter.len() - SCATTER_SWEEPS..];
        let (lo, hi) = recent.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(100.0 * r.0), hi.max(100.0 * r.0))
        });
        let limit = self.spec.unstable_scatter_pct;
        let from_idx = recent[0].1;
        if !self.unstable && lo > limit {
            self.unstable = true;
            findings.push(SweepFinding::LampUnstable {
                at: sweep.at(),
                scatter_pct: lo,
                limit_pct: limit,
                sweeps: SCATTER_SWEEPS,
                from_idx,
            });
        } else if self.unstable && hi < limit / SCATTER_CLEAR {
            self.unstable = false;
            findings.push(SweepFinding::LampSteady {
                at: sweep.at(),
                scatter_pct: hi,
                limit_pct: limit,
                sweeps: SCATTER_SWEEPS,
            });
        }
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
}
