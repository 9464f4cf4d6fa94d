//! The session folder: its layout, the one reader of its JSON-lines result files, the result
//! writer, atomic writes and the session lock. Everything that reads a session (run, replay,
//! report, compare, the status page) reads it through here.
//!
//! ```text
//! SESSION/
//!   config.toml      the configuration the session runs with (copied at creation)
//!   session.json     where the captures are, when and how the session was created (wall clock)
//!   journal.jsonl    every engine input in the order consumed, and every line sent, with wall
//!                    times: the raw serial traffic both ways, link events, capture outcomes
//!   manifest.jsonl   per capture: file, size, SHA-256, status          ┐
//!   captures.jsonl   per-capture results                               │ results: a pure
//!   pairs.jsonl      per-pair reciprocity results                      │ function of the
//!   isotropy.jsonl   per-capture isotropy-class results                │ journal's inputs,
//!   alarms.jsonl     alarms (controller time and capture index only)   │ no wall-clock field
//!   sweeps.jsonl     per completed light direction (isotropic samples) │
//!   summary.json     the running summary (Table 2, counts, link)       ┘
//!   lock             held while a daemon works on the session
//! ```

use super::journal::JsonlFile;
use crate::config::Config;
use crate::engine::{Output, Summary};
use anyhow::{Context, Result};
use serde::Serialize;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Read a JSON-lines result file of a session. A missing file reads as empty; an unterminated
/// last line (a write cut short by a crash) is left out; any other line that does not parse is
/// an error naming the file and the line.
pub(crate) fn read_records<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
    };
    let complete = text.rfind('\n').map_or(0, |p| p + 1);
    let mut out = Vec::new();
    for (n, line) in text[..complete].lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        out.push(
            serde_json::from_str(line)
                .with_context(|| format!("{} line {} is not a record", path.display(), n + 1))?,
        );
    }
    Ok(out)
}

/// Read a finished session's JSON-lines result file for a command that reports on it
/// (`report`, `compare`): as `read_records`, but a file that ends in an unterminated line is an
/// error rather than read short, since a report of part of a file would look complete.
pub(crate) fn read_complete_records<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    if let Ok(bytes) = std::fs::read(path) {
        if bytes.last().is_some_and(|b| *b != b'\n') {
            let tail = bytes.len() - bytes.iter().rposition(|b| *b == b'\n').map_or(0, |p| p + 1);
            anyhow::bail!(
                "{} ends in a torn line ({tail} bytes after its last complete record: a write cut short, or the file was cut); a report of it would leave records out. Resume the session (`goniowatch run` or `check` on it) to rebuild its results from the journal, or replay it (`goniowatch replay SESSION --out DIR`) and report on the replay",
                path.display()
            );
        }
    }
    read_records(path)
}

/// A finished session's `captures.jsonl` for a command that reports on it: complete
/// (`read_complete_records`), and holding at least the captures its summary counts as checked,
/// so a file cut at a line boundary is not taken for the whole session either.
pub(crate) fn read_session_captures(dir: &Path) -> Result<Vec<crate::checks::CaptureRecord>> {
    let path = dir.join("captures.jsonl");
    let records: Vec<crate::checks::CaptureRecord> = read_complete_records(&path)?;
    if let Ok(summary) = load_summary(dir) {
        let counted = summary.checked.captures;
        if (records.len() as u64) < counted {
            anyhow::bail!(
                "{} holds {} capture records where the session's summary counts {counted} checked captures: the results are incomplete (a file cut short or replaced). Resume the session (`goniowatch run` or `check` on it) to rebuild them from the journal, or replay it (`goniowatch replay SESSION --out DIR`) and report on the replay",
                path.display(),
                records.len()
            );
        }
    }
    Ok(records)
}

/// A session's stored configuration, loaded once: the parsed config and its text.
pub(crate) fn load_config(dir: &Path) -> Result<(Config, String)> {
    let path = dir.join("config.toml");
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "cannot read {} (is this a goniowatch session folder?)",
            path.display()
        )
    })?;
    let config = parse_stored_config(&path, &text)?;
    Ok((config, text))
}

/// Parse a session's stored config (`Config::from_stored_toml_str`), warning about each runtime
/// key brought into its current range.
pub(crate) fn parse_stored_config(path: &Path, text: &str) -> Result<Config> {
    let (config, notes) = Config::from_stored_toml_str(text)
        .with_context(|| format!("invalid stored config {}", path.display()))?;
    for n in notes {
        tracing::warn!("{}: {n}", path.display());
    }
    Ok(config)
}

/// A session's `summary.json`.
pub(crate) fn load_summary(dir: &Path) -> Result<Summary> {
    let path = dir.join("summary.json");
    serde_json::from_slice(
        &std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?,
    )
    .with_context(|| format!("cannot parse {}", path.display()))
}

/// The result files, written from engine outputs.
pub(crate) struct Results {
    dir: PathBuf,
    captures: JsonlFile,
    pairs: JsonlFile,
    isotropy: JsonlFile,
    sweeps: JsonlFile,
    alarms: JsonlFile,
    manifest: JsonlFile,
}

pub const RESULT_FILES: [&str; 6] = [
    "captures.jsonl",
    "pairs.jsonl",
    "isotropy.jsonl",
    "alarms.jsonl",
    "manifest.jsonl",
    "sweeps.jsonl",
];

impl Results {
    /// Open for appending (`fresh = false`) or create empty (`fresh = true`).
    pub(crate) fn open(dir: &Path, fresh: bool) -> Result<Self> {
        let open = |name: &str| {
            let p = dir.join(name);
            if fresh {
                JsonlFile::create(&p)
            } else {
                JsonlFile::append(&p)
            }
        };
        Ok(Results {
            dir: dir.to_path_buf(),
            captures: open(RESULT_FILES[0])?,
            pairs: open(RESULT_FILES[1])?,
            isotropy: open(RESULT_FILES[2])?,
            alarms: open(RESULT_FILES[3])?,
            manifest: open(RESULT_FILES[4])?,
            sweeps: open(RESULT_FILES[5])?,
        })
    }

    /// Record one engine output (those that are results).
    pub(crate) fn record(&mut self, o: &Output) -> Result<()> {
        match o {
            Output::Capture(c) => self.captures.write(c),
            Output::Pair(p) => self.pairs.write(p),
            Output::Isotropy(r) => self.isotropy.write(r),
            Output::Sweep(r) => self.sweeps.write(r),
            Output::Alarm(a) => self.alarms.write(a),
            Output::Manifest(m) => self.manifest.write(m),
            // the summary carries the probe pose
            Output::Send(_)
            | Output::Ingest { .. }
            | Output::ProbePose(_)
            | Output::SentinelPose(_)
            | Output::Finished => Ok(()),
        }
    }

    pub(crate) fn sync(&mut self) -> Result<()> {
        for f in [
            &mut self.captures,
            &mut self.pairs,
            &mut self.isotropy,
            &mut self.sweeps,
            &mut self.alarms,
            &mut self.manifest,
        ] {
            f.sync()?;
        }
        Ok(())
    }

    pub(crate) fn write_summary<T: Serialize>(&self, summary: &T) -> Result<()> {
        write_atomic(
            &self.dir.join("summary.json"),
            &serde_json::to_vec_pretty(summary)?,
        )
    }
}

/// `path` made absolute, with `.` dropped and `..` taken by the names (a `..` after a folder
/// that does not exist yet cannot be resolved by the file system).
pub(crate) fn normal_absolute(path: &Path) -> Result<PathBuf> {
    use std::path::Component;
    let abs = std::path::absolute(path).with_context(|| format!("{}", path.display()))?;
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    Ok(out)
}

/// Whether `folder` (which need not exist yet) is the capture folder or lies inside it, by its
/// names or through a link on its way: goniowatch never writes there.
pub(crate) fn inside_capture_folder(folder: &Path, capture_root: &Path) -> bool {
    let Ok(folder) = normal_absolute(folder) else {
        return false;
    };
    let by_name = normal_absolute(capture_root).is_ok_and(|root| folder.starts_with(root));
    let by_link = capture_root.canonicalize().is_ok_and(|root| {
        folder
            .ancestors()
            .any(|a| a.canonicalize().is_ok_and(|a| a == root))
    });
    by_name || by_link
}

/// Write a file under a temporary name, fsync, rename into place.
pub(crate) fn write_atomic(path: &Path, data: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    {
        let mut f =
            File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        f.write_all(data)
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        f.sync_all()
            .with_context(|| format!("cannot flush {} to disk", tmp.display()))?;
    }
    std::fs::rename(&tmp, path).with_context(|| format!("cannot rename {}", tmp.display()))?;
    Ok(())
}

/// An exclusive lock on the session directory.
pub(crate) struct SessionLock {
    _file: File,
}

impl SessionLock {
    pub(crate) fn acquire(dir: &Path) -> Result<Self> {
        let path = dir.join("lock");
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .with_context(|| format!("cannot open {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                anyhow::bail!(
                    "session {} is in use by another goniowatch process",
                    dir.display()
                )
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(e).context("cannot lock the session")
            }
        }
        Ok(SessionLock { _file: file })
    }
}
