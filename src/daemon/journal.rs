//! Shell: the session directory.
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
//!   summary.json     the running summary (Table 2, counts, link)       ┘
//!   lock             held while a daemon works on the session
//! ```
//!
//! Appends are written line by line with `write(2)` (a `kill -9` loses nothing written) and
//! `fsync`ed once per capture outcome. A torn last line (a crash mid-write) is cut on open.

use crate::engine::{Input, Output};
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// One line of `journal.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JournalEntry {
    /// Wall-clock milliseconds since the Unix epoch (for replay pacing and the record; never
    /// seen by the engine).
    pub wall_ms: u64,
    #[serde(flatten)]
    pub item: JournalItem,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JournalItem {
    /// An engine input.
    In(Input),
    /// A line sent to the controller.
    Out(String),
}

pub fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

/// Cut a torn last line (no LF, or not valid JSON) off a JSON-lines file. Returns the lines cut.
pub fn repair_jsonl(path: &Path) -> Result<usize> {
    let Ok(data) = std::fs::read(path) else {
        return Ok(0);
    };
    let mut keep = data.len();
    let mut cut = 0;
    if !data.is_empty() && data[data.len() - 1] != b'\n' {
        keep = data
            .iter()
            .rposition(|b| *b == b'\n')
            .map(|p| p + 1)
            .unwrap_or(0);
        cut += 1;
    }
    // the last complete line must parse too (a crash can leave a full but garbled line only on
    // a broken disk, but check anyway)
    if keep > 0 {
        let start = data[..keep - 1]
            .iter()
            .rposition(|b| *b == b'\n')
            .map(|p| p + 1)
            .unwrap_or(0);
        if serde_json::from_slice::<serde_json::Value>(&data[start..keep - 1]).is_err() {
            keep = start;
            cut += 1;
        }
    }
    if keep != data.len() {
        let f = OpenOptions::new()
            .write(true)
            .open(path)
            .with_context(|| format!("cannot repair {}", path.display()))?;
        f.set_len(keep as u64)?;
        f.sync_all()?;
    }
    Ok(cut)
}

/// Read the journal (after repairing it).
pub fn read_journal(path: &Path) -> Result<Vec<JournalEntry>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
    };
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(n, l)| {
            serde_json::from_str(l).with_context(|| {
                format!("{}: line {} is not a journal entry", path.display(), n + 1)
            })
        })
        .collect()
}

/// An append-only JSON-lines file.
pub struct JsonlFile {
    file: File,
    dirty: bool,
}

impl JsonlFile {
    pub fn append(path: &Path) -> Result<Self> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("cannot open {}", path.display()))?;
        Ok(JsonlFile { file, dirty: false })
    }
    pub fn create(path: &Path) -> Result<Self> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        Ok(JsonlFile { file, dirty: false })
    }
    pub fn write<T: Serialize>(&mut self, value: &T) -> Result<()> {
        let mut line = serde_json::to_vec(value)?;
        line.push(b'\n');
        self.file.write_all(&line)?;
        self.dirty = true;
        Ok(())
    }
    pub fn sync(&mut self) -> Result<()> {
        if self.dirty {
            self.file.sync_data()?;
            self.dirty = false;
        }
        Ok(())
    }
}

/// The result files, written from engine outputs.
pub struct Results {
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
    pub fn open(dir: &Path, fresh: bool) -> Result<Self> {
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
    pub fn record(&mut self, o: &Output) -> Result<()> {
        match o {
            Output::Capture(c) => self.captures.write(c),
            Output::Pair(p) => self.pairs.write(p),
            Output::Isotropy(r) => self.isotropy.write(r),
            Output::Sweep(r) => self.sweeps.write(r),
            Output::Alarm(a) => self.alarms.write(a),
            Output::Manifest(m) => self.manifest.write(m),
            Output::Send(_) | Output::Ingest { .. } | Output::Finished => Ok(()),
        }
    }

    pub fn sync(&mut self) -> Result<()> {
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

    pub fn write_summary<T: Serialize>(&self, summary: &T) -> Result<()> {
        write_atomic(
            &self.dir.join("summary.json"),
            &serde_json::to_vec_pretty(summary)?,
        )
    }
}

/// Write a file under a temporary name, fsync, rename into place.
pub fn write_atomic(path: &Path, data: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    {
        let mut f =
            File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        f.write_all(data)?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, path).with_context(|| format!("cannot rename {}", tmp.display()))?;
    Ok(())
}

/// An exclusive lock on the session directory.
pub struct SessionLock {
    _file: File,
}

impl SessionLock {
    pub fn acquire(dir: &Path) -> Result<Self> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn torn_lines_are_cut() -> Result<()> {
        let dir = std::env::temp_dir().join(format!("gw-journal-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let p = dir.join("j.jsonl");
        std::fs::write(&p, b"{\"a\":1}\n{\"a\":2}\n{\"a\":")?;
        assert_eq!(repair_jsonl(&p)?, 1);
        assert_eq!(std::fs::read(&p)?, b"{\"a\":1}\n{\"a\":2}\n");
        std::fs::write(&p, b"{\"a\":1}\n{\"a\"::}\n")?;
        assert_eq!(repair_jsonl(&p)?, 1);
        assert_eq!(std::fs::read(&p)?, b"{\"a\":1}\n");
        std::fs::write(&p, b"{\"a\":1}\n")?;
        assert_eq!(repair_jsonl(&p)?, 0);
        std::fs::remove_dir_all(&dir).ok();
        Ok(())
    }
}
