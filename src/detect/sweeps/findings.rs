//! What the sweep checks find: typed, with their numbers; `crate::checks` words them as
//! alarms.

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
            | SweepFinding::LampUnstable { at, .. }
            | SweepFinding::LampSteady { at, .. } => at,
        }
    }
}
