//! Shell: `goniowatch replay`: feed a recorded session's journal through the same engine, and
//! its captures through the same measuring code, into a fresh results folder.
//!
//! Every capture whose outcome was `ok` is read again, checked against the recorded size and
//! SHA-256, decoded and averaged (on a worker pool, ahead of the engine, so a max-speed replay
//! is decode-bound). Failed and missing outcomes are taken as recorded: the file's state at
//! that moment of the live run cannot be recovered. The session folder is only read.

use super::ingest::{measure_file, resolve};
use crate::checks::Outcome;
use crate::decode::DecodeLimits;
use crate::engine::{Input, Summary};
use crate::session::folder::{write_atomic, Results};
use crate::session::recovery::{inputs, verified_journal, Session};
use anyhow::{bail, Context, Result};
use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    Max,
    Factor(f64),
}

impl std::str::FromStr for Speed {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "max" => Ok(Speed::Max),
            "realtime" => Ok(Speed::Factor(1.0)),
            f => f
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v > 0.0)
                .map(Speed::Factor)
                .ok_or_else(|| format!("speed '{s}' is not max, realtime or a positive factor")),
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct ReplayReport {
    pub inputs: usize,
    pub captures_decoded: usize,
    /// Captures whose file changed since the live run, or decoded differently.
    pub mismatches: Vec<String>,
    pub seconds: f64,
    pub summary: Summary,
}

/// How to replay.
#[derive(Debug, Clone)]
pub struct ReplayOptions {
    /// Where the result files go (default: SESSION/replay).
    pub out: Option<PathBuf>,
    pub speed: Speed,
    /// Decoding threads.
    pub workers: usize,
    /// Draw a progress bar (when stderr is a terminal).
    pub progress: bool,
    /// Read the captures from here instead of the session's capture root.
    pub capture_root: Option<PathBuf>,
    /// Take every capture outcome as journaled instead of measuring the file again (the
    /// captures need not exist; the results are then a function of the journal alone).
    pub recorded_outcomes: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        ReplayOptions {
            out: None,
            speed: Speed::Max,
            workers: 2,
            progress: false,
            capture_root: None,
            recorded_outcomes: false,
        }
    }
}

pub fn replay(session_dir: &Path, options: &ReplayOptions) -> Result<ReplayReport> {
    let (out, speed, workers, progress) = (
        options.out.as_deref(),
        options.speed,
        options.workers,
        options.progress,
    );
    let mut session = Session::open_read_only(session_dir)?;
    if let Some(c) = &options.capture_root {
        session.info.capture_root = c.to_path_buf();
    } else if session.info.capture_root.is_relative() && !options.recorded_outcomes {
        tracing::warn!(
            "the session's capture root {} is relative (recorded by an older goniowatch); it is taken from the working directory; give --capture-root if the captures are elsewhere",
            session.info.capture_root.display()
        );
    }
    let out_dir: PathBuf = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| session_dir.join("replay"));
    if out_dir.canonicalize().ok() == session_dir.canonicalize().ok() {
        bail!("--out must not be the session folder itself");
    }
    if let Some(held) = ["journal.jsonl", "session.json"]
        .into_iter()
        .find(|f| out_dir.join(f).exists())
    {
        bail!(
            "--out {} holds a session ({held}); replay writes result files there and will not overwrite another session's. Give an empty or new folder",
            out_dir.display()
        );
    }
    let inside_captures =
        crate::session::folder::inside_capture_folder(&out_dir, &session.info.capture_root);
    if inside_captures {
        bail!(
            "--out {} is inside the capture folder {}; goniowatch never writes there. Give a folder elsewhere",
            out_dir.display(),
            session.info.capture_root.display()
        );
    }
    // verify the journal before anything is written
    let all = journaled_inputs(session_dir, &session)?;
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    // the config beside the results, so that the replayed folder stands on its own (`report`)
    let config_text = std::fs::read(session_dir.join("config.toml"))
        .with_context(|| format!("cannot read {}", session_dir.join("config.toml").display()))?;
    write_atomic(&out_dir.join("config.toml"), &config_text)?;
    let jobs = if options.recorded_outcomes {
        Vec::new()
    } else {
        capture_jobs(&all)
    };

    // measure ahead of the engine on a pool; results keyed by journal position
    let (job_tx, job_rx) = crossbeam_channel::bounded::<(usize, String)>(workers.max(1) * 4);
    let (res_tx, res_rx) = crossbeam_channel::unbounded::<(usize, Result<Outcome, String>)>();
    let root = session.info.capture_root.clone();
    let average_opts = session.config.capture;
    let limits = DecodeLimits {
        threads: 1,
        ..super::ingest::decode_limits(&session.config.ingest)
    };
    let mut handles = Vec::new();
    for _ in 0..workers.max(1) {
        let (rx, tx, root) = (job_rx.clone(), res_tx.clone(), root.clone());
        handles.push(std::thread::spawn(move || {
            while let Ok((n, file)) = rx.recv() {
                let r = resolve(&root, &file)
                    .map_err(|e| e.to_string())
                    .and_then(|p| {
                        measure_file(&root, &p, &average_opts, &limits).map_err(|e| e.reason)
                    });
                if tx.send((n, r)).is_err() {
                    return;
                }
            }
        }));
    }
    drop(res_tx);
    let feeder = std::thread::spawn(move || {
        for j in jobs {
            if job_tx.send(j).is_err() {
                return;
            }
        }
    });

    let bar = if progress && std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new(all.len() as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template("replay [{elapsed_precise}] {bar:30} {pos}/{len} inputs  {per_sec}  ETA {eta}  {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };

    let mut engine = crate::engine::Engine::from_config(&session.config)?;
    let mut results = Results::open(&out_dir, true)?;
    let mut report = ReplayReport::default();
    let mut ready: HashMap<usize, Result<Outcome, String>> = HashMap::new();
    let started = Instant::now();
    let first_wall = all.first().map(|(w, _)| *w).unwrap_or(0);
    for (n, (wall, input)) in all.iter().enumerate() {
        if let Speed::Factor(f) = speed {
            let due = Duration::from_secs_f64(wall.saturating_sub(first_wall) as f64 / 1000.0 / f);
            if let Some(wait) = due.checked_sub(started.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        let fed = match input {
            Input::Outcome {
                idx,
                outcome: recorded @ Outcome::Ok { .. },
            } if !options.recorded_outcomes => {
                let got = loop {
                    if let Some(r) = ready.remove(&n) {
                        break Some(r);
                    }
                    match res_rx.recv() {
                        Ok((k, r)) => {
                            ready.insert(k, r);
                        }
                        Err(_) => break None,
                    }
                };
                report.captures_decoded += 1;
                match got {
                    Some(Ok(o)) if &o == recorded => input.clone(),
                    Some(Ok(o)) => {
                        report.mismatches.push(format!("capture {idx}: the file now measures differently from the live run (recorded {}, now {})", serde_json::to_string(recorded).unwrap_or_default(), serde_json::to_string(&o).unwrap_or_default()));
                        Input::Outcome {
                            idx: *idx,
                            outcome: o,
                        }
                    }
                    Some(Err(e)) => {
                        report.mismatches.push(format!("capture {idx}: {e}"));
                        Input::Outcome {
                            idx: *idx,
                            outcome: Outcome::Failed { error: e },
                        }
                    }
                    None => input.clone(),
                }
            }
            other => other.clone(),
        };
        for o in engine.handle(&fed) {
            results.record(&o)?;
        }
        report.inputs += 1;
        if let Some(b) = &bar {
            b.set_position(n as u64 + 1);
            if n % 256 == 0 {
                b.set_message(format!(
                    "checked {}  alarms {}",
                    engine.checked_through(),
                    engine.alarm_count()
                ));
            }
        }
    }
    let _ = feeder.join();
    for h in handles {
        let _ = h.join();
    }
    results.sync()?;
    report.summary = engine.summary();
    results.write_summary(&report.summary)?;
    report.seconds = started.elapsed().as_secs_f64();
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    Ok(report)
}

/// The journal's inputs (with their wall times), verified; refused when there are none.
fn journaled_inputs(session_dir: &Path, session: &Session) -> Result<Vec<(u64, Input)>> {
    let journal_path = session_dir.join("journal.jsonl");
    let read = verified_journal(&journal_path, session.info.journal_checksums)?;
    if read.torn_tail {
        tracing::warn!(
            "{} ends in a torn line (a write cut short); it is left out",
            journal_path.display()
        );
    }
    let all: Vec<(u64, Input)> = inputs(&read.entries).map(|(w, i)| (w, i.clone())).collect();
    if all.is_empty() {
        bail!(
            "{} has no journaled inputs ({} is {}): there is nothing to replay",
            session_dir.display(),
            journal_path.display(),
            if journal_path.exists() {
                "empty"
            } else {
                "missing"
            }
        );
    }
    Ok(all)
}

/// The captures to measure again, in journal order: (journal position, file) of every `ok`
/// outcome whose file an announcement named.
fn capture_jobs(all: &[(u64, Input)]) -> Vec<(usize, String)> {
    let mut files: HashMap<u64, String> = HashMap::new();
    for (_, i) in all {
        if let Input::Rx { line } = i {
            if let Ok(crate::protocol::Line {
                message: crate::protocol::FromController::Capture(a),
                ..
            }) = crate::protocol::parse_message(line)
            {
                files.entry(a.idx).or_insert(a.file);
            }
        }
    }
    all.iter()
        .enumerate()
        .filter_map(|(n, (_, i))| match i {
            Input::Outcome {
                idx,
                outcome: Outcome::Ok { .. },
            } => files.get(idx).map(|f| (n, f.clone())),
            _ => None,
        })
        .collect()
}
