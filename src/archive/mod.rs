//! Core: captures known only by their files — an archive of a finished acquisition, or a rig
//! that writes files but does not speak docs/protocol.md.
//!
//! - [`listing`]: file names (a pattern with named groups) or a sidecar table → plan entries,
//!   capture order and times; what cannot be placed is reported with its reason, never guessed.
//! - [`follow`]: watch mode's memory between listings: what to announce, what to check again
//!   after its file changed, which duplicates to report.
//! - [`controller`]: the controller's side of the protocol for such a listing, as a pure state
//!   machine. The engine, journal, resume and replay then work exactly as with a real rig: the
//!   lines it writes are what the engine receives and the journal records.
//!
//! Pure: file facts (names, modification times) and sidecar rows come in as data.

pub mod controller;
pub(crate) mod follow;
pub mod listing;

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where captures come from (`[source]` in the config).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum SourceKind {
    /// A controller speaking docs/protocol.md on the serial link.
    #[default]
    Protocol,
    /// Files in the capture folder, placed by their names or a sidecar.
    Files,
}

/// How the captures of a files source are put in acquisition order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum OrderRule {
    /// `index` when the pattern has an `idx` group, else `time` when the sidecar has times,
    /// else `plan`.
    #[default]
    Auto,
    /// The `idx` group of the pattern, or the sidecar's `idx` column.
    Index,
    /// The sidecar's `t` column.
    Time,
    /// The files' modification times (also taken as the capture times).
    Mtime,
    /// The plan's acquisition order of the entries (a rig that followed its plan).
    Plan,
}

/// The Bonn convention: `tl<θi>`, `pl<φi>`, `tv<θo>`, `pv<φo>` in degrees, in that order,
/// anywhere in the name (e.g. `tl015_pl060_tv030_pv000.exr`, `00042 tl15 pl60 tv30 pv0.hdr`);
/// a leading number, when present, is the capture index.
pub(crate) const BONN_PATTERN: &str = r"(?i)^(?:.*/)?(?:(?P<idx>\d+)[ _-]+)?tl(?P<tl>\d+(?:\.\d+)?)[ _-]*pl(?P<pl>\d+(?:\.\d+)?)[ _-]*tv(?P<tv>\d+(?:\.\d+)?)[ _-]*pv(?P<pv>\d+(?:\.\d+)?)[^/]*$";

/// `[source]` in the config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SourceSpec {
    pub kind: SourceKind,
    /// A regular expression over each file's path relative to the capture folder, with named
    /// groups `tl`, `pl`, `tv`, `pv` (light and camera θ, φ in degrees) or `entry` (the plan
    /// entry), and optionally `idx` (the capture index). Ignored when a sidecar is given.
    pub pattern: String,
    /// A table beside the captures (relative to the capture folder): `.csv` with a header, or
    /// `.jsonl`, one row per file with `file` and either `theta_i, phi_i, theta_o, phi_o` or
    /// `entry`, and optionally `t` (seconds), `idx` and `exposure` (relative; the capture's
    /// linear values are divided by it).
    pub sidecar: Option<PathBuf>,
    pub order: OrderRule,
    /// Where no capture times are known: the time between captures, in seconds (the rates are
    /// then per capture index, and the session says so).
    pub seconds_per_capture: f64,
    /// How far a file's angles may be from the plan's direction.
    pub angle_tolerance_deg: f64,
    /// File name endings taken as captures (case-insensitive).
    pub extensions: Vec<String>,
    /// Watch mode: how often the capture folder is listed.
    pub poll_ms: u64,
    /// Watch mode: list the folder as soon as the file system reports a change too (inotify);
    /// off for shares that report none, where `poll_ms` alone applies.
    pub notify: bool,
}

impl Default for SourceSpec {
    fn default() -> Self {
        SourceSpec {
            kind: SourceKind::Protocol,
            pattern: BONN_PATTERN.into(),
            sidecar: None,
            order: OrderRule::Auto,
            seconds_per_capture: 7.0,
            angle_tolerance_deg: 0.5,
            extensions: ["hdr", "exr", "png", "jpg", "jpeg"]
                .map(String::from)
                .to_vec(),
            poll_ms: 1000,
            notify: true,
        }
    }
}
