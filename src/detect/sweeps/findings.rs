//! What the sweep checks find: typed, with their numbers; `crate::checks` words them as
//! alarms.

pub(crate) use super::approach::ApproachReading;
pub(crate) use super::axis::AxisReading;
use super::JointFit;

/// The sweep a finding was made at: its light direction, its last capture with that capture's
/// controller time, and its θi layer (millidegrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SweepAt {
    pub light: usize,
    pub last_idx: u64,
    pub last_t: f64,
    pub layer_mdeg: i64,
}

/// A level CUSUM run that crossed its threshold: its mean level (%), the sweeps in it and the
/// capture that ended its first sweep, its statistic and the threshold it crossed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LevelRun {
    pub level_pct: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
}

/// A joint's pattern against the earlier sweeps of its own θi layer (`SweepMonitor::
/// layer_change`): the layer's sweeps tested before the pattern's CUSUM run began, their mean offset
/// and its standard error (none without such sweeps), and the run's mean offset less theirs in
/// standard errors.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct LayerChange {
    pub sweeps_before: usize,
    pub before: Option<(f64, f64)>,
    pub change_z: Option<f64>,
}

/// The θi layer below a level crossing at the crossing run's light azimuths
/// (`SweepMonitor::pattern_below`): its θi (degrees), the mean departure of its light effects
/// from their own azimuthal pattern model there (ln units, interpolated between its lights),
/// that mean's standard error from its sweeps' level standard errors, and the growth a
/// light-side pattern may have from that θi to the crossing's (the lamp footprint's tan² law).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PatternBelow {
    pub below_deg: f64,
    pub departure: f64,
    pub se: f64,
    pub growth: f64,
}

/// The wagon named as lagging (`wagon`): the lag's estimate (degrees) with its standard error
/// and the sweeps behind it, the CUSUM run's own mean and length, the wagon's offset in the
/// sweep that named it (untested, for the operator), the capture that ended the run's first
/// sweep (`since_idx`), the first capture the lag can have affected (`from_idx`), the statistic
/// and the threshold it crossed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct WagonBacklash {
    pub backlash_deg: f64,
    pub se_deg: f64,
    pub estimate_sweeps: usize,
    pub run_mean_deg: f64,
    pub offset_deg: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub from_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    /// Named by a pose re-captured from both sides after the re-captured pair departed
    /// (`approach`): its reading; the other fields are then the pair's (its CUSUM, and its
    /// change read as an offset), none of the sweeps'.
    pub approach: Option<ApproachReading>,
}

/// The wagon's offset named by re-capturing two poses (`wagon_watch`): its estimate (degrees)
/// with its standard error, the two plan entries,
/// the change of their difference (%) and its sensitivity to the wagon (%/°), what a degree of
/// joint 1 and of joint 2 would read as (degrees of wagon), the light sweeps of the originals,
/// the readings behind the estimate, the CUSUM and its threshold, and the first capture it can
/// have affected (the one after the sweep of the last reading in control).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct WagonOffset {
    pub offset_deg: f64,
    pub se_deg: f64,
    pub entries: [usize; 2],
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub joint_leak: [f64; 2],
    pub originals_lights: [usize; 2],
    pub readings: usize,
    /// The light sweeps' departure of the wagon's offset over the same span (standard
    /// deviations, `wagon_watch::attribute`); None when they named no axis in time.
    pub sweeps_z: Option<f64>,
    pub statistic: f64,
    pub threshold: f64,
    pub since_idx: u64,
    /// One of the pair's poses re-captured from both sides, when it read no lag (`approach`).
    pub approach: Option<ApproachReading>,
    /// The re-captures that tell the wagon from joint 1 (`axis`), when they were read.
    pub axis: Option<AxisReading>,
    /// Whether the wagon was told from joint 1 (by the light sweeps' refit or by `axis`);
    /// otherwise the camera's pose moved and nothing says which of the two moved it.
    pub told: bool,
}

/// A joint named as slipped: its estimated offset (degrees) with its standard error and the
/// sweeps behind the estimate, the CUSUM run's own mean and length, the capture that ended the
/// run's first sweep (`since_idx`), the first capture the slip can have affected (`from_idx`),
/// the statistic and the threshold it crossed, the level change attributed to it (when a level
/// change named it) and the sweep's fits of the other joints.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct JointSlip {
    /// 1 or 2.
    pub joint: usize,
    pub offset_deg: f64,
    pub se_deg: f64,
    pub estimate_sweeps: usize,
    pub run_mean_deg: f64,
    pub sweeps: usize,
    pub since_idx: u64,
    pub from_idx: u64,
    pub statistic: f64,
    pub threshold: f64,
    pub attributed_level_pct: Option<f64>,
    pub other_joints: Vec<JointFit>,
    /// What re-capturing earlier poses said of it (`recapture`).
    pub recapture: Recapture,
    /// The re-captures that told joint 1 from the wagon when the wagon watch's pair departed
    /// (`axis`).
    pub axis: Option<AxisReading>,
}

/// Whether a slip the sweeps name was checked by re-capturing earlier poses (`recapture`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Recapture {
    /// The rig takes no re-captures (watch mode, archives, a rig that refused probes): named
    /// from the sweeps alone.
    NoProbes,
    /// Not asked on a probe-taking rig: no earlier sweep to re-capture poses from yet, or a
    /// level change with the joint's pattern named it.
    NotAsked,
    /// The re-captures show the slip.
    Confirmed(RecaptureReading),
    /// Asked for, and not taken: the rig did not take them within `RECAPTURE_WAIT_CAPTURES`
    /// regular captures, refused probes, or the run ended first. Named from the sweeps alone.
    Unanswered { entries: Vec<usize> },
}

/// Earlier poses of one sweep re-captured back to back: `entries` (first half: those whose
/// luminance rises most with the joint; then those whose luminance falls most), the change of
/// the two halves' mean luminance ratio against the originals' (%), the difference of their
/// mean sensitivities to the named joint (%/°), and the joint's offset that change makes
/// (degrees) with its standard error.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RecaptureReading {
    pub joint: usize,
    pub entries: Vec<usize>,
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub offset_deg: f64,
    pub se_deg: f64,
}

/// What the sweep checks saw in a completed sweep, with its numbers. `checks` words these as
/// alarms.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum SweepFinding {
    /// The level of the layer's sweeps moved `up` or down beyond the modelled drift and no
    /// joint's pattern explains it: a lamp step, which the drift model takes from `from_idx`
    /// (the first capture of the run's first sweep, at `since_t`).
    GainStep {
        at: SweepAt,
        up: bool,
        run: LevelRun,
        since_t: Option<f64>,
        from_idx: u64,
    },
    /// A level change that began after `joint` was named slipped in the same layer (from
    /// capture `slip_from_idx`): the tilt's, no lamp step.
    LevelAfterSlip {
        at: SweepAt,
        run: LevelRun,
        joint: usize,
        slip_from_idx: u64,
    },
    /// A gain step raised at capture `step_idx` (`level_pct`) came after `joint` began to slip
    /// (from `slip_from_idx`): it was the tilt's, and leaves the drift model.
    GainStepWithdrawn {
        at: SweepAt,
        joint: usize,
        step_idx: u64,
        level_pct: f64,
        slip_from_idx: u64,
    },
    /// The pattern across the cameras (or a level change with that joint's pattern) names a
    /// joint as slipped, while the encoders agree with the commands.
    JointSlip { at: SweepAt, slip: JointSlip },
    /// The sweeps' pattern named `joint` offset by `offset_deg`, and a re-capture of two earlier
    /// poses shows no such change (`reading`): a stationary pattern of the geometry that
    /// follows the pose, not a slip.
    SlipRefuted {
        at: SweepAt,
        joint: usize,
        offset_deg: f64,
        reading: RecaptureReading,
    },
    /// The sweeps' pattern named `joint` offset by `offset_deg`, which no set of re-captures
    /// of earlier poses could check: they would show an offset of `checkable_deg` or more. A
    /// stationary pattern of the geometry or a slip smaller than that; not named (once a
    /// layer).
    SlipUnverifiable {
        at: SweepAt,
        joint: usize,
        offset_deg: f64,
        checkable_deg: f64,
    },
    /// (A rig without re-captures) The sweeps' pattern named `joint` offset by `offset_deg`,
    /// but no change within its θi layer shows it: a slip at the layer's start or a
    /// stationary pattern of the new θi's geometry, which only re-captures of earlier poses
    /// tell apart; not named (once a layer).
    SlipUnresolved {
        at: SweepAt,
        joint: usize,
        offset_deg: f64,
        change: LayerChange,
    },
    /// (No probes) The level of the layer's sweeps moved `up` or down, but at the same light
    /// azimuths the layer below departed from its own pattern the same way, by enough to
    /// account for the run when grown towards grazing (`below`): a stationary light-side
    /// pattern (a holder's shadow, a bowed sample) or a lamp step, which only later sweeps or
    /// re-captures tell apart; no alarm (once per sign and layer). The step is still raised
    /// when the level stays off where the layer below does not explain it.
    StepUnresolved {
        at: SweepAt,
        up: bool,
        run: LevelRun,
        below: PatternBelow,
    },
    /// The wagon lags behind its commanded angle against its last direction of motion.
    WagonBacklash {
        at: SweepAt,
        backlash: WagonBacklash,
    },
    /// The wagon stands off its commanded angle (re-captures of two poses).
    WagonOffset { at: SweepAt, offset: WagonOffset },
    /// (No probes) The captures scatter about the isotropy model by at least `scatter_pct` (the
    /// smallest residual SD of `sweeps` consecutive judged sweeps, the first from capture
    /// `from_idx`), beyond `limit_pct`: the lamp's gain moves from capture to capture.
    LampUnstable {
        at: SweepAt,
        scatter_pct: f64,
        limit_pct: f64,
        sweeps: usize,
        from_idx: u64,
    },
    /// The scatter is back well under the limit: `scatter_pct` is the largest residual SD of the
    /// last `sweeps` judged sweeps.
    LampSteady {
        at: SweepAt,
        scatter_pct: f64,
        limit_pct: f64,
        sweeps: usize,
    },
}

impl SweepFinding {
    /// The sweep it was made at.
    pub(crate) fn at(&self) -> &SweepAt {
        match self {
            SweepFinding::GainStep { at, .. }
            | SweepFinding::LevelAfterSlip { at, .. }
            | SweepFinding::GainStepWithdrawn { at, .. }
            | SweepFinding::JointSlip { at, .. }
            | SweepFinding::SlipRefuted { at, .. }
            | SweepFinding::SlipUnverifiable { at, .. }
            | SweepFinding::SlipUnresolved { at, .. }
            | SweepFinding::StepUnresolved { at, .. }
            | SweepFinding::WagonBacklash { at, .. }
            | SweepFinding::WagonOffset { at, .. }
            | SweepFinding::LampUnstable { at, .. }
            | SweepFinding::LampSteady { at, .. } => at,
        }
    }
}
