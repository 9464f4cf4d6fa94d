//! Opening a session folder (creating it, reopening it, or refusing one whose results have lost
//! their journal) and rebuilding its results from a verified journal through a fresh engine
//! (crash recovery; replay feeds the same inputs).

use super::folder::{write_atomic, Results, RESULT_FILES};
use super::journal::{read_journal, repair_jsonl, JournalEntry, JournalItem, JournalRead};
use crate::config::Config;
use crate::engine::{Engine, Input};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `session.json`: facts about the session that are not results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionInfo {
    pub created_ms: u64,
    pub goniowatch: String,
    /// Absolute capture root, resolved at creation.
    pub capture_root: PathBuf,
    /// The serial port, resolved at creation.
    pub port: PathBuf,
    /// The config file the session was created from.
    pub config_source: PathBuf,
    /// Every journal line carries a checksum (sessions created before they did have none).
    #[serde(default)]
    pub journal_checksums: bool,
}

/// A session directory, opened.
pub struct Session {
    pub dir: PathBuf,
    pub config: Config,
    pub info: SessionInfo,
    /// True when the session already had a journal (a resume).
    pub resumed: bool,
}

/// Resolve `p` against `base` unless it is absolute.
pub(crate) fn resolve_against(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

/// `p` as an absolute path (against the working directory), so that a session folder means
/// the same from wherever it is later read.
fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot make {} absolute", p.display()))
}

/// Whether a file exists with at least one byte.
fn non_empty(p: &Path) -> bool {
    std::fs::metadata(p).map(|m| m.len() > 0).unwrap_or(false)
}

/// The result files of `dir` that hold data. `summary.json` is not one: the run writes it on
/// its first tick even before any input, and it is always rebuilt.
fn results_present(dir: &Path) -> Vec<&'static str> {
    RESULT_FILES
        .iter()
        .copied()
        .filter(|n| non_empty(&dir.join(n)))
        .collect()
}

/// The config a new session is created from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum ConfigGiven<'a> {
    /// A config file (relative paths in it are taken from its folder).
    File(&'a Path),
    /// A config text, named `source` in session.json (relative paths from the working folder).
    Text { text: &'a str, source: &'a Path },
}

impl ConfigGiven<'_> {
    fn path(&self) -> &Path {
        match self {
            ConfigGiven::File(p) => p,
            ConfigGiven::Text { source, .. } => source,
        }
    }
    fn text(&self) -> String {
        match self {
            ConfigGiven::File(p) => std::fs::read_to_string(p).unwrap_or_default(),
            ConfigGiven::Text { text, .. } => text.to_string(),
        }
    }
}

/// Why an existing session folder cannot be resumed as a check of `capture_root` with
/// `config_text`, if it cannot: a session folder belongs to one capture folder and one config,
/// and a resume of another would report the old folder's results as the new one's. `None`
/// for a folder that holds no session yet, or the same source.
pub(crate) fn other_source(
    dir: &Path,
    capture_root: &Path,
    config_text: &str,
) -> Result<Option<String>> {
    let (stored, info_path) = (dir.join("config.toml"), dir.join("session.json"));
    if !(stored.exists() && info_path.exists()) {
        return Ok(None);
    }
    let info: SessionInfo = serde_json::from_slice(
        &std::fs::read(&info_path)
            .with_context(|| format!("cannot read {}", info_path.display()))?,
    )
    .with_context(|| format!("cannot parse {}", info_path.display()))?;
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    };
    if !same(&info.capture_root, capture_root) {
        return Ok(Some(format!(
            "{} holds the session of another capture folder ({}), not of {}; a session folder belongs to one capture folder. Give another --session (or leave it out: the folder's own DIR.check)",
            dir.display(),
            info.capture_root.display(),
            capture_root.display()
        )));
    }
    let text = std::fs::read_to_string(&stored)
        .with_context(|| format!("cannot read {}", stored.display()))?;
    if text != config_text {
        return Ok(Some(format!(
            "{} was made with another config ({}, stored as {}); a session keeps the config it was made with. Give another --session to check with this one, or check again with the same config",
            dir.display(),
            info.config_source.display(),
            stored.display()
        )));
    }
    Ok(None)
}

/// Why a finished check in `dir` cannot be resumed on a folder whose listing now places
/// `placed` (file names relative to the capture folder), if it cannot: a finished check has
/// written its end-of-set results (the pairs resolved at the end, the final alarms), so captures
/// that appeared since are not appended to it, and reporting the old result for the new folder
/// would be wrong. None for a session that is not finished, or whose captures are the folder's.
pub(crate) fn finished_check_outdated(dir: &Path, placed: &[String]) -> Result<Option<String>> {
    let Ok(summary) = super::folder::load_summary(dir) else {
        return Ok(None);
    };
    if !summary.finished {
        return Ok(None);
    }
    let seen: std::collections::BTreeSet<String> = super::folder::read_session_captures(dir)?
        .into_iter()
        .filter(|c| !c.probe)
        .map(|c| c.file)
        .collect();
    let new: Vec<&String> = placed.iter().filter(|f| !seen.contains(*f)).collect();
    if new.is_empty() {
        return Ok(None);
    }
    Ok(Some(format!(
        "{} holds a finished check of {} captures, and the folder now places {} captures it has not checked (the first: {}); a finished check is not extended, because its end-of-set results are written. Check the folder into a new session folder (--session NEW) to check all {} captures",
        dir.display(),
        seen.len(),
        new.len(),
        new[0],
        placed.len()
    )))
}

impl Session {
    /// Create `dir` from a config file, or reopen it (then its stored config is used).
    pub fn open_or_create(
        dir: &Path,
        config_path: Option<&Path>,
        port: Option<&Path>,
        capture_root: Option<&Path>,
    ) -> Result<Session> {
        Self::open_or_create_given(dir, config_path.map(ConfigGiven::File), port, capture_root)
    }

    /// Create `dir` from a config file or text, or reopen it (then its stored config is used).
    pub(crate) fn open_or_create_given(
        dir: &Path,
        given: Option<ConfigGiven<'_>>,
        port: Option<&Path>,
        capture_root: Option<&Path>,
    ) -> Result<Session> {
        let config_path = given.as_ref().map(ConfigGiven::path);
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create session folder {}", dir.display()))?;
        let stored = dir.join("config.toml");
        let info_path = dir.join("session.json");
        let journal = dir.join("journal.jsonl");
        let has_journal = non_empty(&journal);
        let results = results_present(dir);
        if stored.exists() && info_path.exists() {
            if !has_journal && !results.is_empty() {
                bail!(
                    "{} has results ({}) but its journal.jsonl is {}; the results cannot be rebuilt or checked without it, and goniowatch will not overwrite them. Restore journal.jsonl from a backup to resume, or give a new --session folder to start over",
                    dir.display(),
                    results.join(", "),
                    if journal.exists() { "empty" } else { "missing" }
                );
            }
            let text = std::fs::read_to_string(&stored)
                .with_context(|| format!("cannot read {}", stored.display()))?;
            let config = super::folder::parse_stored_config(&stored, &text)?;
            let mut info: SessionInfo = serde_json::from_slice(
                &std::fs::read(&info_path)
                    .with_context(|| format!("cannot read {}", info_path.display()))?,
            )
            .with_context(|| format!("cannot parse {}", info_path.display()))?;
            if let Some(g) = &given {
                let p = g.path();
                if g.text() != text {
                    tracing::warn!(
                        "{} differs from the session's stored config; the stored one is used",
                        p.display()
                    );
                }
            }
            if let Some(p) = port {
                info.port = p.to_path_buf();
            }
            if let Some(c) = capture_root {
                info.capture_root = absolute(c)?;
            }
            return Ok(Session {
                dir: dir.to_path_buf(),
                config,
                info,
                resumed: has_journal,
            });
        }
        if has_journal || !results.is_empty() {
            let mut held: Vec<&str> = results;
            if has_journal {
                held.insert(0, "journal.jsonl");
            }
            bail!(
                "{} holds session data ({}) but no {}; it is not a complete goniowatch session and will not be overwritten. Give a new --session folder to start one",
                dir.display(),
                held.join(", "),
                if stored.exists() { "session.json" } else { "config.toml" }
            );
        }
        let Some(config_path) = config_path else {
            bail!(
                "{} is not a goniowatch session; give --config to start one",
                dir.display()
            );
        };
        let (config, text, base) = match given {
            Some(ConfigGiven::Text { text, .. }) => (
                Config::from_toml_str(text)
                    .with_context(|| format!("invalid config {}", config_path.display()))?,
                text.to_string(),
                PathBuf::from("."),
            ),
            _ => {
                let (config, text) = Config::load(config_path)
                    .with_context(|| format!("invalid config {}", config_path.display()))?;
                let base = config_path
                    .canonicalize()
                    .ok()
                    .and_then(|p| p.parent().map(Path::to_path_buf))
                    .unwrap_or_else(|| PathBuf::from("."));
                (config, text, base)
            }
        };
        crate::setup::live_white(&config)
            .with_context(|| format!("invalid config {}", config_path.display()))?;
        let info = SessionInfo {
            created_ms: super::journal::now_ms(),
            goniowatch: env!("CARGO_PKG_VERSION").into(),
            capture_root: match capture_root {
                Some(c) => absolute(c)?,
                None => absolute(&resolve_against(&base, &config.ingest.capture_root))?,
            },
            port: port
                .map(Path::to_path_buf)
                .unwrap_or_else(|| config.link.port.clone()),
            config_source: config_path.to_path_buf(),
            journal_checksums: true,
        };
        write_atomic(&stored, text.as_bytes())?;
        write_atomic(&info_path, &serde_json::to_vec_pretty(&info)?)?;
        Ok(Session {
            dir: dir.to_path_buf(),
            config,
            info,
            resumed: false,
        })
    }

    /// Read a session directory without changing it (for replay).
    pub(crate) fn open_read_only(dir: &Path) -> Result<Session> {
        let (config, _) = super::folder::load_config(dir)?;
        let info_path = dir.join("session.json");
        let info: SessionInfo = serde_json::from_slice(
            &std::fs::read(&info_path)
                .with_context(|| format!("cannot read {}", info_path.display()))?,
        )
        .with_context(|| format!("cannot parse {}", info_path.display()))?;
        Ok(Session {
            dir: dir.to_path_buf(),
            config,
            info,
            resumed: true,
        })
    }
}

/// The longest unterminated tail cut as a torn write; a journal line is far shorter (the serial
/// link bounds its lines, and a capture outcome is a few hundred bytes).
const MAX_TORN_TAIL: usize = 1 << 20;

/// Rebuild the results of a session from its journal: repair torn lines, feed every recorded
/// input to a fresh engine, and rewrite the result files from scratch. Returns the engine.
pub fn recover(session: &Session) -> Result<(Engine, usize)> {
    let journal_path = session.dir.join("journal.jsonl");
    // verify first: a damaged journal leaves every file as it was
    let read = verified_journal(&journal_path, session.info.journal_checksums)?;
    let results = results_present(&session.dir);
    if !results.is_empty()
        && !read
            .entries
            .iter()
            .any(|e| matches!(e.item, JournalItem::In(_)))
    {
        bail!(
            "{} holds results ({}) but its journal.jsonl records no input{}; the results cannot be rebuilt from it, and goniowatch will not overwrite them. Nothing was changed. Restore journal.jsonl from a backup to resume, or give a new --session folder to start over",
            session.dir.display(),
            results.join(", "),
            if read.torn_tail { " (only an unterminated line)" } else { "" }
        );
    }
    if read.torn_bytes > MAX_TORN_TAIL {
        bail!(
            "{} ends in {} bytes without a line end; a write cut short leaves at most one line, so this is damage, not a torn write. Nothing was changed. Restore journal.jsonl from a backup, or give a new --session folder to start over",
            journal_path.display(),
            read.torn_bytes
        );
    }
    if read.torn_tail {
        repair_jsonl(&journal_path)?;
        tracing::warn!(
            "cut a torn last line (a write cut short) off {}",
            journal_path.display()
        );
    }
    let mut engine = crate::engine::Engine::from_config(&session.config)?;
    let mut results = Results::open(&session.dir, true)?;
    let mut n = 0;
    for e in &read.entries {
        if let JournalItem::In(input) = &e.item {
            for o in engine.handle(input) {
                results.record(&o)?;
            }
            n += 1;
        }
    }
    results.sync()?;
    results.write_summary(&engine.summary())?;
    Ok((engine, n))
}

/// Read and verify a session's journal, warning when it predates checksums.
pub(crate) fn verified_journal(path: &Path, require_sums: bool) -> Result<JournalRead> {
    let read = read_journal(path, require_sums)?;
    if read.unverified > 0 {
        tracing::warn!(
            "{}: its first {} lines have no checksums (written by an older goniowatch); they are read but cannot be verified",
            path.display(),
            read.unverified
        );
    }
    Ok(read)
}

/// The inputs of a journal, in order.
pub(crate) fn inputs(entries: &[JournalEntry]) -> impl Iterator<Item = (u64, &Input)> {
    entries.iter().filter_map(|e| match &e.item {
        JournalItem::In(i) => Some((e.wall_ms, i)),
        JournalItem::Out(_) => None,
    })
}
