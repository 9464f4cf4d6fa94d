//! The `goniowatch` binary: argument parsing, logging and printing. The work is in the library.

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use goniowatch::cli::commands::{
    average_file, plan_summary, AverageOutcome, ProbePlanSummary, ProbeScatter,
};
use goniowatch::config::Config;
use goniowatch::measure::averaging::Roi;
use goniowatch::measure::probe_plan::{CadenceFigures, DetectionTarget, ProbePlan};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Live checker beside a BTF gonioreflectometer.
#[derive(Parser)]
#[command(name = "goniowatch", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
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
    /// Run a session in lockstep with a simulated rig on standard input and output (the
    /// detection lab's fast path; `python -m goniosim lockstep` drives it): stdin carries the
    /// rig's lines, stdout the daemon's, each turn ended by an empty line.
    #[command(hide = true)]
    Lockstep(LockstepArgs),
}

#[derive(Args)]
struct LockstepArgs {
    /// Config file (its [source] must be the protocol).
    #[arg(long)]
    config: PathBuf,
    /// A new session folder.
    #[arg(long)]
    session: PathBuf,
    /// Where the rig writes its captures.
    #[arg(long)]
    capture_root: PathBuf,
}

#[derive(Args)]
struct CheckArgs {
    /// The capture folder (only read).
    dir: PathBuf,
    /// Config file; its [source] must be absent or kind = "files" (default: the built-in
    /// config/archive.toml: the UBO plan, Bonn-style names).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Session folder for the results (default: DIR.check beside DIR). Rerunning on the same
    /// folder resumes it.
    #[arg(long)]
    session: Option<PathBuf>,
    /// Decoding threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=64))]
    workers: Option<u16>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct AverageArgs {
    /// Capture files.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Config file for colour, region and clip settings (default: built-in UBO defaults).
    #[arg(long)]
    config: Option<PathBuf>,
    /// One JSON object per file and line.
    #[arg(long)]
    json: bool,
    /// Region of interest: full, rect:X,Y,W,H, margin:PIXELS or margin:PERCENT%.
    #[arg(long)]
    roi: Option<String>,
}

#[derive(Args)]
struct RunArgs {
    /// Config file (required to start a new session; a session folder keeps its own copy).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Session folder (created if absent; resumed if it holds a journal).
    #[arg(long, default_value = "session")]
    session: PathBuf,
    /// Serial port, overriding the config's `[link] port`.
    #[arg(long)]
    port: Option<PathBuf>,
    /// Capture root, overriding the config's `[ingest] capture_root`.
    #[arg(long)]
    capture_root: Option<PathBuf>,
    /// Stay attached after the controller reports the run done.
    #[arg(long)]
    keep_running: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Serve a live status page (and /status.json, /metrics) at this address, e.g.
    /// 127.0.0.1:8080. Loopback only unless the config's [http] allow_remote is set.
    #[arg(long)]
    http: Option<std::net::SocketAddr>,
}

#[derive(Args)]
struct ReplayArgs {
    /// The session folder to replay (only read).
    session: PathBuf,
    /// Where to write the results (default: SESSION/replay).
    #[arg(long)]
    out: Option<PathBuf>,
    /// max, realtime, or a factor of real time (e.g. 60).
    #[arg(long, default_value = "max")]
    speed: goniowatch::daemon::replay::Speed,
    /// Decoding threads (1–64).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    workers: u16,
    /// Read the captures from here instead of the session's recorded capture root (a
    /// capture set that moved).
    #[arg(long)]
    capture_root: Option<PathBuf>,
    /// Take capture outcomes as journaled instead of measuring the files again (the
    /// captures need not exist; checks only the journal's path through the engine).
    #[arg(long)]
    recorded_outcomes: bool,
    #[arg(long)]
    quiet: bool,
}

#[derive(Args)]
struct CompareArgs {
    /// The session folder (read; crossval.json is written into it).
    session: PathBuf,
    /// The reference file.
    reference: PathBuf,
    #[arg(long)]
    json: bool,
    /// How many of the largest deviations to list.
    #[arg(long, default_value_t = 10)]
    worst: usize,
    /// Correct for this gain drift (%/h) instead of the session's own estimate.
    #[arg(long, allow_hyphen_values = true)]
    drift_rate: Option<f64>,
    /// No gain correction.
    #[arg(long, conflicts_with = "drift_rate")]
    no_gain_correction: bool,
    /// Leave out directions where the resampled reference's relative uncertainty exceeds
    /// this (gaps in the reference's grid), in percent.
    #[arg(long, default_value_t = 5.0)]
    max_reference_spread_pct: f64,
}

#[derive(Args)]
struct ReportArgs {
    /// The session folder (or a replay's output folder).
    session: PathBuf,
    /// Where to write (default: SESSION/report).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct PlanArgs {
    /// Config file (default: built-in UBO defaults).
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long)]
    json: bool,
    /// The scatter of one probe against its original capture, % SD (measure it: the probes'
    /// `residual_scale` in a session's summary.json, × 100). Default: the config's
    /// `[probes] design_scatter_pct`.
    #[arg(long)]
    probe_scatter_pct: Option<f64>,
    /// Target: a linear gain decay of this size (%/h) ...
    #[arg(long, default_value_t = 1.0)]
    target_decay_pct_per_h: f64,
    /// ... flagged before this fraction of the run.
    #[arg(long, default_value_t = 0.25)]
    target_decay_by: f64,
    /// Target: a gain step of this size (%, negative: darker) ...
    #[arg(long, default_value_t = -2.0, allow_hyphen_values = true)]
    target_step_pct: f64,
    /// ... flagged within this many captures.
    #[arg(long, default_value_t = 300)]
    target_step_within: u64,
    /// Target: fault-free runs with a probe alarm, at most this share.
    #[arg(long, default_value_t = 0.05)]
    target_false_alarms: f64,
    /// The scatter of one probe's ln X/Y and of its ln Z/Y against its original capture, % SD
    /// each (measure it on fault-free sessions: `benches/probe_scatter.py`). Default: the luminance
    /// scatter.
    #[arg(long)]
    colour_scatter_pct: Option<f64>,
    /// Target: a drift of the lamp's colour temperature of this size (K/h; 0: no colour
    /// target) ...
    #[arg(long, default_value_t = -20.0, allow_hyphen_values = true)]
    target_colour_k_per_h: f64,
    /// ... flagged before this fraction of the run.
    #[arg(long, default_value_t = 0.15)]
    target_colour_by: f64,
}

/// Exit codes (documented in README.md).
const EXIT_FILE_FAILED: u8 = 1;
const EXIT_CRITICAL: u8 = 4;
const EXIT_REPLAY_MISMATCH: u8 = 5;
/// `check` and watch mode: the result is empty or meaningless (`cli::summary::meaningless`).
const EXIT_MEANINGLESS: u8 = 6;

/// A mistake in how the command was called (exit status 2).
#[derive(Debug)]
struct UsageError(String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

fn load_config(path: Option<&Path>) -> Result<Config> {
    match path {
        None => Ok(Config::default()),
        Some(p) => Ok(Config::load(p)
            .with_context(|| format!("invalid config {}", p.display()))?
            .0),
    }
}

fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("GONIOWATCH_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
    // Route panics to the log. A decoder panic is also caught and reported as a typed error.
    std::panic::set_hook(Box::new(|info| {
        tracing::error!(target: "goniowatch::panic", "panic: {info}");
    }));
}

fn main() -> ExitCode {
    init_logging();
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            // usage, configuration, a files source's sidecar and pattern, and malformed input
            // files named on the command line are 2;
            // anything else at run time is 3
            let usage = e.chain().any(|c| {
                c.downcast_ref::<goniowatch::config::ConfigError>()
                    .is_some()
                    || c.downcast_ref::<goniowatch::reference::ReferenceError>()
                        .is_some()
                    || c.downcast_ref::<UsageError>().is_some()
                    || c.downcast_ref::<goniowatch::measure::probe_plan::ProbePlanError>()
                        .is_some()
                    // a sidecar table that does not parse, or a pattern and order that cannot
                    // place anything: the configuration's input, as a config error is
                    || c.downcast_ref::<goniowatch::archive::listing::ListingError>()
                        .is_some()
            });
            ExitCode::from(if usage { 2 } else { 3 })
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match cli.command {
        Command::Average(a) => average_command(a, &mut out),
        Command::Run(a) => run_command(a, &mut out),
        Command::Replay(a) => replay_command(a, &mut out),
        Command::Compare(a) => compare_command(a, &mut out),
        Command::Report(a) => report_command(a, &mut out),
        Command::Plan(a) => plan_command(a, &mut out),
        Command::Check(a) => check_command(a, &mut out),
        Command::Lockstep(a) => {
            let (_, critical) = goniowatch::daemon::lockstep::lockstep(
                &goniowatch::daemon::lockstep::LockstepOptions {
                    session_dir: a.session,
                    config: a.config,
                    capture_root: a.capture_root,
                },
                std::io::stdin().lock(),
                &mut out,
            )?;
            Ok(if critical {
                ExitCode::from(EXIT_CRITICAL)
            } else {
                ExitCode::SUCCESS
            })
        }
    }
}

fn average_command(args: AverageArgs, out: &mut impl Write) -> Result<ExitCode> {
    let AverageArgs {
        files,
        config,
        json,
        roi,
    } = args;
    let cfg = load_config(config.as_deref())?;
    let mut opts = cfg.capture;
    if let Some(r) = roi {
        opts.roi = Roi::parse(&r).map_err(|e| UsageError(format!("--roi: {e}")))?;
    }
    let mut failed = 0usize;
    for f in &files {
        let rec = average_file(f, &cfg, &opts);
        if json {
            writeln!(out, "{}", serde_json::to_string(&rec)?)?;
        } else {
            match &rec.outcome {
                AverageOutcome::Ok(ok) => writeln!(
                    out,
                    "{}: {}×{} {:?}  mean RGB [{:.6e} {:.6e} {:.6e}]  XYZ [{:.4} {:.4} {:.4}]  pixels {}  non-finite {}  negative {}  clipped {}",
                    rec.file, ok.width, ok.height, ok.format, ok.mean_rgb[0], ok.mean_rgb[1], ok.mean_rgb[2],
                    ok.xyz[0], ok.xyz[1], ok.xyz[2], ok.pixels, ok.nonfinite, ok.negative, ok.clipped
                )?,
                AverageOutcome::Err { error } => writeln!(out, "{}: ERROR {error}", rec.file)?,
            }
        }
        if matches!(rec.outcome, AverageOutcome::Err { .. }) {
            tracing::warn!(file = %rec.file, "capture failed");
            failed += 1;
        }
    }
    if failed > 0 {
        eprintln!("{failed} of {} files failed", files.len());
        return Ok(ExitCode::from(EXIT_FILE_FAILED));
    }

    Ok(ExitCode::SUCCESS)
}

fn run_command(args: RunArgs, out: &mut impl Write) -> Result<ExitCode> {
    let RunArgs {
        config,
        session,
        port,
        capture_root,
        keep_running,
        quiet,
        http,
    } = args;
    use goniowatch::cli::summary::print_summary;
    use goniowatch::daemon::run::{run, RunEnd, RunOptions};
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let (end, summary) = rt.block_on(run(RunOptions {
        session_dir: session.clone(),
        config,
        config_text: None,
        port,
        capture_root,
        keep_running,
        progress: !quiet,
        http,
        finished_set: false,
        workers: None,
    }))?;
    rt.shutdown_timeout(std::time::Duration::from_secs(1));
    print_summary(&summary, out)?;
    writeln!(out, "results in {}", session.display())?;
    // watch mode (a files source) judges its result as `check` does
    let watched = summary.rig.as_deref() == Some(goniowatch::archive::controller::RIG_ID);
    if let (true, RunEnd::Finished { .. }, Some(why)) = (
        watched,
        end,
        goniowatch::cli::summary::meaningless(&summary),
    ) {
        eprintln!("goniowatch: {why}");
        return Ok(ExitCode::from(EXIT_MEANINGLESS));
    }
    Ok(match end {
        RunEnd::Finished { critical: false } => ExitCode::SUCCESS,
        RunEnd::Finished { critical: true } => ExitCode::from(EXIT_CRITICAL),
        RunEnd::Signal(n) => ExitCode::from(128 + n as u8),
    })
}

fn replay_command(args: ReplayArgs, out: &mut impl Write) -> Result<ExitCode> {
    let ReplayArgs {
        session,
        out: out_dir,
        speed,
        workers,
        capture_root,
        recorded_outcomes,
        quiet,
    } = args;
    use goniowatch::cli::summary::print_summary;
    use goniowatch::daemon::replay::{replay, ReplayOptions};
    let r = replay(
        &session,
        &ReplayOptions {
            out: out_dir,
            speed,
            workers: workers as usize,
            progress: !quiet,
            capture_root,
            recorded_outcomes,
        },
    )?;
    print_summary(&r.summary, out)?;
    writeln!(
        out,
        "replayed {} inputs, {} captures decoded in {:.2} s ({:.1} captures/s)",
        r.inputs,
        r.captures_decoded,
        r.seconds,
        r.captures_decoded as f64 / r.seconds.max(1e-9)
    )?;
    for m in &r.mismatches {
        writeln!(out, "MISMATCH: {m}")?;
    }
    if !r.mismatches.is_empty() {
        return Ok(ExitCode::from(EXIT_REPLAY_MISMATCH));
    }

    Ok(ExitCode::SUCCESS)
}

fn compare_command(args: CompareArgs, out: &mut impl Write) -> Result<ExitCode> {
    let CompareArgs {
        session,
        reference,
        json,
        worst,
        drift_rate,
        no_gain_correction,
        max_reference_spread_pct,
    } = args;
    if !(max_reference_spread_pct > 0.0 && max_reference_spread_pct.is_finite()) {
        return Err(UsageError(format!(
            "--max-reference-spread-pct {max_reference_spread_pct} must be a positive number"
        ))
        .into());
    }
    use goniowatch::cli::compare::{compare, render, GainChoice};
    if let Some(r) = drift_rate {
        if !r.is_finite() {
            return Err(UsageError(format!("--drift-rate {r} is not a finite number")).into());
        }
    }
    let gain = match (drift_rate, no_gain_correction) {
        (Some(r), _) => GainChoice::Rate(r),
        (None, true) => GainChoice::None,
        (None, false) => GainChoice::Session,
    };
    let report = compare(
        &session,
        &reference,
        gain,
        worst,
        max_reference_spread_pct / 100.0,
    )?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        write!(out, "{}", render(&report))?;
    }

    Ok(ExitCode::SUCCESS)
}

fn report_command(args: ReportArgs, out: &mut impl Write) -> Result<ExitCode> {
    let ReportArgs {
        session,
        out: out_dir,
    } = args;
    let files = goniowatch::cli::report::report(&session, out_dir.as_deref())?;
    for f in &files {
        writeln!(out, "{}", f.display())?;
    }

    Ok(ExitCode::SUCCESS)
}

fn plan_command(args: PlanArgs, out: &mut impl Write) -> Result<ExitCode> {
    let PlanArgs {
        config,
        json,
        probe_scatter_pct,
        target_decay_pct_per_h,
        target_decay_by,
        target_step_pct,
        target_step_within,
        target_false_alarms,
        colour_scatter_pct,
        target_colour_k_per_h,
        target_colour_by,
    } = args;
    let cfg = load_config(config.as_deref())?;
    let target = DetectionTarget {
        decay_pct_per_h: target_decay_pct_per_h,
        decay_by_fraction: target_decay_by,
        step_pct: target_step_pct,
        step_within_captures: target_step_within,
        false_alarms_per_run: target_false_alarms,
        colour_k_per_h: target_colour_k_per_h,
        colour_by_fraction: target_colour_by,
        ..DetectionTarget::default()
    };
    let luminance_pct = probe_scatter_pct.unwrap_or(cfg.probes.design_scatter_pct);
    let s = plan_summary(
        &cfg,
        ProbeScatter {
            luminance_pct,
            chromaticity_pct: colour_scatter_pct.unwrap_or(luminance_pct),
        },
        &target,
    )?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&s)?)?;
    } else {
        writeln!(out, "Sampling plan ({:?} order)", s.order)?;
        writeln!(out, "  θ [deg]   Δφ [deg]   directions")?;
        for (t, d, n) in &s.table1 {
            writeln!(
                out,
                "  {t:>7}   {:>8}   {n:>10}",
                if *t == 0.0 {
                    "-".to_string()
                } else {
                    d.to_string()
                }
            )?;
        }
        writeln!(out, "directions             {}", s.directions)?;
        writeln!(out, "captures               {}", s.captures)?;
        writeln!(
            out,
            "reciprocal pairs       {} (+ {} self pairs)",
            s.reciprocal_pairs, s.self_pairs
        )?;
        writeln!(out, "isotropy classes       {}", s.isotropy_classes)?;
        writeln!(
            out,
            "occlusion substitutes  {} (lamp–camera separation < {}°, θi changed)",
            s.occlusion_substitutes, s.min_separation_deg
        )?;
        if !s.unreachable.is_empty() {
            writeln!(out, "UNREACHABLE entries    {}", s.unreachable.len())?;
        }
        writeln!(
            out,
            "\nDrift from reciprocal pairs alone (no probes, no isotropy classes), 7 s per capture:\nstandard errors per 1 % of pair noise, the {} free per-direction non-reciprocities fitted",
            s.directions.saturating_sub(1)
        )?;
        writeln!(
            out,
            "  order                    rate [%/h]   step at 10 / 25 / 50 / 75 / 90 % of the run [%]"
        )?;
        let cell = |v: Option<f64>| v.map_or("  –   ".to_string(), |x| format!("{x:6.3}"));
        for o in &s.drift_from_pairs {
            let steps: Vec<String> = o.pairs.step_se_pct.iter().map(|(_, v)| cell(*v)).collect();
            writeln!(
                out,
                "  {:<24} {:>10}   {}{}",
                o.order,
                o.pairs
                    .rate_se_pct_per_h
                    .map_or("not seen".to_string(), |x| format!("{x:.4}")),
                steps.join(" "),
                if o.configurable {
                    ""
                } else {
                    "  (not a config order)"
                }
            )?;
        }
        print_probe_plan(&s.probes, &cfg.probes, out)?;
    }

    Ok(ExitCode::SUCCESS)
}

/// `plan`'s drift-probe section: the target, every cadence tried, and the recommendation or why
/// there is none.
fn print_probe_plan(
    p: &ProbePlanSummary,
    spec: &goniowatch::measure::probes::ProbeSpec,
    out: &mut impl Write,
) -> Result<()> {
    let t = &p.target;
    let pose = match spec.entry {
        Some(e) => format!("plan entry {e}"),
        None => format!(
            "a pose the daemon chooses after {} captures, plan entry {} standing in",
            p.session.probes_from, p.session.anchor
        ),
    };
    writeln!(
        out,
        "\nDrift probes: a re-capture every N captures of {pose}; {} s {}; probe scatter {} %{}",
        p.session.seconds_per_probe,
        if p.sentinel {
            "per round (the lamp probe, then a joint-3 sentinel: the sample is anisotropic)"
        } else {
            "each"
        },
        p.session.scatter_pct,
        p.session.colour.as_ref().map_or(String::new(), |c| format!(
            ", chromaticity scatter {} % (ln X/Y, ln Z/Y; a {} K lamp)",
            c.scatter_pct, c.lamp_cct_k
        ))
    )?;
    let colour_target = match &p.session.colour {
        Some(c) if t.colour_k_per_h != 0.0 => format!(
            ", a {:+} K/h colour drift before {:.0} % of the run (colour-drift: tolerance {} K/h, z = {})",
            t.colour_k_per_h,
            100.0 * t.colour_by_fraction,
            c.tolerance_k_per_h,
            c.z
        ),
        _ => String::new(),
    };
    writeln!(
        out,
        "target: a {} %/h decay flagged before {:.0} % of the run and a {:+} % step within {} captures{colour_target}, each in {:.0} % of runs; at most {:.0} false alarms in 100 runs ({} simulated runs per cadence through the daemon's probe detector: z = {}, step_sigmas = {}, step_pct = {})",
        t.decay_pct_per_h,
        100.0 * t.decay_by_fraction,
        t.step_pct,
        t.step_within_captures,
        100.0 * t.power,
        100.0 * t.false_alarms_per_run,
        goniowatch::measure::probe_plan::RUNS,
        spec.z,
        spec.step_sigmas,
        spec.step_pct
    )?;
    writeln!(
        out,
        "  every   probes   run time +   false alarms/run   decay in time (median at)   step in time (median delay)   colour in time (median at)"
    )?;
    let row = |c: &CadenceFigures| {
        let colour = c
            .colour_in_time
            .map_or("     –              ".to_string(), |x| {
                format!(
                    "{:>5.0} % ({:>5})",
                    100.0 * x,
                    c.colour_median_fraction
                        .map_or("–".to_string(), |f| format!("{:.0} %", 100.0 * f))
                )
            });
        format!(
            "  {:>5}   {:>6}   {:>4.2} h {:>4.1} %   {:>16.3}   {:>5.0} % ({:>5})            {:>5.0} % ({:>5})              {colour}           {}",
            c.every,
            c.probes_per_run,
            c.overhead_h,
            c.overhead_pct,
            c.false_alarms_per_run,
            100.0 * c.decay_in_time,
            c.decay_median_fraction
                .map_or("–".to_string(), |f| format!("{:.0} %", 100.0 * f)),
            100.0 * c.step_in_time,
            c.step_median_delay.map_or("–".to_string(), |d| format!("{d:.0}")),
            if c.meets { "meets" } else { "" }
        )
    };
    let tried = match &p.design {
        ProbePlan::Recommended { tried, .. } | ProbePlan::Unreachable { tried, .. } => tried,
    };
    for c in tried {
        writeln!(out, "{}", row(c))?;
    }
    match &p.design {
        ProbePlan::Recommended { cadence, .. } => writeln!(
            out,
            "recommended: [probes] every = {} (adds {:.2} h, {:.1} % of the run)",
            cadence.every, cadence.overhead_h, cadence.overhead_pct
        )?,
        ProbePlan::Unreachable { reason, .. } => {
            writeln!(out, "NO CADENCE MEETS THE TARGET: {reason}")?
        }
    }
    if let Some(c) = &p.configured {
        writeln!(out, "configured:\n{}", row(c))?;
    }
    if p.isotropic_sample {
        writeln!(
            out,
            "(an isotropic sample: its isotropy classes and light sweeps watch the lamp without probes, and the classes its colour, so the probes are designed for the luminance target only)"
        )?;
    } else {
        writeln!(
            out,
            "(an anisotropic sample: without probes nothing watches the lamp's rate or colour)"
        )?;
    }
    Ok(())
}

/// The built-in config of `check` without --config.
const ARCHIVE_CONFIG: &str = include_str!("../config/archive.toml");

/// `path` made absolute, with `.` dropped and `..` taken by the names.
fn normal_absolute(path: &Path) -> Result<PathBuf> {
    let abs = std::path::absolute(path).with_context(|| format!("{}", path.display()))?;
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    Ok(out)
}

fn check_command(args: CheckArgs, out: &mut impl Write) -> Result<ExitCode> {
    let CheckArgs {
        dir,
        config,
        session,
        workers,
        quiet,
    } = args;
    if !dir.is_dir() {
        return Err(UsageError(format!("{} is not a folder of captures", dir.display())).into());
    }
    let dir_abs = normal_absolute(&dir)?;
    let session = match session {
        Some(s) => s,
        None => {
            let name = dir_abs
                .file_name()
                .map(|n| format!("{}.check", n.to_string_lossy()))
                .ok_or_else(|| UsageError("give --session for a capture folder at /".into()))?;
            dir_abs.with_file_name(name)
        }
    };
    let session_abs = normal_absolute(&session)?;
    let real_dir = dir.canonicalize().unwrap_or_else(|_| dir_abs.clone());
    if session_abs.starts_with(&dir_abs)
        || session_abs
            .ancestors()
            .any(|a| a.canonicalize().is_ok_and(|a| a == real_dir))
    {
        return Err(UsageError(format!(
            "the session folder {} is inside the capture folder {}; goniowatch never writes there. Give --session elsewhere",
            session.display(),
            dir.display()
        ))
        .into());
    }
    let (text, source) = match &config {
        Some(p) => (
            std::fs::read_to_string(p)
                .with_context(|| format!("cannot read config {}", p.display()))?,
            p.clone(),
        ),
        None => (
            ARCHIVE_CONFIG.to_string(),
            PathBuf::from("(built-in config/archive.toml)"),
        ),
    };
    let table: toml::Table = text
        .parse()
        .map_err(|e| goniowatch::config::ConfigError::Parse(format!("{e}")))
        .with_context(|| format!("invalid config {}", source.display()))?;
    let text = match table.get("source") {
        None => format!("{text}\n[source]\nkind = \"files\"\n"),
        Some(s) if s.get("kind").and_then(|k| k.as_str()) == Some("files") => text,
        Some(_) => {
            return Err(UsageError(format!(
                "{}: check reads a folder of files; its [source] needs kind = \"files\" (or leave [source] out)",
                source.display()
            ))
            .into())
        }
    };
    // a folder where nothing can be placed is refused before a session folder is made
    let cfg = goniowatch::config::Config::from_toml_str(&text)
        .with_context(|| format!("invalid config {}", source.display()))?;
    let listing = goniowatch::daemon::archive::preflight(&dir_abs, &cfg)?;
    if listing.captures.is_empty() {
        return Err(UsageError(format!(
            "no capture in {} could be placed on the plan ({} file(s) looked at)\n{}",
            dir.display(),
            listing.skipped.len(),
            goniowatch::daemon::archive::describe(&listing, 10)
        ))
        .into());
    }
    if let Some(why) = goniowatch::session::recovery::other_source(&session, &dir_abs, &text)? {
        anyhow::bail!(why);
    }
    let placed: Vec<String> = listing.captures.iter().map(|c| c.file.clone()).collect();
    if let Some(why) = goniowatch::session::recovery::finished_check_outdated(&session, &placed)? {
        anyhow::bail!(why);
    }
    let workers = workers.map(usize::from).unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(2)
    });
    use goniowatch::cli::summary::print_summary;
    use goniowatch::daemon::run::{run, RunEnd, RunOptions};
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let (end, summary) = rt.block_on(run(RunOptions {
        session_dir: session.clone(),
        config: None,
        config_text: Some((text, source)),
        port: None,
        capture_root: Some(dir_abs),
        keep_running: false,
        progress: !quiet,
        http: None,
        finished_set: true,
        workers: Some(workers),
    }))?;
    rt.shutdown_timeout(std::time::Duration::from_secs(1));
    print_summary(&summary, out)?;
    writeln!(out, "files: {}", listing.describe())?;
    writeln!(out, "results in {}", session.display())?;
    if let (RunEnd::Finished { .. }, Some(why)) =
        (end, goniowatch::cli::summary::meaningless(&summary))
    {
        eprintln!("goniowatch: {why}");
        return Ok(ExitCode::from(EXIT_MEANINGLESS));
    }
    Ok(match end {
        RunEnd::Finished { critical: false } => ExitCode::SUCCESS,
        RunEnd::Finished { critical: true } => ExitCode::from(EXIT_CRITICAL),
        RunEnd::Signal(n) => ExitCode::from(128 + n as u8),
    })
}
