//! The session journal: every engine input in the order consumed, and every line sent, with
//! wall times, one JSON object a line, each ending in a checksum. Resume and replay read it
//! through `read_journal`, which verifies every line before anything is rebuilt from it.
//!
//! Appends are written line by line with `write(2)` (a `kill -9` loses nothing written) and
//! `fsync`ed once per capture outcome. Only an unterminated last line (a write cut short by a
//! crash) is ever cut.

use crate::engine::Input;
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

pub(crate) fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

/// The checksum field that ends every journal line: `,"sum":"<16 hex digits>"}`. It covers
/// the line's JSON without it (the bytes up to the field, then `}`), so any changed byte of an
/// entry is found on resume and replay.
const SUM_PREFIX: &str = ",\"sum\":\"";
const SUM_HEX: usize = 16;
const SUM_SUFFIX_LEN: usize = SUM_PREFIX.len() + SUM_HEX + 2;

fn line_sum(body: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(body)[..SUM_HEX / 2]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// One journal entry as its line (LF included), checksum appended.
pub(crate) fn encode_entry(entry: &JournalEntry) -> Result<Vec<u8>> {
    let mut line = serde_json::to_vec(entry)?;
    if line.last() != Some(&b'}') {
        anyhow::bail!("a journal entry did not serialise to a JSON object");
    }
    let sum = line_sum(&line);
    line.pop();
    line.extend_from_slice(SUM_PREFIX.as_bytes());
    line.extend_from_slice(sum.as_bytes());
    line.extend_from_slice(b"\"}\n");
    Ok(line)
}

/// Why a journal cannot be trusted. Nothing is rebuilt from a damaged journal.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path} line {line} is damaged ({reason}); goniowatch will not rebuild or replay a session from a damaged journal. Nothing was changed. Restore the journal from a backup, or start a new session folder")]
    Damaged {
        path: String,
        line: usize,
        reason: String,
    },
}

/// A journal as read: its entries, and what was left out.
#[derive(Debug, Clone, Default)]
pub struct JournalRead {
    pub entries: Vec<JournalEntry>,
    /// An unterminated last line (a write cut short by a crash); not an entry.
    pub torn_tail: bool,
    /// The length of that line.
    pub torn_bytes: usize,
    /// Lines at the start of the journal without checksums (written by a goniowatch before
    /// journal lines carried them): read, but not verified.
    pub unverified: usize,
}

/// Whether a journal line ends in a checksum field.
fn has_sum(text: &str) -> bool {
    let n = text.len();
    n > SUM_SUFFIX_LEN
        && text.is_char_boundary(n - SUM_SUFFIX_LEN)
        && text[n - SUM_SUFFIX_LEN..].starts_with(SUM_PREFIX)
        && text.ends_with("\"}")
}

/// Check one complete journal line and parse it. A line with a checksum must match it; a line
/// without one is accepted only when `plain` (a legacy line, read unverified).
fn parse_line(text: &str, plain: bool) -> std::result::Result<JournalEntry, String> {
    let body = if plain {
        text.to_string()
    } else {
        if !has_sum(text) {
            return Err("no checksum, although the journal's other lines have one".into());
        }
        let n = text.len();
        let want = &text[n - SUM_HEX - 2..n - 2];
        let body = format!("{}}}", &text[..n - SUM_SUFFIX_LEN]);
        let got = line_sum(body.as_bytes());
        if got != want {
            return Err(format!(
                "checksum {want} does not match its content ({got})"
            ));
        }
        body
    };
    serde_json::from_str(&body).map_err(|e| format!("not a journal entry: {e}"))
}

/// Read and verify a journal. A missing file reads as empty. Every complete line must verify;
/// an unterminated last line is left out and reported (`torn_tail`). Unless `require_sums` (the
/// session was created with them), lines without a checksum are read unverified while no line
/// before them had one.
pub fn read_journal(
    path: &Path,
    require_sums: bool,
) -> std::result::Result<JournalRead, JournalError> {
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(JournalRead::default()),
        Err(source) => {
            return Err(JournalError::Read {
                path: path.display().to_string(),
                source,
            })
        }
    };
    let damaged = |line: usize, reason: String| JournalError::Damaged {
        path: path.display().to_string(),
        line,
        reason,
    };
    let complete = data
        .iter()
        .rposition(|b| *b == b'\n')
        .map(|p| p + 1)
        .unwrap_or(0);
    let mut out = JournalRead {
        torn_tail: complete < data.len(),
        torn_bytes: data.len() - complete,
        ..JournalRead::default()
    };
    let lines: Vec<&[u8]> = data[..complete].split(|b| *b == b'\n').collect();
    let lines = &lines[..lines.len().saturating_sub(1)]; // the split after the last LF is empty
                                                         // A session created before journal lines carried checksums (`!require_sums`) has plain
                                                         // lines first, then checksummed ones once a newer goniowatch resumed it. Plain lines are
                                                         // accepted only as that prefix: after the first checksummed line every line must verify.
    let mut plain_prefix = !require_sums;
    for (n, raw) in lines.iter().enumerate() {
        let text = std::str::from_utf8(raw).map_err(|_| damaged(n + 1, "not UTF-8".into()))?;
        if text.trim().is_empty() {
            return Err(damaged(n + 1, "empty line".into()));
        }
        plain_prefix = plain_prefix && !has_sum(text);
        if plain_prefix {
            out.unverified += 1;
        }
        out.entries
            .push(parse_line(text, plain_prefix).map_err(|r| damaged(n + 1, r))?);
    }
    Ok(out)
}

/// Cut an unterminated last line (a write cut short by a crash) off a JSON-lines file. Returns
/// the lines cut (0 or 1). Complete lines are never cut: their damage is reported by the reader.
pub(crate) fn repair_jsonl(path: &Path) -> Result<usize> {
    let Ok(data) = std::fs::read(path) else {
        return Ok(0);
    };
    if data.is_empty() || data[data.len() - 1] == b'\n' {
        return Ok(0);
    }
    let keep = data
        .iter()
        .rposition(|b| *b == b'\n')
        .map(|p| p + 1)
        .unwrap_or(0);
    let f = OpenOptions::new()
        .write(true)
        .open(path)
        .with_context(|| format!("cannot repair {}", path.display()))?;
    f.set_len(keep as u64)
        .with_context(|| format!("cannot repair {}", path.display()))?;
    f.sync_all()
        .with_context(|| format!("cannot repair {}", path.display()))?;
    Ok(1)
}

/// An append-only JSON-lines file. Every error names the file.
pub struct JsonlFile {
    file: File,
    path: PathBuf,
    dirty: bool,
}

impl JsonlFile {
    pub fn append(path: &Path) -> Result<Self> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("cannot open {}", path.display()))?;
        Ok(JsonlFile {
            file,
            path: path.to_path_buf(),
            dirty: false,
        })
    }
    pub fn create(path: &Path) -> Result<Self> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        Ok(JsonlFile {
            file,
            path: path.to_path_buf(),
            dirty: false,
        })
    }
    pub(crate) fn write<T: Serialize>(&mut self, value: &T) -> Result<()> {
        let mut line = serde_json::to_vec(value)?;
        line.push(b'\n');
        self.write_line(&line)
    }
    /// Append one journal entry with its checksum.
    pub fn write_entry(&mut self, entry: &JournalEntry) -> Result<()> {
        let line = encode_entry(entry)?;
        self.write_line(&line)
    }
    fn write_line(&mut self, line: &[u8]) -> Result<()> {
        self.file
            .write_all(line)
            .with_context(|| format!("cannot write to {}", self.path.display()))?;
        self.dirty = true;
        Ok(())
    }
    pub fn sync(&mut self) -> Result<()> {
        if self.dirty {
            self.file
                .sync_data()
                .with_context(|| format!("cannot flush {} to disk", self.path.display()))?;
            self.dirty = false;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Input;

    /// A journal path in a fresh directory, removed with the guard (also when a test fails).
    fn temp(name: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::Builder::new()
            .prefix(&format!("gw-journal-{name}-"))
            .tempdir()
            .unwrap();
        let p = dir.path().join("journal.jsonl");
        (dir, p)
    }

    fn entries() -> Vec<JournalEntry> {
        vec![
            JournalEntry {
                wall_ms: 1,
                item: JournalItem::In(Input::Connected),
            },
            JournalEntry {
                wall_ms: 2,
                item: JournalItem::Out("0 HELLO proto=1*4537".into()),
            },
            JournalEntry {
                wall_ms: 3,
                item: JournalItem::In(Input::Rx {
                    line: "4 CAPTURE idx=0 entry=0 file=demo/cap_0.hdr t=0.000*8B6D".into(),
                }),
            },
        ]
    }

    fn write(path: &Path, e: &[JournalEntry]) -> Vec<u8> {
        let mut f = JsonlFile::create(path).unwrap();
        for x in e {
            f.write_entry(x).unwrap();
        }
        f.sync().unwrap();
        std::fs::read(path).unwrap()
    }

    #[test]
    fn a_full_disk_names_the_file() {
        let full = Path::new("/dev/full");
        if !full.exists() {
            return;
        }
        let mut f = JsonlFile::append(full).unwrap();
        let e = f
            .write_entry(&entries()[0])
            .and_then(|_| f.sync())
            .unwrap_err();
        let msg = format!("{e:#}");
        assert!(msg.contains("/dev/full") && msg.contains("space"), "{msg}");
    }

    #[test]
    fn entries_round_trip_with_their_checksums() {
        let (_dir, p) = temp("rt");
        let bytes = write(&p, &entries());
        for line in bytes.split(|b| *b == b'\n').filter(|l| !l.is_empty()) {
            // every line stays one JSON object
            let v: serde_json::Value = serde_json::from_slice(line).unwrap();
            assert_eq!(v["sum"].as_str().unwrap().len(), 16);
        }
        let r = read_journal(&p, true).unwrap();
        assert_eq!(r.entries, entries());
        assert!(!r.torn_tail && r.unverified == 0);
    }

    #[test]
    fn every_changed_byte_is_found_and_named_by_line() {
        let (_dir, p) = temp("flip");
        let good = write(&p, &entries());
        let line_of = |pos: usize| good[..pos].iter().filter(|b| **b == b'\n').count() + 1;
        for pos in 0..good.len() {
            if good[pos] == b'\n' {
                continue;
            }
            for bit in [0x01u8, 0x08, 0x20] {
                let mut bad = good.clone();
                bad[pos] ^= bit;
                if bad[pos] == b'\n' {
                    continue;
                }
                std::fs::write(&p, &bad).unwrap();
                match read_journal(&p, true) {
                    Err(JournalError::Damaged { line, .. }) => {
                        assert_eq!(line, line_of(pos), "byte {pos}")
                    }
                    other => panic!("byte {pos} bit {bit:#x}: {other:?}"),
                }
            }
        }
    }

    #[test]
    fn a_torn_tail_is_left_out_and_cut_only_by_repair() {
        let (_dir, p) = temp("torn");
        let mut bytes = write(&p, &entries());
        bytes.extend_from_slice(b"{\"wall_ms\":4,\"in\":{\"ty");
        std::fs::write(&p, &bytes).unwrap();
        let r = read_journal(&p, true).unwrap();
        assert!(r.torn_tail);
        assert_eq!(r.entries.len(), 3);
        assert_eq!(repair_jsonl(&p).unwrap(), 1);
        assert_eq!(repair_jsonl(&p).unwrap(), 0);
        assert!(!read_journal(&p, true).unwrap().torn_tail);
    }

    #[test]
    fn a_legacy_journal_is_read_unverified_and_then_checksummed_lines_verify() {
        let (_dir, p) = temp("legacy");
        let legacy: Vec<u8> = entries()
            .iter()
            .flat_map(|e| {
                let mut l = serde_json::to_vec(e).unwrap();
                l.push(b'\n');
                l
            })
            .collect();
        std::fs::write(&p, &legacy).unwrap();
        // a session created with checksums never reads a line without one
        assert!(matches!(
            read_journal(&p, true),
            Err(JournalError::Damaged { line: 1, .. })
        ));
        let r = read_journal(&p, false).unwrap();
        assert_eq!(r.unverified, entries().len());
        assert_eq!(r.entries, entries());
        // a legacy session resumed by this goniowatch: plain lines, then checksummed ones
        let mut resumed = legacy.clone();
        for e in entries() {
            resumed.extend_from_slice(&encode_entry(&e).unwrap());
        }
        std::fs::write(&p, &resumed).unwrap();
        let r = read_journal(&p, false).unwrap();
        assert_eq!(r.unverified, entries().len());
        assert_eq!(r.entries.len(), 2 * entries().len());
        assert!(matches!(
            read_journal(&p, true),
            Err(JournalError::Damaged { line: 1, .. })
        ));
        // the checksummed part still verifies: a changed byte there is found
        let mut flipped = resumed.clone();
        let at = legacy.len() + 12;
        flipped[at] ^= 0x01;
        std::fs::write(&p, &flipped).unwrap();
        assert!(matches!(
            read_journal(&p, false),
            Err(JournalError::Damaged { line, .. }) if line == entries().len() + 1
        ));
        // a plain line after a checksummed one is damage, even in a legacy session
        let mut mixed = encode_entry(&entries()[0]).unwrap();
        mixed.extend_from_slice(&legacy);
        std::fs::write(&p, &mixed).unwrap();
        assert!(matches!(
            read_journal(&p, false),
            Err(JournalError::Damaged { line: 2, .. })
        ));
        // an empty line in the middle is damage, not a gap to skip
        let mut gap = write(&p, &entries());
        gap.splice(0..0, b"\n".iter().copied());
        std::fs::write(&p, &gap).unwrap();
        assert!(matches!(
            read_journal(&p, true),
            Err(JournalError::Damaged { line: 1, .. })
        ));
    }
}
