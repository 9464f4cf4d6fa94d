//! The detectors: pure, deterministic stages that watch the measurements for the faults of a
//! long acquisition (lamp drift and steps, joint slips, the lamp's colour) and say what they saw,
//! with its numbers. They never decide what to alarm about: `crate::checks` turns their findings
//! into alarms and owns the words, the severity and the advice. Their design is in
//! docs/detectors.md.

pub mod drift;
pub mod identifiability;
pub mod lamp;
pub mod probe_plan;
pub mod probes;
pub mod sentinel;
pub mod sweeps;
