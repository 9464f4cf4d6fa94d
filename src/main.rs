//! The `goniowatch` binary: argument parsing, logging and printing. The work is in the library.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use goniowatch::commands::{average_file, plan_summary, AverageOutcome};
use goniowatch::config::Config;
use goniowatch::measure::averaging::Roi;
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
    Average {
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
    },
    /// Print the sampling plan: directions, captures, reciprocal pairs, isotropy classes and the
    /// entries the rig must take at a substitute pose.
    Plan {
        /// Config file (default: built-in UBO defaults).
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
}

/// Exit codes (documented in README.md).
const EXIT_FILE_FAILED: u8 = 1;

fn load_config(path: Option<&Path>) -> Result<Config> {
    match path {
        None => Ok(Config::default()),
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read config {}", p.display()))?;
            Config::from_toml_str(&text).with_context(|| format!("invalid config {}", p.display()))
        }
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
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match cli.command {
        Command::Average {
            files,
            config,
            json,
            roi,
        } => {
            let cfg = load_config(config.as_deref())?;
            let mut opts = cfg.capture;
            if let Some(r) = roi {
                opts.roi = Roi::parse(&r)
                    .map_err(anyhow::Error::msg)
                    .context("--roi")?;
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
        }
        Command::Plan { config, json } => {
            let cfg = load_config(config.as_deref())?;
            let s = plan_summary(&cfg)?;
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
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
