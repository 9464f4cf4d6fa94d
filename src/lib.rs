//! goniowatch: a live checker that runs beside a BTF gonioreflectometer.
//!
//! Layers (see ARCHITECTURE.md):
//! - [`measure`]: the sans-IO measurement core (colour, geometry, kinematics, plan, averaging,
//!   reciprocity). Pure and deterministic.
//! - [`config`]: the TOML configuration (pure parsing and validation).
//! - [`decode`]: shell side, HDR/EXR bytes → RGB buffer, hardened against malformed files.
//! - [`commands`]: shell side, the CLI's commands as functions returning serialisable records.

pub mod commands;
pub mod config;
pub mod decode;
pub mod measure;
