//! goniowatch: a live checker that runs beside a BTF gonioreflectometer.
//!
//! Layers (see ARCHITECTURE.md):
//! - [`measure`]: the sans-IO measurement core (colour, geometry, kinematics, plan, averaging,
//!   reciprocity). Pure and deterministic.
//! - [`config`]: the TOML configuration (pure parsing and validation).
//! - [`decode`]: shell side, HDR/EXR bytes → RGB buffer, hardened against malformed files.
//! - [`protocol`]: the line framing of docs/protocol.md (pure).
//! - [`engine`]: the deterministic session engine: inputs (serial lines, link events, capture
//!   outcomes) in, lines to send, captures to ingest and result records out (pure).
//! - [`daemon`]: shell side, `run` and `replay`: serial link, ingestion pool, journal, sinks.
//! - [`commands`]: shell side, the CLI's commands as functions returning serialisable records.
//! - [`compare`]: shell side, `goniowatch compare`: a session against a reference measurement.
//! - [`reference`]: the reference-BRDF file format (pure parsing).
//! - [`report`]: shell side, `goniowatch report`: the end-of-run HTML report and CSV tables.

pub mod checks;
pub mod cli;
pub mod config;
pub mod daemon;
pub mod decode;
pub mod engine;
pub mod measure;
pub mod protocol;
pub mod reference;
pub mod session;
