//! The detectors: pure, deterministic stages that watch the measurements for the faults of a
//! long acquisition (lamp drift and steps, joint slips, the lamp's colour) and say what they saw,
//! with its numbers. They never decide what to alarm about: `crate::checks` turns their findings
//! into alarms and owns the words, the severity and the advice. Their design is in
//! docs/detectors.md.

pub(crate) mod drift;
pub(crate) mod identifiability;
pub(crate) mod lamp;
pub(crate) mod probe_plan;
pub(crate) mod probes;
pub(crate) mod sentinel;
pub(crate) mod sweeps;
