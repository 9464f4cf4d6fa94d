//! The command line: the subcommands and their arguments (clap).

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// Live checker beside a BTF gonioreflectometer.
#[derive(Parser)]
#[command(name = "goniowatch", version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Decode and average HDR captures (Radiance .hdr or OpenEXR) to one linear RGB and XYZ each.
    Average(AverageArgs),
    /// Run beside the rig: follow the controller on the serial link, check every capture as it
    /// is written, raise alarms, and record the session so it can be resumed and replayed.
    Run(RunArgs),
    /// Replay a recorded session through the same code path into a fresh results folder.
    Replay(ReplayArgs),
    /// Cross-validate a session against an independent reference measurement of the same sample
    /// (docs/reference-format.md): resample the reference at the session's capture directions,
    /// fit the 3×3 colour transform, and print the paper's Table 3 and the worst directions,
    /// also with the session's gain drift divided out. Writes SESSION/crossval.json.
    Compare(CompareArgs),
    /// Write the end-of-run report: one self-contained HTML file with its plots (hemisphere
    /// maps of the reciprocity residual, the gain drift with its band and the alarms, the
    /// residual distribution, Tables 2 and 3, quality, link, configuration) and the tables as CSV.
    Report(ReportArgs),
    /// Print the sampling plan: directions, captures, reciprocal pairs, isotropy classes and the
    /// entries the rig must take at a substitute pose.
    Plan(PlanArgs),
    /// Check a finished capture set (a folder of captures whose names or sidecar give the
    /// angles) with the same checks as a live run, on every core, into a session folder that
    /// `report`, `compare` and `replay` read like any other. The folder is only read.
    Check(CheckArgs),
    /// Export a checked session for the lab: the MERL BRDF binary (isotropic samples; with a
    /// JSON sidecar of units, white, corrections, support and the checks' verdict), a table of
    /// every capture raw and drift-corrected with its BRDF (CSV and JSON lines), or
    /// drift-corrected OpenEXR copies of the captures. Never writes under the capture root.
    Export(ExportArgs),
    /// Print the alarm catalogue: every alarm code with its kind, severities, meaning,
    /// evidence fields and what to do (docs/alarms.md is this table).
    Alarms(AlarmsArgs),
    /// Run a session in lockstep with a simulated rig on standard input and output (the
    /// detection lab's fast path; `python -m goniosim lockstep` drives it): stdin carries the
    /// rig's lines, stdout the daemon's, each turn ended by an empty line.
    #[command(hide = true)]
    Lockstep(LockstepArgs),
}

#[derive(Args)]
pub struct LockstepArgs {
    /// Config file (its [source] must be the protocol).
    #[arg(long)]
    pub config: PathBuf,
    /// A new session folder.
    #[arg(long)]
    pub session: PathBuf,
    /// Where the rig writes its captures.
    #[arg(long)]
    pub capture_root: PathBuf,
}

#[derive(Args)]
pub struct CheckArgs {
    /// The capture folder (only read).
    pub dir: PathBuf,
    /// Config file; its [source] must be absent or kind = "files" (default: the built-in
    /// config/archive.toml: the UBO plan, Bonn-style names).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Session folder for the results (default: DIR.check beside DIR). Rerunning on the same
    /// folder resumes it.
    #[arg(long)]
    pub session: Option<PathBuf>,
    /// Decoding threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub workers: Option<u16>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args)]
pub struct AverageArgs {
    /// Capture files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Config file for colour, region and clip settings (default: built-in UBO defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// One JSON object per file and line.
    #[arg(long)]
    pub json: bool,
    /// Region of interest: full, rect:X,Y,W,H, margin:PIXELS or margin:PERCENT%.
    #[arg(long)]
    pub roi: Option<String>,
}

#[derive(Args)]
pub struct RunArgs {
    /// Config file (required to start a new session; a session folder keeps its own copy).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Session folder (created if absent; resumed if it holds a journal).
    #[arg(long, default_value = "session")]
    pub session: PathBuf,
    /// Serial port, overriding the config's `[link] port`.
    #[arg(long)]
    pub port: Option<PathBuf>,
    /// Capture root, overriding the config's `[ingest] capture_root`.
    #[arg(long)]
    pub capture_root: Option<PathBuf>,
    /// Stay attached after the controller reports the run done.
    #[arg(long)]
    pub keep_running: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Serve a live status page (and /status.json, /metrics) at this address, e.g.
    /// 127.0.0.1:8080. Loopback only unless the config's [http] allow_remote is set.
    #[arg(long)]
    pub http: Option<std::net::SocketAddr>,
}

#[derive(Args)]
pub struct ReplayArgs {
    /// The session folder to replay (only read).
    pub session: PathBuf,
    /// Where to write the results (default: SESSION/replay).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// max, realtime, or a factor of real time (e.g. 60).
    #[arg(long, default_value = "max")]
    pub speed: crate::daemon::replay::Speed,
    /// Decoding threads (1–64).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub workers: u16,
    /// Read the captures from here instead of the session's recorded capture root (a
    /// capture set that moved).
    #[arg(long)]
    pub capture_root: Option<PathBuf>,
    /// Take capture outcomes as journaled instead of measuring the files again (the
    /// captures need not exist; checks only the journal's path through the engine).
    #[arg(long)]
    pub recorded_outcomes: bool,
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args)]
pub struct CompareArgs {
    /// The session folder (read; crossval.json is written into it).
    pub session: PathBuf,
    /// The reference file.
    pub reference: PathBuf,
    #[arg(long)]
    pub json: bool,
    /// How many of the largest deviations to list.
    #[arg(long, default_value_t = 10)]
    pub worst: usize,
    /// Correct for this gain drift (%/h) instead of the session's own estimate.
    #[arg(long, allow_hyphen_values = true)]
    pub drift_rate: Option<f64>,
    /// No gain correction.
    #[arg(long, conflicts_with = "drift_rate")]
    pub no_gain_correction: bool,
    /// Leave out directions where the resampled reference's relative uncertainty exceeds
    /// this (gaps in the reference's grid), in percent.
    #[arg(long, default_value_t = 5.0)]
    pub max_reference_spread_pct: f64,
}

#[derive(Args)]
pub struct ReportArgs {
    /// The session folder (or a replay's output folder).
    pub session: PathBuf,
    /// Where to write (default: SESSION/report).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Args)]
pub struct PlanArgs {
    /// Config file (default: built-in UBO defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
    /// The scatter of one probe against its original capture, % SD (measure it: the probes'
    /// `residual_scale` in a session's summary.json, × 100). Default: the config's
    /// `[probes] design_scatter_pct`.
    #[arg(long)]
    pub probe_scatter_pct: Option<f64>,
    /// Target: a linear gain decay of this size (%/h) ...
    #[arg(long, default_value_t = 1.0)]
    pub target_decay_pct_per_h: f64,
    /// ... flagged before this fraction of the run.
    #[arg(long, default_value_t = 0.25)]
    pub target_decay_by: f64,
    /// Target: a gain step of this size (%, negative: darker) ...
    #[arg(long, default_value_t = -2.0, allow_hyphen_values = true)]
    pub target_step_pct: f64,
    /// ... flagged within this many captures.
    #[arg(long, default_value_t = 300)]
    pub target_step_within: u64,
    /// Target: fault-free runs with a probe alarm, at most this share.
    #[arg(long, default_value_t = 0.05)]
    pub target_false_alarms: f64,
    /// The scatter of one probe's ln X/Y and of its ln Z/Y against its original capture, % SD
    /// each (measure it on fault-free sessions: `benches/probe_scatter.py`). Default: the luminance
    /// scatter.
    #[arg(long)]
    pub colour_scatter_pct: Option<f64>,
    /// Target: a drift of the lamp's colour temperature of this size (K/h; 0: no colour
    /// target) ...
    #[arg(long, default_value_t = -20.0, allow_hyphen_values = true)]
    pub target_colour_k_per_h: f64,
    /// ... flagged before this fraction of the run.
    #[arg(long, default_value_t = 0.15)]
    pub target_colour_by: f64,
}

#[derive(Args)]
pub struct ExportArgs {
    /// The session folder (or a replay's output folder).
    pub session: PathBuf,
    /// merl, table or corrected-images.
    #[arg(long, value_enum)]
    pub format: crate::cli::export::ExportFormat,
    /// merl: the file (default SESSION/export/brdf.binary; its sidecar is FILE.json).
    /// table: the CSV (default SESSION/export/captures-table.csv; the JSON lines beside it
    /// as .jsonl). corrected-images: the folder (required; outside the capture root).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// merl: also write each cell's interpolation σ in the same layout to this file.
    #[arg(long)]
    pub sigma: Option<PathBuf>,
    /// merl: nodes in each nodal fit of the modified Shepard interpolant (Renka's NC; 10–40).
    /// More nodes average the captures' noise over a wider neighbourhood and keep the fits
    /// from swinging into gaps (the retro-reflection hole); fewer follow a narrow lobe closer.
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u16).range(10..=40))]
    pub fit_nodes: u16,
    /// merl: nodes within each node's radius of influence (Renka's NW; 1–40).
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u16).range(1..=40))]
    pub weight_nodes: u16,
    /// merl: what is interpolated across the θi layers: brdf (the BRDF itself; closest on
    /// matte samples) or cosine-weighted (the BRDF × cos θi × cos θo: several times closer to a
    /// glossy lobe at θi ≥ 45°). BENCHMARKS.md gives the error of each.
    #[arg(long, value_enum, default_value = "brdf")]
    pub across_layers: crate::cli::export::LayerInterpolation,
    /// Export the values as measured, without dividing the session's drift estimate out.
    #[arg(long)]
    pub no_drift_correction: bool,
    /// corrected-images: read the captures from here instead of the session's recorded
    /// capture root.
    #[arg(long)]
    pub capture_root: Option<PathBuf>,
    /// Threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub threads: Option<u16>,
}

#[derive(Args)]
pub struct AlarmsArgs {
    /// One JSON object per code instead of the Markdown table.
    #[arg(long)]
    pub json: bool,
}
