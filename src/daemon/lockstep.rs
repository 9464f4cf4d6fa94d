//! Shell: `goniowatch lockstep`, the daemon's engine in lockstep with a simulated rig over
//! standard input and output: the detection lab's fast path (`benches/detection.py`) and the
//! regression sessions of the test suite.
//!
//! The rig (`python -m goniosim lockstep`) writes every line it would send on the serial port
//! to stdin. For each line this shell journals it, hands it to the engine, measures at once
//! every capture the engine asks for (the rig writes a capture before it announces it), and
//! answers with the lines the engine sends, each on its own line, then an empty line: the
//! rig's turn. Before the first line it answers the connection the same way (`HELLO`). So:
//!
//! - the rig never runs ahead of the checks: a probe the engine asks for is taken right after
//!   the regular capture that made it due, as on a real rig at 7 s a capture, where a live
//!   daemon keeps up; a live run at full simulator speed may take it a few captures later;
//! - a session costs the CPU time of its checks and decoding, never the wall time of a link
//!   (no timeout, no idle question, no reconnect);
//! - the session folder is a live run's: `replay`, `report` and `compare` read it, and its
//!   journal replays to the same results. Nothing is fsynced (the lab records again what a
//!   crash loses), and a capture's file is taken as finished when it is announced.
//!
//! End of stdin ends the session: the capture folder is listed for unannounced files (as the
//! live daemon does at the end of a run) and the summary is written.

use super::ingest::ingest;
use super::run::unannounced;
use crate::engine::{Engine, Input, Output, Summary};
use crate::protocol::MAX_LINE;
use crate::session::folder::{Results, SessionLock};
use crate::session::journal::{now_ms, JournalEntry, JournalItem, JsonlFile};
use crate::session::recovery::{ConfigGiven, Session};
use anyhow::{bail, Context, Result};
use std::collections::{BTreeSet, VecDeque};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

/// What `lockstep` needs: a new session folder, its config and the rig's capture root.
pub(crate) struct LockstepOptions {
    pub session_dir: PathBuf,
    pub config: PathBuf,
    pub capture_root: PathBuf,
}

/// The engine with its journal and result files; inputs are carried out to the end, captures
/// measured in the calling thread.
struct Stepper {
    engine: Engine,
    journal: JsonlFile,
    results: Results,
    capture_root: PathBuf,
    ingest: crate::config::IngestSpec,
    capture: crate::measure::averaging::AverageOptions,
    finished: bool,
}

impl Stepper {
    /// Journal `input`, hand it to the engine and carry out what it asks, measuring the
    /// captures it wants before returning. Lines to send are appended to `sent`.
    fn process(&mut self, input: Input, sent: &mut Vec<String>) -> Result<()> {
        let mut queue = VecDeque::from([input]);
        while let Some(input) = queue.pop_front() {
            self.journal.write_entry(&JournalEntry {
                wall_ms: now_ms(),
                item: JournalItem::In(input.clone()),
            })?;
            for o in self.engine.handle(&input) {
                match &o {
                    Output::Send(line) => {
                        self.journal.write_entry(&JournalEntry {
                            wall_ms: now_ms(),
                            item: JournalItem::Out(line.clone()),
                        })?;
                        sent.push(line.clone());
                    }
                    Output::Ingest { idx, file } => {
                        let outcome = ingest(&self.capture_root, file, &self.ingest, &self.capture);
                        queue.push_back(Input::Outcome { idx: *idx, outcome });
                    }
                    Output::Finished => self.finished = true,
                    _ => self.results.record(&o)?,
                }
            }
        }
        Ok(())
    }
}

/// The rig's side of the turn: the engine's lines, then an empty line.
fn answer(out: &mut impl Write, sent: &mut Vec<String>) -> Result<()> {
    for line in sent.drain(..) {
        out.write_all(line.as_bytes())?;
        out.write_all(b"\n")?;
    }
    out.write_all(b"\n")?;
    out.flush().context("cannot write to the rig (stdout)")?;
    Ok(())
}

/// One line of the rig as the live link frames it: a line too long or not UTF-8 becomes
/// `RxBad`, never the end of the session.
fn framed(mut raw: Vec<u8>) -> Input {
    if raw.last() == Some(&b'\n') {
        raw.pop();
    }
    if raw.last() == Some(&b'\r') {
        raw.pop();
    }
    if raw.len() >= MAX_LINE {
        return Input::RxBad {
            reason: format!("line longer than {MAX_LINE} bytes"),
        };
    }
    match String::from_utf8(raw) {
        Ok(line) => Input::Rx { line },
        Err(_) => Input::RxBad {
            reason: "line is not UTF-8".into(),
        },
    }
}

/// Run a session in lockstep with the rig on `input` / `output` (stdin and stdout for the
/// command); returns the summary and whether a critical alarm was raised. Refuses a folder that already holds a session: a lab recording is never resumed.
pub(crate) fn lockstep(
    opts: &LockstepOptions,
    input: impl BufRead,
    mut output: impl Write,
) -> Result<(Summary, bool)> {
    if opts.session_dir.join("journal.jsonl").exists() {
        bail!(
            "{} already holds a session; lockstep records into a new folder",
            opts.session_dir.display()
        );
    }
    let session = Session::open_or_create_given(
        &opts.session_dir,
        Some(ConfigGiven::File(&opts.config)),
        Some(Path::new("lockstep")),
        Some(&opts.capture_root),
    )?;
    let _lock = SessionLock::acquire(&session.dir)?;
    let cfg = &session.config;
    if cfg.source.kind != crate::archive::SourceKind::Protocol {
        bail!("lockstep follows a controller: the config's [source] must be the protocol");
    }
    // the rig renames a capture into place before announcing it: nothing to wait for
    let mut ingest_spec = cfg.ingest.clone();
    ingest_spec.settle_ms = 0;
    let mut st = Stepper {
        engine: Engine::from_config(cfg)?,
        journal: JsonlFile::append(&session.dir.join("journal.jsonl"))?,
        results: Results::open(&session.dir, true)?,
        capture_root: session.info.capture_root.clone(),
        ingest: ingest_spec,
        capture: cfg.capture,
        finished: false,
    };
    let mut sent = Vec::new();
    st.process(Input::Connected, &mut sent)?;
    answer(&mut output, &mut sent)?;
    let mut input = input;
    loop {
        let mut raw = Vec::new();
        let n = input
            .read_until(b'\n', &mut raw)
            .context("cannot read the rig's lines (stdin)")?;
        if n == 0 {
            break;
        }
        st.process(framed(raw), &mut sent)?;
        answer(&mut output, &mut sent)?;
    }
    if st.finished {
        let files = unannounced(&st.engine, &st.capture_root, &BTreeSet::new());
        st.process(Input::Unannounced { files }, &mut sent)?;
    }
    let summary = st.engine.summary();
    st.results.write_summary(&summary)?;
    Ok((summary, st.engine.critical_raised()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_framed_as_the_live_link_frames_it() {
        assert_eq!(
            framed(b"abc\r\n".to_vec()),
            Input::Rx { line: "abc".into() }
        );
        assert!(matches!(framed(vec![0xff, b'\n']), Input::RxBad { .. }));
        assert!(matches!(
            framed(vec![b'a'; MAX_LINE + 1]),
            Input::RxBad { .. }
        ));
    }
}
