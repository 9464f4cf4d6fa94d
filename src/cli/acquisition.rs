//! The commands that run a session: `run` (beside a rig, or watching a folder), `check` (a
//! finished capture set), `replay` and the lab's `lockstep`.

use super::args::{CheckArgs, LockstepArgs, ReplayArgs, RunArgs};
use super::exit::{self, UsageError};
use crate::cli::summary::print_summary;
use crate::daemon::run::{RunEnd, RunOptions};
use crate::session::folder::{inside_capture_folder, normal_absolute};
use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

pub(super) fn run_command(args: RunArgs, out: &mut impl Write) -> Result<ExitCode> {
    let RunArgs {
        config,
        session,
        port,
        capture_root,
        keep_running,
        quiet,
        http,
    } = args;
    run_session(
        RunOptions {
            session_dir: session,
            config,
            config_text: None,
            port,
            capture_root,
            keep_running,
            progress: !quiet,
            http,
            finished_set: false,
            workers: None,
        },
        None,
        out,
    )
}

/// Run a session on its own runtime, print its summary (and `files`, a files source's listing)
/// and give its exit status. A session whose captures are a files source's (`check`, watch
/// mode) is judged for an empty or meaningless result.
fn run_session(opts: RunOptions, files: Option<String>, out: &mut impl Write) -> Result<ExitCode> {
    let session = opts.session_dir.clone();
    let checked_set = opts.finished_set;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let (end, summary) = rt.block_on(crate::daemon::run::run(opts))?;
    rt.shutdown_timeout(std::time::Duration::from_secs(1));
    print_summary(&summary, out)?;
    if let Some(files) = files {
        writeln!(out, "files: {files}")?;
    }
    writeln!(out, "results in {}", session.display())?;
    // a finished set (`check`) and watch mode (a files source) are judged alike
    let from_files =
        checked_set || summary.rig.as_deref() == Some(crate::archive::controller::RIG_ID);
    if let (true, RunEnd::Finished { .. }, Some(why)) =
        (from_files, end, crate::cli::summary::meaningless(&summary))
    {
        eprintln!("goniowatch: {why}");
        return Ok(ExitCode::from(exit::EXIT_MEANINGLESS));
    }
    Ok(match end {
        RunEnd::Finished { critical: false } => ExitCode::SUCCESS,
        RunEnd::Finished { critical: true } => ExitCode::from(exit::EXIT_CRITICAL),
        RunEnd::Signal(n) => ExitCode::from(128 + n as u8),
    })
}

pub(super) fn replay_command(args: ReplayArgs, out: &mut impl Write) -> Result<ExitCode> {
    let ReplayArgs {
        session,
        out: out_dir,
        speed,
        workers,
        capture_root,
        recorded_outcomes,
        quiet,
    } = args;
    use crate::daemon::replay::{replay, ReplayOptions};
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
        return Ok(ExitCode::from(exit::EXIT_REPLAY_MISMATCH));
    }

    Ok(ExitCode::SUCCESS)
}

/// The built-in config of `check` without --config.
const ARCHIVE_CONFIG: &str = include_str!("../../config/archive.toml");

pub(super) fn check_command(args: CheckArgs, out: &mut impl Write) -> Result<ExitCode> {
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
    if inside_capture_folder(&session, &dir) {
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
        .map_err(|e| crate::config::ConfigError::Parse(format!("{e}")))
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
    let cfg = crate::config::Config::from_toml_str(&text)
        .with_context(|| format!("invalid config {}", source.display()))?;
    let listing = crate::daemon::archive::preflight(&dir_abs, &cfg)?;
    if listing.captures.is_empty() {
        return Err(UsageError(format!(
            "no capture in {} could be placed on the plan ({} file(s) looked at)\n{}",
            dir.display(),
            listing.skipped.len(),
            crate::daemon::archive::describe(&listing, 10)
        ))
        .into());
    }
    // no scale in the config: the white from the data (the factor a resumed check was made
    // with, or taken now from the folder's captures), written into the session's config
    let text = match cfg.colour.rgb_scale {
        Some(_) => text,
        None => match crate::daemon::scale::stored(&session, &text) {
            Some(scale) => crate::daemon::scale::with_scale(&text, scale)?,
            None => match crate::daemon::scale::from_captures(&dir_abs, &listing.captures, &cfg) {
                Some(found) => {
                    eprintln!("{}", found.describe());
                    crate::daemon::scale::with_scale(&text, found.rgb_scale)?
                }
                None => {
                    eprintln!(
                        "goniowatch: [colour] rgb_scale is not set and fewer than {} captures decode to a positive luminance: the files' values are taken as they are (rgb_scale = 1)",
                        crate::measure::stats::WHITE_MIN_CAPTURES
                    );
                    text
                }
            },
        },
    };
    if let Some(why) = crate::session::recovery::other_source(&session, &dir_abs, &text)? {
        anyhow::bail!(why);
    }
    let placed: Vec<String> = listing.captures.iter().map(|c| c.file.clone()).collect();
    if let Some(why) = crate::session::recovery::finished_check_outdated(&session, &placed)? {
        anyhow::bail!(why);
    }
    let workers = workers.map(usize::from).unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(2)
    });
    let files = listing.describe();
    run_session(
        RunOptions {
            session_dir: session,
            config: None,
            config_text: Some((text, source)),
            port: None,
            capture_root: Some(dir_abs),
            keep_running: false,
            progress: !quiet,
            http: None,
            finished_set: true,
            workers: Some(workers),
        },
        Some(files),
        out,
    )
}

pub(super) fn lockstep_command(args: LockstepArgs, out: &mut impl Write) -> Result<ExitCode> {
    let (_, critical) = crate::daemon::lockstep::lockstep(
        &crate::daemon::lockstep::LockstepOptions {
            session_dir: args.session,
            config: args.config,
            capture_root: args.capture_root,
        },
        std::io::stdin().lock(),
        out,
    )?;
    Ok(if critical {
        ExitCode::from(exit::EXIT_CRITICAL)
    } else {
        ExitCode::SUCCESS
    })
}
