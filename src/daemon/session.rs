//! Shell: creating and reopening a session directory, and feeding a recorded journal through a
//! fresh engine (shared by crash recovery and replay).

use super::journal::{
    read_journal, repair_jsonl, write_atomic, JournalEntry, JournalItem, Results,
};
use crate::config::Config;
use crate::engine::{Engine, Input, Output};
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
pub fn resolve_against(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

impl Session {
    /// Create `dir` from a config file, or reopen it (then its stored config is used).
    pub fn open_or_create(
        dir: &Path,
        config_path: Option<&Path>,
        port: Option<&Path>,
        capture_root: Option<&Path>,
    ) -> Result<Session> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create session folder {}", dir.display()))?;
        let stored = dir.join("config.toml");
        let info_path = dir.join("session.json");
        if stored.exists() && info_path.exists() {
            let text = std::fs::read_to_string(&stored)
                .with_context(|| format!("cannot read {}", stored.display()))?;
            let config = Config::from_toml_str(&text)
                .with_context(|| format!("invalid stored config {}", stored.display()))?;
            let mut info: SessionInfo = serde_json::from_slice(&std::fs::read(&info_path)?)
                .with_context(|| format!("cannot read {}", info_path.display()))?;
            if let Some(p) = config_path {
                let given = std::fs::read_to_string(p).unwrap_or_default();
                if given != text {
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
                info.capture_root = c.to_path_buf();
            }
            let resumed = dir.join("journal.jsonl").exists();
            return Ok(Session {
                dir: dir.to_path_buf(),
                config,
                info,
                resumed,
            });
        }
        let Some(config_path) = config_path else {
            bail!(
                "{} is not a goniowatch session; give --config to start one",
                dir.display()
            );
        };
        let (config, text) = Config::load(config_path)
            .with_context(|| format!("invalid config {}", config_path.display()))?;
        config
            .live_white()
            .with_context(|| format!("invalid config {}", config_path.display()))?;
        let base = config_path
            .canonicalize()
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf))
            .unwrap_or_else(|| PathBuf::from("."));
        let info = SessionInfo {
            created_ms: super::journal::now_ms(),
            goniowatch: env!("CARGO_PKG_VERSION").into(),
            capture_root: capture_root
                .map(Path::to_path_buf)
                .unwrap_or_else(|| resolve_against(&base, &config.ingest.capture_root)),
            port: port
                .map(Path::to_path_buf)
                .unwrap_or_else(|| config.link.port.clone()),
            config_source: config_path.to_path_buf(),
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
    pub fn open_read_only(dir: &Path) -> Result<Session> {
        let stored = dir.join("config.toml");
        let text = std::fs::read_to_string(&stored).with_context(|| {
            format!(
                "{} is not a goniowatch session (no config.toml)",
                dir.display()
            )
        })?;
        let config = Config::from_toml_str(&text)
            .with_context(|| format!("invalid stored config {}", stored.display()))?;
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

/// Rebuild the results of a session from its journal: repair torn lines, feed every recorded
/// input to a fresh engine, and rewrite the result files from scratch. Returns the engine.
pub fn recover(session: &Session) -> Result<(Engine, usize)> {
    let journal_path = session.dir.join("journal.jsonl");
    let cut = repair_jsonl(&journal_path)?;
    if cut > 0 {
        tracing::warn!("cut {cut} torn line(s) off {}", journal_path.display());
    }
    let entries = read_journal(&journal_path)?;
    let mut engine = session.config.engine()?;
    let mut results = Results::open(&session.dir, true)?;
    let mut n = 0;
    for e in &entries {
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

/// The inputs of a journal, in order.
pub fn inputs(entries: &[JournalEntry]) -> impl Iterator<Item = (u64, &Input)> {
    entries.iter().filter_map(|e| match &e.item {
        JournalItem::In(i) => Some((e.wall_ms, i)),
        JournalItem::Out(_) => None,
    })
}

/// Whether an output is a result record.
pub fn is_record(o: &Output) -> bool {
    matches!(
        o,
        Output::Capture(_)
            | Output::Pair(_)
            | Output::Isotropy(_)
            | Output::Sweep(_)
            | Output::Alarm(_)
            | Output::Manifest(_)
    )
}
