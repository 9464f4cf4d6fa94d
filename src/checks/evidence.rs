//! What an alarm saw, typed: one variant per kind of evidence, each with its numbers. Written
//! to the result files as the JSON object of its fields with the keys in alphabetical order
//! (`null` for none), so the files read as they always have; read back by the alarm's code.
//! Evidence whose shape this version does not know (a file from another version) is kept as
//! it was read (`Evidence::Unknown`), never dropped.

use super::alarm::{Alarm, AlarmCode};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Where a drift or lamp figure came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Source {
    /// Repeated geometry and interpolated pairs of an isotropic sample.
    #[serde(rename = "isotropy classes")]
    IsotropyClasses,
    /// Drift probes (re-captures of one pose).
    #[serde(rename = "probes")]
    Probes,
    /// Whole light sweeps against the earlier ones.
    #[serde(rename = "light sweeps")]
    LightSweeps,
    /// Joint 3's sentinel probes against the lamp probes.
    #[serde(rename = "sentinel probes")]
    SentinelProbes,
    /// Two earlier poses re-captured back to back.
    #[serde(rename = "re-captures")]
    Recaptures,
}

impl Source {
    /// The name in messages and result files.
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            Source::IsotropyClasses => "isotropy classes",
            Source::Probes => "probes",
            Source::LightSweeps => "light sweeps",
            Source::SentinelProbes => "sentinel probes",
            Source::Recaptures => "re-captures",
        }
    }
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What an alarm saw.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Evidence {
    /// Nothing beyond the message.
    None,
    /// Alarms of one code held back in a storm, reported as one.
    Aggregated(Box<Aggregated>),
    /// `crc-errors`.
    CrcErrors(CrcErrors),
    /// `announcement-refused`.
    AnnouncementRefused(AnnouncementRefused),
    /// `capture-never-announced`.
    NeverAnnounced(NeverAnnounced),
    /// `duplicate-index`.
    DuplicateIndex(DuplicateIndex),
    /// `time-stepped-back`.
    TimeStep(TimeStep),
    /// `skipped-files`.
    SkippedFiles(SkippedFiles),
    /// `duplicate-files`.
    DuplicateFiles(DuplicateFiles),
    /// `unannounced-files`.
    UnannouncedFiles(UnannouncedFiles),
    /// `capture-failed` and `missing-capture`.
    CaptureFailure(CaptureFailure),
    /// `non-finite-pixels`.
    NonFinite(NonFinite),
    /// `clipped-pixels`.
    Clipped(Clipped),
    /// `dark-capture`.
    Dark(Dark),
    /// `pose-off-plan` as it opens.
    PoseError(PoseError),
    /// `encoder-mismatch` as it opens.
    EncoderReading(EncoderReading),
    /// A pose-off-plan or encoder-mismatch episode: still open (the status after a restart), or
    /// `…-cleared`.
    Episode(Episode),
    /// `joint-offset-suspected` for arm joint 1 or 2, from the light sweeps.
    JointSlip(JointSlip),
    /// `joint-offset-suspected` for arm joint 3, from the sentinel probes.
    Joint3Slip(Joint3Slip),
    /// `level-after-slip`.
    LevelAfterSlip(LevelAfterSlip),
    /// `gain-step-withdrawn`.
    StepWithdrawn(StepWithdrawn),
    /// `gain-step` from the light sweeps.
    SweepStep(SweepStep),
    /// `gain-step` from the pairs or the probes.
    TrendStep(TrendStep),
    /// `probe-moved-with-pose`.
    ProbePoseMoved(ProbePoseMoved),
    /// `gain-drift`.
    GainRate(GainRate),
    /// `trend-unresolved`.
    UnresolvedTrend(UnresolvedTrend),
    /// `slip-refuted`.
    SlipRefuted(SlipRefuted),
    /// `slip-unverifiable`.
    SlipUnverifiable(SlipUnverifiable),
    /// `slip-unresolved`.
    SlipUnresolved(SlipUnresolved),
    /// `step-unresolved`.
    StepUnresolved(StepUnresolved),
    /// `wagon-backlash-suspected`.
    WagonBacklash(WagonBacklash),
    /// `wagon-offset-suspected`.
    WagonOffset(WagonOffset),
    /// `lamp-unstable` and `lamp-unstable-cleared` from the probes.
    LampScatter(LampScatter),
    /// `lamp-unstable` and `lamp-unstable-cleared` from the light sweeps.
    SweepScatter(SweepScatter),
    /// `colour-drift`.
    ColourRate(ColourRate),
    /// `sample-off-centre`.
    MountPattern(MountPattern),
    /// `reciprocity-outlier`.
    PairOutlier(PairOutlier),
    /// `probes-refused`.
    ProbesRefused(ProbesRefused),
    /// Read from a file, in a shape this version does not know for the alarm's code.
    Unknown(serde_json::Value),
}

/// A storm's held-back alarms: how many, the window of inputs, their captures and the latest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Aggregated {
    pub aggregated: u64,
    pub window_inputs: [u64; 2],
    pub captures: Vec<u64>,
    pub latest: Alarm,
}

/// Corrupt lines among the last `window` lines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CrcErrors {
    pub bad_lines: u64,
    pub window: u64,
}

/// The capture index whose announcement was given up on, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnnouncementRefused {
    pub idx: u64,
    pub reason: String,
}

/// Capture indices the controller's log does not hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NeverAnnounced {
    pub count: u64,
    pub first: u64,
    pub last: u64,
}

/// The file of the first announcement of an index, and of the other one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DuplicateIndex {
    pub kept: String,
    pub ignored: String,
}

/// A step back of the capture times: its size, the times either side of it and the shift
/// applied from that capture on (seconds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeStep {
    pub step_s: f64,
    pub announced_t: f64,
    pub previous_t: f64,
    pub shift_s: f64,
}

/// One file not placed as a capture, with the kind of its reason and the reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedFile {
    pub file: String,
    pub kind: String,
    pub why: String,
}

/// Files not placed as captures: counted by kind, and listed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedFiles {
    pub counts: BTreeMap<String, u64>,
    pub files: Vec<SkippedFile>,
}

/// Files placed on one plan entry: the one checked and the others.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DuplicateGroup {
    pub entry: usize,
    pub kept: String,
    pub others: Vec<String>,
    /// Watch mode only: the file the rule keeps, when it arrived after `kept` was checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rule_prefers: Option<String>,
}

/// Every plan entry with more than one file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DuplicateFiles {
    pub groups: Vec<DuplicateGroup>,
}

/// Files no announcement named.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnannouncedFiles {
    pub files: Vec<String>,
}

/// A capture's file that failed or never came, and the failures in a row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureFailure {
    pub file: String,
    pub consecutive_failures: u32,
}

/// NaN or infinite pixels of the region.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NonFinite {
    pub nonfinite: u64,
    pub pixels: u64,
}

/// Pixels at the sensor's maximum, and that maximum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Clipped {
    pub clipped: u64,
    pub pixels: u64,
    pub max_value: f64,
}

/// A capture's mean luminance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dark {
    pub y: f64,
}

/// How far the judged pose is from the plan's (degrees), with the encoder and commanded
/// poses (joints 1–3, wagon).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseError {
    pub pose_error_deg: f64,
    pub enc: [f64; 4],
    pub cmd: [f64; 4],
}

/// The axis whose encoder disagrees, with the encoder and commanded poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EncoderReading {
    pub axis: String,
    pub enc: [f64; 4],
    pub cmd: [f64; 4],
}

/// A positioning episode: its axis, its captures, the worst error (degrees) and how many were
/// placed by the commanded pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    pub axis: String,
    pub captures: u64,
    pub first_idx: u64,
    pub last_idx: u64,
    pub worst_deg: f64,
    pub by_command: u64,
}

/// One joint's fit in the sweep that named another.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OtherJoint {
    pub joint: usize,
    pub offset_deg: f64,
    pub se_deg: f64,
    pub cusum: f64,
}

/// Arm joint 1 or 2 named by the light sweeps: the offset with its standard error and the
/// sweeps behind it, the CUSUM run's own mean and length and where its first sweep ended, the
/// statistic and its threshold, the other joint's fit, and the level change it explains.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointSlip {
    pub joint: usize,
    pub offset_deg: f64,
    pub se_deg: f64,
    pub estimate_sweeps: usize,
    pub run_mean_deg: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    pub other_joints: Vec<OtherJoint>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attributed_level_pct: Option<f64>,
    /// What re-capturing two earlier poses said (a probe-taking rig; none when not asked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recapture: Option<SlipRecapture>,
    /// Joint 1 told from the wagon by re-captures, when the wagon watch's pair departed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<AxisReading>,
}

/// Earlier poses of one sweep re-captured back to back to check a slip the light sweeps
/// named: confirmed or refuted with the reading, or asked for and not taken.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum SlipRecapture {
    Confirmed(RecaptureReading),
    Refuted(RecaptureReading),
    Unanswered { entries: Vec<usize> },
}

/// The re-captured plan entries (first half: those whose luminance rises most with the joint;
/// then those whose luminance falls most), the change of the halves' mean luminance ratio
/// against the originals' (%), the difference of their mean sensitivities to the joint (%/°),
/// and the offset that makes (degrees) with its standard error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecaptureReading {
    pub entries: Vec<usize>,
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub offset_deg: f64,
    pub se_deg: f64,
}

/// The wagon's lag: its estimate (degrees) with its standard error. Named by the light sweeps
/// (`source` "light sweeps"): the sweeps behind the estimate, the CUSUM run's mean and length,
/// the wagon's constant offset in the sweep that named it (not tested), the capture that ended
/// the run's first sweep, the statistic and its threshold. Named by a pose re-captured from
/// both sides after the re-captured pair departed (`source` "re-captures", `approach`): the
/// pair's change read as an offset (`run_mean_deg`, `offset_deg`), no sweeps, the first capture
/// of the pair's CUSUM run, its statistic and threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WagonBacklash {
    pub source: Source,
    pub backlash_deg: f64,
    pub se_deg: f64,
    pub estimate_sweeps: usize,
    pub run_mean_deg: f64,
    pub offset_deg: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approach: Option<ApproachReading>,
}

/// One pose re-captured from both sides of the wagon's travel: the plan entries in the order
/// asked (a pose below, the pose, a pose above, the pose), ln Y of the pose approached from
/// below less from above (%), its change per degree of wagon (%/°), and the wagon's lag that
/// makes (degrees; positive: it lags its motion) with its standard error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ApproachReading {
    pub entries: [usize; 4],
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub backlash_deg: f64,
    pub se_deg: f64,
}

/// The wagon's offset named by re-captures of two poses: its estimate and standard error
/// (degrees), the two plan entries and the light sweeps of their originals, the change of their
/// difference (%) and its sensitivity to the wagon (%/°), what a degree of joint 1 and of
/// joint 2 reads as (degrees of wagon), the readings behind the estimate, the first capture it
/// can have affected, the CUSUM and its threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WagonOffset {
    pub source: Source,
    pub offset_deg: f64,
    pub se_deg: f64,
    pub entries: [usize; 2],
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub joint_leak: [f64; 2],
    pub originals_lights: [usize; 2],
    pub readings: usize,
    pub sweeps_z: Option<f64>,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    /// One of the two poses re-captured from both sides, which read no lag.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approach: Option<ApproachReading>,
    /// The re-captures chosen to tell the wagon from joint 1, when they were read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<AxisReading>,
}

/// Poses re-captured to tell the wagon from arm joint 1 after the re-captured pair departed:
/// the plan entries (the first `up` those a joint-1 slip moves up against the wagon), their
/// contrast (%: the first ones' mean ln Y against their originals less the others'), what a
/// joint-1 slip and a wagon offset that move the pair as it moved would make it (%), and its
/// standard error (%).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisReading {
    pub entries: Vec<usize>,
    pub up: usize,
    pub change_pct: f64,
    pub joint1_pct: f64,
    pub wagon_pct: f64,
    pub se_pct: f64,
}

/// A slip the light sweeps' pattern named (`joint`, `offset_deg`), refuted by re-captures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlipRefuted {
    pub source: Source,
    pub joint: usize,
    pub offset_deg: f64,
    pub recapture: SlipRecapture,
}

/// A pattern the light sweeps' fit took for `joint` offset by `offset_deg`, which re-captures
/// of earlier poses could check only from `checkable_deg` on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlipUnverifiable {
    pub source: Source,
    pub joint: usize,
    pub offset_deg: f64,
    pub checkable_deg: f64,
    pub layer_deg: f64,
    pub light: usize,
}

/// A pattern the light sweeps' fit took for `joint` offset by `offset_deg`, on a rig without
/// re-captures, against the earlier sweeps of its θi layer: `sweeps_before` of them tested
/// before its run began, their mean offset and its standard error (null without any), and the
/// run's departure from them in standard errors (null without any), under `threshold_z`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlipUnresolved {
    pub source: Source,
    pub joint: usize,
    pub offset_deg: f64,
    pub layer_deg: f64,
    pub light: usize,
    pub sweeps_before: usize,
    pub before_deg: Option<f64>,
    pub before_se_deg: Option<f64>,
    pub change_z: Option<f64>,
    pub threshold_z: f64,
}

/// A level CUSUM run of the light sweeps (`level_pct` over `sweeps` sweeps, the first ending at
/// capture `since_idx`; its sign the direction) that the θi layer below accounts for, on a rig
/// without probes: at the run's light azimuths that layer (θi = `below_deg`) departed from its
/// own azimuthal pattern by `below_pct` ± `below_se_pct` (standard error), which grown by
/// `growth` (the lamp footprint's tan² law from that θi to `layer_deg`) reaches the run's
/// level, and departs by at least `threshold_z` standard errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepUnresolved {
    pub source: Source,
    pub level_pct: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    pub layer_deg: f64,
    pub light: usize,
    pub below_deg: f64,
    pub below_pct: f64,
    pub below_se_pct: f64,
    pub growth: f64,
    pub threshold_z: f64,
}

/// Arm joint 3 named by its sentinel: the turn, the first capture after the last reading in
/// control, the statistic and its threshold, and the sentinel's pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Joint3Slip {
    pub joint: usize,
    pub offset_deg: f64,
    pub source: Source,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    pub entry: usize,
    pub sensitivity_pct_per_deg: f64,
}

/// A level change after a named slip: the joint, the level, the CUSUM run and the slip's
/// first capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LevelAfterSlip {
    pub source: Source,
    pub joint: usize,
    pub level_pct: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub slip_from_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
}

/// A gain step withdrawn: the joint that explains it, where it was raised, its level and the
/// slip's first capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepWithdrawn {
    pub source: Source,
    pub joint: usize,
    pub step_idx: u64,
    pub level_pct: f64,
    pub slip_from_idx: u64,
}

/// A gain step in the light sweeps' levels: the level, the CUSUM run and where (and when) its
/// first sweep began, the statistic and its threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepStep {
    pub source: Source,
    pub level_pct: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub since_t: Option<f64>,
    pub statistic: f64,
    pub threshold: f64,
}

/// A gain step against the trend of the pairs or the probes: its direction (+1 brighter, −1),
/// the statistic and its threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrendStep {
    pub direction: i8,
    pub statistic: f64,
    pub threshold: f64,
    pub source: Source,
}

/// A lamp probe's departure from its trend that the wagon pair's reading, taken right after it,
/// explains: the probe's departure (direction, statistic, threshold), the pair's reading in
/// standard deviations of its readings in control and as degrees of wagon, and the probe pose's
/// change per degree of wagon (%/°, the smooth model's; absent when it gives none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProbePoseMoved {
    pub direction: i8,
    pub statistic: f64,
    pub threshold: f64,
    pub probe_idx: u64,
    pub pose_z: f64,
    pub wagon_deg: f64,
    pub probe_sensitivity_pct_per_deg: Option<f64>,
}

/// A gain drift rate with its standard error (%/h) and the observations behind it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GainRate {
    pub rate_pct_per_h: f64,
    pub se_pct_per_h: f64,
    pub n: usize,
    pub source: Source,
}

/// A gain trend of the isotropy classes (%/h, its standard error and observations) beside the
/// same trend fitted with a stationary light-side pattern per θi layer, which leaves it within
/// the significance the alarm asks for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnresolvedTrend {
    pub rate_pct_per_h: f64,
    pub se_pct_per_h: f64,
    pub robust_rate_pct_per_h: f64,
    pub robust_se_pct_per_h: f64,
    pub n: usize,
    pub source: Source,
}

/// The light sweeps' scatter about the isotropy model (%, the median residual SD of `sweeps`
/// sweeps) against the limit (`[checks.sweeps] unstable_scatter_pct`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepScatter {
    pub source: Source,
    pub scatter_pct: f64,
    pub limit_pct: f64,
    pub sweeps: usize,
}

/// The probes' robust scatter against the design scatter (%), over this many probes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LampScatter {
    pub scatter_pct: f64,
    pub design_scatter_pct: f64,
    pub probes: usize,
    pub source: Source,
}

/// The lamp's colour-temperature rate (K/h) with its standard error, the ΔE00 it moves a white
/// by per hour, the lamp's colour temperature, the X and Z rates and the observations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColourRate {
    pub k_per_h: f64,
    pub se_k_per_h: f64,
    pub de00_per_h: f64,
    pub lamp_cct_k: f64,
    pub x_rate_pct_per_h: f64,
    pub z_rate_pct_per_h: f64,
    pub n: usize,
    pub source: Source,
}

/// The off-centre mount's pattern: the camera's and the light's amplitude (%), azimuth and
/// standard error, and how much it inflates the drift rate's standard error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MountPattern {
    pub camera_pct: f64,
    pub camera_azimuth_deg: f64,
    pub camera_se_pct: f64,
    pub light_pct: f64,
    pub light_azimuth_deg: f64,
    pub light_se_pct: f64,
    pub rate_inflation: f64,
    pub source: Source,
}

/// A reciprocal pair beyond its limit: ΔE00, the limit, the median and MAD of its geometry's
/// pairs and how many, the two captures and the pair's θ (degrees).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairOutlier {
    pub de2000: f64,
    pub limit: f64,
    pub median: f64,
    pub mad: f64,
    pub pairs: usize,
    pub a: u64,
    pub b: u64,
    pub theta_pair_deg: [f64; 2],
}

/// The controller's reason for refusing a probe, and how many probes it took before.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProbesRefused {
    pub reason: String,
    pub probes_taken: u64,
}

/// Writes evidence as the result files hold it: the object of its fields, keys in alphabetical
/// order (through `serde_json::Value`, whose maps are sorted).
pub(super) fn write_sorted<S: serde::Serializer>(e: &Evidence, s: S) -> Result<S::Ok, S::Error> {
    serde_json::to_value(e)
        .map_err(serde::ser::Error::custom)?
        .serialize(s)
}

fn parse<T: serde::de::DeserializeOwned>(
    v: &serde_json::Value,
    f: fn(T) -> Evidence,
) -> Option<Evidence> {
    serde_json::from_value(v.clone()).ok().map(f)
}

impl Evidence {
    /// Evidence as a result file holds it, for an alarm of `code`.
    pub(crate) fn read(code: AlarmCode, v: serde_json::Value) -> Evidence {
        use AlarmCode as C;
        if v.is_null() {
            return Evidence::None;
        }
        if v.get("aggregated").is_some() {
            return parse(&v, |a: Aggregated| Evidence::Aggregated(Box::new(a)))
                .unwrap_or(Evidence::Unknown(v));
        }
        let typed = match code {
            C::CrcErrors => parse(&v, Evidence::CrcErrors),
            C::AnnouncementRefused => parse(&v, Evidence::AnnouncementRefused),
            C::CaptureNeverAnnounced => parse(&v, Evidence::NeverAnnounced),
            C::DuplicateIndex => parse(&v, Evidence::DuplicateIndex),
            C::TimeSteppedBack => parse(&v, Evidence::TimeStep),
            C::SkippedFiles => parse(&v, Evidence::SkippedFiles),
            C::DuplicateFiles => parse(&v, Evidence::DuplicateFiles),
            C::UnannouncedFiles => parse(&v, Evidence::UnannouncedFiles),
            C::CaptureFailed | C::MissingCapture => parse(&v, Evidence::CaptureFailure),
            C::NonFinitePixels => parse(&v, Evidence::NonFinite),
            C::ClippedPixels => parse(&v, Evidence::Clipped),
            C::DarkCapture => parse(&v, Evidence::Dark),
            C::PoseOffPlan => {
                parse(&v, Evidence::PoseError).or_else(|| parse(&v, Evidence::Episode))
            }
            C::EncoderMismatch => {
                parse(&v, Evidence::EncoderReading).or_else(|| parse(&v, Evidence::Episode))
            }
            C::PoseOffPlanCleared | C::EncoderMismatchCleared => parse(&v, Evidence::Episode),
            C::JointOffsetSuspected => {
                parse(&v, Evidence::JointSlip).or_else(|| parse(&v, Evidence::Joint3Slip))
            }
            C::LevelAfterSlip => parse(&v, Evidence::LevelAfterSlip),
            C::GainStepWithdrawn => parse(&v, Evidence::StepWithdrawn),
            C::GainStep => {
                parse(&v, Evidence::SweepStep).or_else(|| parse(&v, Evidence::TrendStep))
            }
            C::GainDrift => parse(&v, Evidence::GainRate),
            C::TrendUnresolved => parse(&v, Evidence::UnresolvedTrend),
            C::SlipRefuted => parse(&v, Evidence::SlipRefuted),
            C::SlipUnverifiable => parse(&v, Evidence::SlipUnverifiable),
            C::SlipUnresolved => parse(&v, Evidence::SlipUnresolved),
            C::StepUnresolved => parse(&v, Evidence::StepUnresolved),
            C::WagonBacklashSuspected => parse(&v, Evidence::WagonBacklash),
            C::WagonOffsetSuspected | C::CameraPoseMoved => parse(&v, Evidence::WagonOffset),
            C::ProbeMovedWithPose => parse(&v, Evidence::ProbePoseMoved),
            C::LampUnstable | C::LampUnstableCleared => {
                parse(&v, Evidence::LampScatter).or_else(|| parse(&v, Evidence::SweepScatter))
            }
            C::ColourDrift => parse(&v, Evidence::ColourRate),
            C::SampleOffCentre => parse(&v, Evidence::MountPattern),
            C::ReciprocityOutlier => parse(&v, Evidence::PairOutlier),
            C::ProbesRefused => parse(&v, Evidence::ProbesRefused),
            C::BadAnnouncement
            | C::BadEntry
            | C::BadLine
            | C::BadPose
            | C::CapturesPending
            | C::ColourDriftCleared
            | C::ControllerFault
            | C::ControllerReboot
            | C::DaemonRestart
            | C::EntryRepeated
            | C::GainDriftCleared
            | C::Joint3SentinelUnavailable
            | C::PortBack
            | C::PortLost
            | C::ProbePoseUnavailable
            | C::SessionChanged
            | C::UnsupportedVersion => None,
        };
        typed.unwrap_or(Evidence::Unknown(v))
    }

    /// Whether this evidence is of a kind an alarm of `code` carries (every code may carry
    /// none, an aggregation of its storm, or evidence read in an unknown shape).
    pub(crate) fn fits(&self, code: AlarmCode) -> bool {
        use AlarmCode as C;
        match self {
            Evidence::None | Evidence::Aggregated(_) | Evidence::Unknown(_) => true,
            Evidence::CrcErrors(_) => code == C::CrcErrors,
            Evidence::AnnouncementRefused(_) => code == C::AnnouncementRefused,
            Evidence::NeverAnnounced(_) => code == C::CaptureNeverAnnounced,
            Evidence::DuplicateIndex(_) => code == C::DuplicateIndex,
            Evidence::TimeStep(_) => code == C::TimeSteppedBack,
            Evidence::SkippedFiles(_) => code == C::SkippedFiles,
            Evidence::DuplicateFiles(_) => code == C::DuplicateFiles,
            Evidence::UnannouncedFiles(_) => code == C::UnannouncedFiles,
            Evidence::CaptureFailure(_) => matches!(code, C::CaptureFailed | C::MissingCapture),
            Evidence::NonFinite(_) => code == C::NonFinitePixels,
            Evidence::Clipped(_) => code == C::ClippedPixels,
            Evidence::Dark(_) => code == C::DarkCapture,
            Evidence::PoseError(_) => code == C::PoseOffPlan,
            Evidence::EncoderReading(_) => code == C::EncoderMismatch,
            Evidence::Episode(_) => matches!(
                code,
                C::PoseOffPlan
                    | C::EncoderMismatch
                    | C::PoseOffPlanCleared
                    | C::EncoderMismatchCleared
            ),
            Evidence::JointSlip(_) | Evidence::Joint3Slip(_) => code == C::JointOffsetSuspected,
            Evidence::LevelAfterSlip(_) => code == C::LevelAfterSlip,
            Evidence::StepWithdrawn(_) => code == C::GainStepWithdrawn,
            Evidence::SweepStep(_) | Evidence::TrendStep(_) => code == C::GainStep,
            Evidence::GainRate(_) => code == C::GainDrift,
            Evidence::UnresolvedTrend(_) => code == C::TrendUnresolved,
            Evidence::SlipRefuted(_) => code == C::SlipRefuted,
            Evidence::SlipUnverifiable(_) => code == C::SlipUnverifiable,
            Evidence::SlipUnresolved(_) => code == C::SlipUnresolved,
            Evidence::StepUnresolved(_) => code == C::StepUnresolved,
            Evidence::WagonBacklash(_) => code == C::WagonBacklashSuspected,
            Evidence::WagonOffset(_) => {
                matches!(code, C::WagonOffsetSuspected | C::CameraPoseMoved)
            }
            Evidence::ProbePoseMoved(_) => code == C::ProbeMovedWithPose,
            Evidence::LampScatter(_) | Evidence::SweepScatter(_) => {
                matches!(code, C::LampUnstable | C::LampUnstableCleared)
            }
            Evidence::ColourRate(_) => code == C::ColourDrift,
            Evidence::MountPattern(_) => code == C::SampleOffCentre,
            Evidence::PairOutlier(_) => code == C::ReciprocityOutlier,
            Evidence::ProbesRefused(_) => code == C::ProbesRefused,
        }
    }

    /// The evidence as the result files hold it.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }

    /// A named joint slip: the joint (1–3), its offset (degrees) and the capture that ended the
    /// first sweep (or followed the last reading in control) that showed it.
    pub(crate) fn slip(&self) -> Option<(usize, f64, u64)> {
        match self {
            Evidence::JointSlip(e) => Some((e.joint, e.offset_deg, e.since_idx)),
            Evidence::Joint3Slip(e) => Some((e.joint, e.offset_deg, e.since_idx)),
            _ => None,
        }
    }

    /// The first capture and the last of a closed episode.
    pub(crate) fn episode_range(&self) -> Option<(u64, u64)> {
        match self {
            Evidence::Episode(e) => Some((e.first_idx, e.last_idx)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::alarm::{AlarmKind, Severity};

    /// Every alarm the regression corpus recorded reads back with typed evidence that fits its
    /// code, and is written again byte for byte.
    #[test]
    fn the_corpus_alarms_read_typed_and_write_back_unchanged() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/sessions");
        let mut seen = std::collections::BTreeSet::new();
        let mut n = 0;
        for dir in std::fs::read_dir(root).unwrap() {
            let path = dir.unwrap().path().join("expected/alarms.jsonl");
            let Ok(text) = std::fs::read_to_string(&path) else {
                continue;
            };
            for line in text.lines().filter(|l| !l.trim().is_empty()) {
                let a: Alarm = serde_json::from_str(line).unwrap();
                assert!(
                    !matches!(a.evidence, Evidence::Unknown(_)),
                    "{}: {line}",
                    path.display()
                );
                assert!(a.evidence.fits(a.code), "{line}");
                if let Evidence::Aggregated(g) = &a.evidence {
                    assert!(!matches!(g.latest.evidence, Evidence::Unknown(_)), "{line}");
                }
                assert_eq!(serde_json::to_string(&a).unwrap(), line);
                seen.insert(a.code);
                n += 1;
            }
        }
        assert!(
            n >= 25 && seen.len() >= 15,
            "{n} alarms of {} codes",
            seen.len()
        );
    }

    #[test]
    fn evidence_of_a_shape_this_version_does_not_know_is_kept_as_read() {
        let line = r#"{"kind":"drift","severity":"warning","code":"gain-drift","idx":3,"t":1.5,"message":"m","evidence":{"rate":1.0,"z":{"a":[1,2]}}}"#;
        let a: Alarm = serde_json::from_str(line).unwrap();
        assert!(matches!(a.evidence, Evidence::Unknown(_)));
        assert_eq!(serde_json::to_string(&a).unwrap(), line);
        // no evidence at all, and an alarm written without the field
        let bare = r#"{"kind":"link","severity":"info","code":"port-back","idx":null,"t":null,"message":"m"}"#;
        let a: Alarm = serde_json::from_str(bare).unwrap();
        assert_eq!(a.evidence, Evidence::None);
    }

    #[test]
    fn written_evidence_has_its_keys_in_order_and_names_its_source() {
        let a = Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            AlarmCode::GainDrift,
            "m".into(),
        )
        .with(Evidence::GainRate(GainRate {
            rate_pct_per_h: -1.5,
            se_pct_per_h: 0.25,
            n: 400,
            source: Source::Probes,
        }));
        assert_eq!(
            a.evidence.to_json().to_string(),
            r#"{"n":400,"rate_pct_per_h":-1.5,"se_pct_per_h":0.25,"source":"probes"}"#
        );
        let back: Alarm = serde_json::from_str(&serde_json::to_string(&a).unwrap()).unwrap();
        assert_eq!(back, a);
        // the same fields under a code that does not carry them are not read as that kind
        assert!(!Evidence::GainRate(GainRate {
            rate_pct_per_h: 0.0,
            se_pct_per_h: 0.0,
            n: 0,
            source: Source::Probes,
        })
        .fits(AlarmCode::GainStep));
        assert!(matches!(
            Evidence::read(AlarmCode::GainStep, a.evidence.to_json()),
            Evidence::Unknown(_)
        ));
    }
}
