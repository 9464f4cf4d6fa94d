//! Alarms: what was seen, against what threshold, with the evidence. Deterministic (controller
//! time and capture index only; wall-clock time is added by the shell's sinks, never here).

use super::evidence::Evidence;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AlarmKind {
    Link,
    CaptureQuality,
    ReciprocityOutlier,
    Isotropy,
    Drift,
    Positioning,
}

impl AlarmKind {
    /// The name in the result files.
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            AlarmKind::Link => "link",
            AlarmKind::CaptureQuality => "capture-quality",
            AlarmKind::ReciprocityOutlier => "reciprocity-outlier",
            AlarmKind::Isotropy => "isotropy",
            AlarmKind::Drift => "drift",
            AlarmKind::Positioning => "positioning",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    Info,
    Warning,
    Critical,
}

/// The stable short name of an alarm's condition: what the result files hold in `code`, the
/// storm book counts and the retake list matches. Serialised as its kebab-case name, and
/// ordered by it (so maps keyed by code keep the order they had as strings).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AlarmCode {
    /// A CAPTURE line stayed unreadable after it was asked for again; that capture is skipped.
    AnnouncementRefused,
    /// A CAPTURE line was malformed; it is asked for again.
    BadAnnouncement,
    /// A capture names a plan entry the plan does not have.
    BadEntry,
    /// Re-captures show the camera's pose moved, and nothing tells whether the wagon or arm
    /// joint 1 moved it.
    CameraPoseMoved,
    /// A line from the controller failed its framing or CRC.
    BadLine,
    /// A capture's commanded or encoder pose is not a pose of the rig.
    BadPose,
    /// A capture's file could not be decoded or averaged.
    CaptureFailed,
    /// A capture's file never appeared.
    MissingCapture,
    /// A capture index is not in the controller's capture log.
    CaptureNeverAnnounced,
    /// Announced captures are waiting to be checked.
    CapturesPending,
    /// Too many pixels of the region at the sensor's maximum.
    ClippedPixels,
    /// The lamp's colour temperature drifts.
    ColourDrift,
    /// A colour drift no longer holds.
    ColourDriftCleared,
    /// The controller reported a fault state.
    ControllerFault,
    /// The controller restarted (its boot counter moved).
    ControllerReboot,
    /// Lines fail their CRC more often than the configured share.
    CrcErrors,
    /// Goniowatch restarted on the session.
    DaemonRestart,
    /// A capture at or below the dark level.
    DarkCapture,
    /// More than one file placed on one plan entry.
    DuplicateFiles,
    /// Two different CAPTURE lines for one capture index.
    DuplicateIndex,
    /// The encoders disagree with the commanded pose.
    EncoderMismatch,
    /// An encoder mismatch episode ended.
    EncoderMismatchCleared,
    /// A plan entry was captured again.
    EntryRepeated,
    /// The lamp's gain drifts beyond the configured rate.
    GainDrift,
    /// A gain drift no longer holds.
    GainDriftCleared,
    /// The lamp's gain stepped.
    GainStep,
    /// A gain step was later explained otherwise.
    GainStepWithdrawn,
    /// The lamp probe departed from its trend while the camera's pose moved: not a lamp step.
    ProbeMovedWithPose,
    /// The images show an arm joint or the wagon off its commanded angle.
    JointOffsetSuspected,
    /// No pose of the sample can watch arm joint 3.
    Joint3SentinelUnavailable,
    /// The lamp's gain moves from capture to capture (probes, or the light sweeps' scatter).
    LampUnstable,
    /// A lamp instability no longer holds.
    LampUnstableCleared,
    /// The level after a named joint slip, for the drift fits.
    LevelAfterSlip,
    /// A capture holds NaN or infinite pixels.
    NonFinitePixels,
    /// The serial port is open again.
    PortBack,
    /// The serial port was lost.
    PortLost,
    /// Captures are placed off the plan's pose.
    PoseOffPlan,
    /// A pose-off-plan episode ended.
    PoseOffPlanCleared,
    /// No pose could be chosen for the drift probes.
    ProbePoseUnavailable,
    /// The controller refused the drift probes; the lamp is watched without them.
    ProbesRefused,
    /// A reciprocal pair departs beyond the configured limit.
    ReciprocityOutlier,
    /// The sample's surface sits off the arm's rotation centre.
    SampleOffCentre,
    /// The controller announced another session.
    SessionChanged,
    /// Files in the capture folder not placed as captures.
    SkippedFiles,
    /// A joint slip the light sweeps suggested, which a re-capture of earlier poses refutes.
    SlipRefuted,
    /// A joint pattern of the light sweeps too small for re-captures of earlier poses to check.
    SlipUnverifiable,
    /// A joint pattern of the light sweeps present since its θi layer began, on a rig without
    /// re-captures: a slip at the layer's start or the new θi's geometry.
    SlipUnresolved,
    /// A level change of the light sweeps that the layer below's light-side pattern accounts
    /// for, on a rig without probes: a lamp step or a stationary pattern grown towards grazing.
    StepUnresolved,
    /// Capture times went back.
    TimeSteppedBack,
    /// A trend in the isotropy classes that a stationary light-side pattern could also make.
    TrendUnresolved,
    /// Files in the capture folder no CAPTURE line named.
    UnannouncedFiles,
    /// The controller does not speak this protocol version.
    UnsupportedVersion,
    /// The wagon lags behind its commanded angle against its last direction of motion.
    WagonBacklashSuspected,
    /// Re-captures show the wagon standing off its commanded angle.
    WagonOffsetSuspected,
}

impl AlarmCode {
    /// Every code.
    pub(crate) const ALL: [AlarmCode; 54] = [
        AlarmCode::AnnouncementRefused,
        AlarmCode::BadAnnouncement,
        AlarmCode::BadEntry,
        AlarmCode::CameraPoseMoved,
        AlarmCode::BadLine,
        AlarmCode::BadPose,
        AlarmCode::CaptureFailed,
        AlarmCode::MissingCapture,
        AlarmCode::CaptureNeverAnnounced,
        AlarmCode::CapturesPending,
        AlarmCode::ClippedPixels,
        AlarmCode::ColourDrift,
        AlarmCode::ColourDriftCleared,
        AlarmCode::ControllerFault,
        AlarmCode::ControllerReboot,
        AlarmCode::CrcErrors,
        AlarmCode::DaemonRestart,
        AlarmCode::DarkCapture,
        AlarmCode::DuplicateFiles,
        AlarmCode::DuplicateIndex,
        AlarmCode::EncoderMismatch,
        AlarmCode::EncoderMismatchCleared,
        AlarmCode::EntryRepeated,
        AlarmCode::GainDrift,
        AlarmCode::GainDriftCleared,
        AlarmCode::GainStep,
        AlarmCode::GainStepWithdrawn,
        AlarmCode::JointOffsetSuspected,
        AlarmCode::Joint3SentinelUnavailable,
        AlarmCode::LampUnstable,
        AlarmCode::LampUnstableCleared,
        AlarmCode::LevelAfterSlip,
        AlarmCode::NonFinitePixels,
        AlarmCode::PortBack,
        AlarmCode::PortLost,
        AlarmCode::PoseOffPlan,
        AlarmCode::PoseOffPlanCleared,
        AlarmCode::ProbeMovedWithPose,
        AlarmCode::ProbePoseUnavailable,
        AlarmCode::ProbesRefused,
        AlarmCode::ReciprocityOutlier,
        AlarmCode::SampleOffCentre,
        AlarmCode::SessionChanged,
        AlarmCode::SkippedFiles,
        AlarmCode::SlipRefuted,
        AlarmCode::SlipUnverifiable,
        AlarmCode::SlipUnresolved,
        AlarmCode::StepUnresolved,
        AlarmCode::TimeSteppedBack,
        AlarmCode::TrendUnresolved,
        AlarmCode::UnannouncedFiles,
        AlarmCode::UnsupportedVersion,
        AlarmCode::WagonBacklashSuspected,
        AlarmCode::WagonOffsetSuspected,
    ];

    /// The name in the result files.
    pub fn as_str(self) -> &'static str {
        match self {
            AlarmCode::AnnouncementRefused => "announcement-refused",
            AlarmCode::BadAnnouncement => "bad-announcement",
            AlarmCode::BadEntry => "bad-entry",
            AlarmCode::CameraPoseMoved => "camera-pose-moved",
            AlarmCode::BadLine => "bad-line",
            AlarmCode::BadPose => "bad-pose",
            AlarmCode::CaptureFailed => "capture-failed",
            AlarmCode::MissingCapture => "missing-capture",
            AlarmCode::CaptureNeverAnnounced => "capture-never-announced",
            AlarmCode::CapturesPending => "captures-pending",
            AlarmCode::ClippedPixels => "clipped-pixels",
            AlarmCode::ColourDrift => "colour-drift",
            AlarmCode::ColourDriftCleared => "colour-drift-cleared",
            AlarmCode::ControllerFault => "controller-fault",
            AlarmCode::ControllerReboot => "controller-reboot",
            AlarmCode::CrcErrors => "crc-errors",
            AlarmCode::DaemonRestart => "daemon-restart",
            AlarmCode::DarkCapture => "dark-capture",
            AlarmCode::DuplicateFiles => "duplicate-files",
            AlarmCode::DuplicateIndex => "duplicate-index",
            AlarmCode::EncoderMismatch => "encoder-mismatch",
            AlarmCode::EncoderMismatchCleared => "encoder-mismatch-cleared",
            AlarmCode::EntryRepeated => "entry-repeated",
            AlarmCode::GainDrift => "gain-drift",
            AlarmCode::GainDriftCleared => "gain-drift-cleared",
            AlarmCode::GainStep => "gain-step",
            AlarmCode::GainStepWithdrawn => "gain-step-withdrawn",
            AlarmCode::ProbeMovedWithPose => "probe-moved-with-pose",
            AlarmCode::JointOffsetSuspected => "joint-offset-suspected",
            AlarmCode::Joint3SentinelUnavailable => "joint3-sentinel-unavailable",
            AlarmCode::LampUnstable => "lamp-unstable",
            AlarmCode::LampUnstableCleared => "lamp-unstable-cleared",
            AlarmCode::LevelAfterSlip => "level-after-slip",
            AlarmCode::NonFinitePixels => "non-finite-pixels",
            AlarmCode::PortBack => "port-back",
            AlarmCode::PortLost => "port-lost",
            AlarmCode::PoseOffPlan => "pose-off-plan",
            AlarmCode::PoseOffPlanCleared => "pose-off-plan-cleared",
            AlarmCode::ProbePoseUnavailable => "probe-pose-unavailable",
            AlarmCode::ProbesRefused => "probes-refused",
            AlarmCode::ReciprocityOutlier => "reciprocity-outlier",
            AlarmCode::SampleOffCentre => "sample-off-centre",
            AlarmCode::SessionChanged => "session-changed",
            AlarmCode::SkippedFiles => "skipped-files",
            AlarmCode::SlipRefuted => "slip-refuted",
            AlarmCode::SlipUnverifiable => "slip-unverifiable",
            AlarmCode::SlipUnresolved => "slip-unresolved",
            AlarmCode::StepUnresolved => "step-unresolved",
            AlarmCode::TimeSteppedBack => "time-stepped-back",
            AlarmCode::TrendUnresolved => "trend-unresolved",
            AlarmCode::UnannouncedFiles => "unannounced-files",
            AlarmCode::UnsupportedVersion => "unsupported-version",
            AlarmCode::WagonBacklashSuspected => "wagon-backlash-suspected",
            AlarmCode::WagonOffsetSuspected => "wagon-offset-suspected",
        }
    }

    /// What the condition is, in a few words (for the docs and the status page).
    pub(crate) fn meaning(self) -> &'static str {
        match self {
            AlarmCode::AnnouncementRefused => "a CAPTURE line stayed unreadable after it was asked for again; that capture is skipped",
            AlarmCode::BadAnnouncement => "a CAPTURE line was malformed; it is asked for again",
            AlarmCode::BadEntry => "a capture names a plan entry the plan does not have",
            AlarmCode::CameraPoseMoved => "re-captures of two earlier poses show the camera's pose moved, by the wagon or by arm joint 1",
            AlarmCode::BadLine => "a line from the controller failed its framing or CRC",
            AlarmCode::BadPose => "a capture's commanded or encoder pose is not a pose of the rig",
            AlarmCode::CaptureFailed => "a capture's file could not be decoded or averaged",
            AlarmCode::MissingCapture => "a capture's file never appeared",
            AlarmCode::CaptureNeverAnnounced => "a capture index is not in the controller's capture log",
            AlarmCode::CapturesPending => "announced captures are waiting to be checked",
            AlarmCode::ClippedPixels => "too many pixels of the region at the sensor's maximum",
            AlarmCode::ColourDrift => "the lamp's colour temperature drifts",
            AlarmCode::ColourDriftCleared => "a colour drift no longer holds",
            AlarmCode::ControllerFault => "the controller reported a fault state",
            AlarmCode::ControllerReboot => "the controller restarted (its boot counter moved)",
            AlarmCode::CrcErrors => "lines fail their CRC more often than the configured share",
            AlarmCode::DaemonRestart => "goniowatch restarted on the session",
            AlarmCode::DarkCapture => "a capture at or below the dark level",
            AlarmCode::DuplicateFiles => "more than one file placed on one plan entry",
            AlarmCode::DuplicateIndex => "two different CAPTURE lines for one capture index",
            AlarmCode::EncoderMismatch => "the encoders disagree with the commanded pose",
            AlarmCode::EncoderMismatchCleared => "an encoder mismatch episode ended",
            AlarmCode::EntryRepeated => "a plan entry was captured again",
            AlarmCode::GainDrift => "the lamp's gain drifts beyond the configured rate",
            AlarmCode::GainDriftCleared => "a gain drift no longer holds",
            AlarmCode::GainStep => "the lamp's gain stepped",
            AlarmCode::GainStepWithdrawn => "a gain step was later explained otherwise",
            AlarmCode::ProbeMovedWithPose => "the lamp probe departed from its trend while the camera's pose moved: not raised as a lamp step",
            AlarmCode::JointOffsetSuspected => "the images show an arm joint or the wagon off its commanded angle",
            AlarmCode::Joint3SentinelUnavailable => "no pose of the sample can watch arm joint 3",
            AlarmCode::LampUnstable => "the lamp's gain moves from capture to capture: the probes, or without them the light sweeps, scatter more than a steady lamp allows",
            AlarmCode::LampUnstableCleared => "a lamp instability no longer holds",
            AlarmCode::LevelAfterSlip => "the level after a named joint slip, for the drift fits",
            AlarmCode::NonFinitePixels => "a capture holds NaN or infinite pixels",
            AlarmCode::PortBack => "the serial port is open again",
            AlarmCode::PortLost => "the serial port was lost",
            AlarmCode::PoseOffPlan => "captures are placed off the plan's pose",
            AlarmCode::PoseOffPlanCleared => "a pose-off-plan episode ended",
            AlarmCode::ProbePoseUnavailable => "no pose could be chosen for the drift probes",
            AlarmCode::ProbesRefused => {
                "the controller refused the drift probes; the lamp is watched without them"
            }
            AlarmCode::ReciprocityOutlier => "a reciprocal pair departs beyond the configured limit",
            AlarmCode::SampleOffCentre => "the sample's surface sits off the arm's rotation centre",
            AlarmCode::SessionChanged => "the controller announced another session",
            AlarmCode::SkippedFiles => "files in the capture folder not placed as captures",
            AlarmCode::SlipRefuted => "a joint slip the light sweeps suggested, which a re-capture of earlier poses refutes",
            AlarmCode::SlipUnverifiable => "a joint pattern of the light sweeps too small for re-captures of earlier poses to check: not named",
            AlarmCode::SlipUnresolved => "a joint pattern of the light sweeps present since its θi layer began, without re-captures to tell a slip from the geometry: not named",
            AlarmCode::StepUnresolved => "a level change of the light sweeps that the layer below's light-side pattern accounts for, without probes to tell a lamp step from it: not raised",
            AlarmCode::TimeSteppedBack => "capture times went back",
            AlarmCode::TrendUnresolved => "a trend in the isotropy classes that a stationary light-side pattern could also make",
            AlarmCode::UnannouncedFiles => "files in the capture folder no CAPTURE line named",
            AlarmCode::UnsupportedVersion => "the controller does not speak this protocol version",
            AlarmCode::WagonBacklashSuspected => "the images show the wagon lagging behind its commanded angle against its last direction of motion",
            AlarmCode::WagonOffsetSuspected => "re-captures of two earlier poses show the wagon standing off its commanded angle",
        }
    }

    /// The code that ends an episode of this one (`pose-off-plan` → `pose-off-plan-cleared`).
    pub(crate) fn cleared(self) -> Option<AlarmCode> {
        match self {
            AlarmCode::PoseOffPlan => Some(AlarmCode::PoseOffPlanCleared),
            AlarmCode::EncoderMismatch => Some(AlarmCode::EncoderMismatchCleared),
            AlarmCode::GainDrift => Some(AlarmCode::GainDriftCleared),
            AlarmCode::ColourDrift => Some(AlarmCode::ColourDriftCleared),
            AlarmCode::LampUnstable => Some(AlarmCode::LampUnstableCleared),
            _ => None,
        }
    }
}

impl PartialOrd for AlarmCode {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for AlarmCode {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.as_str().cmp(other.as_str())
    }
}

impl std::fmt::Display for AlarmCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is no alarm code.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown alarm code {0:?}")]
pub struct UnknownAlarmCode(pub String);

impl std::str::FromStr for AlarmCode {
    type Err = UnknownAlarmCode;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        AlarmCode::ALL
            .iter()
            .copied()
            .find(|c| c.as_str() == s)
            .ok_or_else(|| UnknownAlarmCode(s.to_string()))
    }
}

impl Serialize for AlarmCode {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for AlarmCode {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "AlarmRecord")]
pub struct Alarm {
    pub kind: AlarmKind,
    pub severity: Severity,
    /// The condition's stable short name.
    pub code: AlarmCode,
    /// The capture the alarm is about, when there is one.
    pub idx: Option<u64>,
    /// Controller time (s) of the evidence, when known.
    pub t: Option<f64>,
    /// A sentence that explains itself: what was seen, against what threshold.
    pub message: String,
    /// The numbers behind the message, typed (written as the object of its fields).
    #[serde(serialize_with = "super::evidence::write_sorted")]
    pub evidence: Evidence,
    /// What the operator can do about it. Every drift, positioning and reciprocity alarm that
    /// opens a condition says it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub action: Option<String>,
    /// Which captures the condition affects, and what the output does about them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub affects: Option<Affects>,
}

/// An alarm as a result file holds it: its evidence is read by its code.
#[derive(Deserialize)]
struct AlarmRecord {
    kind: AlarmKind,
    severity: Severity,
    code: AlarmCode,
    idx: Option<u64>,
    t: Option<f64>,
    message: String,
    #[serde(default)]
    evidence: serde_json::Value,
    #[serde(default)]
    action: Option<String>,
    #[serde(default)]
    affects: Option<Affects>,
}

impl From<AlarmRecord> for Alarm {
    fn from(r: AlarmRecord) -> Self {
        Alarm {
            kind: r.kind,
            severity: r.severity,
            code: r.code,
            idx: r.idx,
            t: r.t,
            message: r.message,
            evidence: Evidence::read(r.code, r.evidence),
            action: r.action,
            affects: r.affects,
        }
    }
}

/// What the operator can do, for the conditions several stages raise. Each says what to check,
/// what the output does meanwhile, and whether anything must be taken again.
pub(crate) mod action {
    /// A gain drift (a rate).
    pub(crate) const GAIN_DRIFT: &str = "Let the lamp warm up and settle, or check its supply; the corrected colours divide the drift out, so no capture needs taking again. If the rate keeps growing, pause the run and re-seat or replace the lamp.";
    /// A gain step.
    pub(crate) const GAIN_STEP: &str = "Check the lamp, its supply and anything that may shade the sample or reflect onto it; the step is fitted and divided out of the corrected colours. Steps that recur mean an unstable lamp: pause the run and fix it.";
    /// The sample sits off the arm's rotation centre.
    pub(crate) const SAMPLE_OFF_CENTRE: &str = "Check that the sample is centred in its holder and lies flat at the holder's height; at the next chance re-centre it. The drift checks model the pattern from now on, at some cost in precision; drift probes ([probes] every = N) measure the lamp free of it.";
    /// A colour drift of the lamp.
    pub(crate) const COLOUR_DRIFT: &str = "Let the lamp settle or check its supply voltage (a colour drift at a steady luminance is the filament's temperature); the corrected colours divide the drift out.";
}

/// What the output does about the captures a condition affects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Handling {
    /// The corrected output divides the condition out: nothing needs taking again.
    Corrected,
    /// The captures are on the retake list.
    Retake,
    /// Neither: the data may be right; the operator has to look.
    Inspect,
}

impl Handling {
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            Handling::Corrected => "corrected",
            Handling::Retake => "retake",
            Handling::Inspect => "inspect",
        }
    }
}

/// The captures an alarm's condition affects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scope", rename_all = "kebab-case")]
pub enum Affects {
    /// These captures.
    Captures { idx: Vec<u64>, handling: Handling },
    /// Every capture from `from_idx` on, for as long as the condition lasts.
    Since { from_idx: u64, handling: Handling },
    /// The captures from `from_idx` to `to_idx`, both included: the condition has ended.
    Between {
        from_idx: u64,
        to_idx: u64,
        handling: Handling,
    },
}

impl Affects {
    pub(crate) fn handling(&self) -> Handling {
        match self {
            Affects::Captures { handling, .. }
            | Affects::Since { handling, .. }
            | Affects::Between { handling, .. } => *handling,
        }
    }

    /// Whether capture `idx` is among the affected ones.
    pub fn contains(&self, idx: u64) -> bool {
        match self {
            Affects::Captures { idx: v, .. } => v.contains(&idx),
            Affects::Since { from_idx, .. } => idx >= *from_idx,
            Affects::Between {
                from_idx, to_idx, ..
            } => (*from_idx..=*to_idx).contains(&idx),
        }
    }

    /// The captures of both (for alarms of one code aggregated into one): a union of lists,
    /// else from the earliest first capture on; the more demanding handling (retake, then
    /// inspect, then corrected). A list is kept to `max_listed` captures, beyond which it
    /// becomes "from its first on".
    pub(crate) fn merge(self, other: Affects, max_listed: usize) -> Affects {
        let rank = |h: Handling| match h {
            Handling::Retake => 2,
            Handling::Inspect => 1,
            Handling::Corrected => 0,
        };
        let handling = if rank(other.handling()) > rank(self.handling()) {
            other.handling()
        } else {
            self.handling()
        };
        let first = |a: &Affects| match a {
            Affects::Captures { idx, .. } => idx.iter().min().copied().unwrap_or(0),
            Affects::Since { from_idx, .. } | Affects::Between { from_idx, .. } => *from_idx,
        };
        let from_idx = first(&self).min(first(&other));
        match (self, other) {
            (Affects::Captures { idx: mut a, .. }, Affects::Captures { idx: b, .. }) => {
                a.extend(b);
                a.sort_unstable();
                a.dedup();
                if a.len() > max_listed {
                    Affects::Since { from_idx, handling }
                } else {
                    Affects::Captures { idx: a, handling }
                }
            }
            _ => Affects::Since { from_idx, handling },
        }
    }

    /// A short phrase for the surfaces, e.g. "captures 3280 on: corrected".
    pub(crate) fn describe(&self) -> String {
        let which = match self {
            Affects::Captures { idx, .. } => {
                let list: Vec<String> = idx.iter().map(u64::to_string).collect();
                format!(
                    "capture{} {}",
                    if idx.len() == 1 { "" } else { "s" },
                    list.join(", ")
                )
            }
            Affects::Since { from_idx, .. } => format!("captures {from_idx} on"),
            Affects::Between {
                from_idx, to_idx, ..
            } => format!("captures {from_idx}–{to_idx}"),
        };
        format!("{which}: {}", self.handling().as_str())
    }
}

impl Alarm {
    pub fn new(kind: AlarmKind, severity: Severity, code: AlarmCode, message: String) -> Self {
        Alarm {
            kind,
            severity,
            code,
            idx: None,
            t: None,
            message,
            evidence: Evidence::None,
            action: None,
            affects: None,
        }
    }
    pub(crate) fn at(mut self, idx: Option<u64>, t: Option<f64>) -> Self {
        self.idx = idx;
        self.t = t;
        self
    }
    pub(crate) fn with(mut self, evidence: Evidence) -> Self {
        debug_assert!(evidence.fits(self.code), "{:?} for {}", evidence, self.code);
        self.evidence = evidence;
        self
    }
    /// What the operator can do, and the captures the condition affects.
    pub(crate) fn advise(mut self, action: &str, affects: Option<Affects>) -> Self {
        self.action = Some(action.to_string());
        self.affects = affects;
        self
    }
    /// The captures the condition affects, without an action (a condition that has ended).
    pub(crate) fn affecting(mut self, affects: Affects) -> Self {
        self.affects = Some(affects);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_alarm_code_is_written_as_its_name_and_read_back() {
        let mut names = std::collections::BTreeSet::new();
        for c in AlarmCode::ALL {
            let json = serde_json::to_string(&c).unwrap();
            assert_eq!(json, format!("\"{}\"", c.as_str()));
            assert_eq!(serde_json::from_str::<AlarmCode>(&json).unwrap(), c);
            assert_eq!(c.as_str().parse::<AlarmCode>().unwrap(), c);
            assert!(names.insert(c.as_str()), "{c} twice");
            assert!(!c.meaning().is_empty());
            // kebab-case, as the files have always held
            assert!(c
                .as_str()
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-'));
        }
        // ordered as the names are, so maps keyed by code keep their order
        let mut by_enum = AlarmCode::ALL.to_vec();
        by_enum.sort();
        let by_name: Vec<&str> = names.into_iter().collect();
        assert_eq!(
            by_enum.iter().map(|c| c.as_str()).collect::<Vec<_>>(),
            by_name
        );
        let e = serde_json::from_str::<AlarmCode>("\"lamp-on-fire\"").unwrap_err();
        assert!(e.to_string().contains("lamp-on-fire"), "{e}");
        for c in AlarmCode::ALL {
            if let Some(k) = c.cleared() {
                assert_eq!(k.as_str(), format!("{c}-cleared"));
            }
        }
    }

    #[test]
    fn every_alarm_kind_is_written_as_its_name() {
        for k in [
            AlarmKind::Link,
            AlarmKind::CaptureQuality,
            AlarmKind::ReciprocityOutlier,
            AlarmKind::Isotropy,
            AlarmKind::Drift,
            AlarmKind::Positioning,
        ] {
            assert_eq!(
                serde_json::to_string(&k).unwrap(),
                format!("\"{}\"", k.as_str())
            );
        }
    }
}
