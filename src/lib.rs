//! goniowatch: a live checker that runs beside a BTF gonioreflectometer.
//!
//! Layers, lowest first (see ARCHITECTURE.md); each imports only from those above it here:
//! - [`measure`]: the sans-IO measurement core (colour, geometry, kinematics, plan, averaging,
//!   reciprocity, resampling, robust statistics). Pure and deterministic.
//! - [`detect`]: the detectors (gain drift and steps, probes, the joint-3 sentinel, the lamp's
//!   colour, the light sweeps, the probe plan): typed findings with their numbers, never alarms.
//! - [`reference`]: the reference-BRDF file format (pure parsing).
//! - [`protocol`]: the line framing of docs/protocol.md and its typed messages (pure).
//! - [`archive`]: captures known only by their files: names or a sidecar → plan entries, and
//!   the controller's side of the protocol that announces them (pure).
//! - [`checks`]: the checker: a router over one stage per concern, the alarms (the words,
//!   severity and advice for every finding) and the result records (pure).
//! - [`export`]: what a lab takes away from a checked session: the drift model and photometry
//!   to a BRDF, one row per capture, the MERL grid (pure).
//! - [`config`]: the TOML configuration as plain data (parsing and validation; the
//!   checks' and core's spec types are its sections).
//! - [`setup`]: the fixed parts of a session built from its configuration once (plan, rig,
//!   colour conversion, probe entry).
//! - [`engine`]: the deterministic session engine: inputs (serial lines, link events, capture
//!   outcomes) in, lines to send, captures to ingest and result records out (pure).
//! - [`decode`]: shell side, HDR/EXR bytes → RGB buffer, hardened against malformed files.
//! - [`session`]: shell side, the session folder: its files, the journal, crash recovery.
//! - [`daemon`]: shell side, `run` and `replay`: serial link, ingestion pool, sinks, status page.
//! - [`cli`]: shell side, the other commands (`average`, `plan`, `compare`, `report`) and the
//!   printed summary.
//!
//! - `fixtures` (dev-only, feature `fixtures`): synthetic sessions and a scripted controller for
//!   the tests and benchmarks.
//!
//! Items used only inside the crate are `pub(crate)`, and `unreachable_pub` is on, so the compiler
//! reports dead code.

#![warn(unreachable_pub)]

pub mod archive;
pub mod checks;
pub mod cli;
pub mod config;
pub mod daemon;
pub mod decode;
pub(crate) mod detect;
pub mod engine;
pub mod export;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod measure;
pub mod protocol;
pub mod reference;
pub mod session;
pub mod setup;
