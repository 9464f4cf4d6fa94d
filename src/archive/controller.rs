//! The controller's side of docs/protocol.md for captures that are only files.
//!
//! A pure state machine in the style of the engine: `handle_*` for what happens (the link
//! opens, a line arrives from the daemon, a file is ready, the set is complete), `poll_line`
//! for the lines it sends. It answers `HELLO` with `IDENT`, `SUBSCRIBE` with `ACK` and a
//! `STATUS`, `RESYNC` by announcing again, and refuses what needs a real rig (`PAUSE`, `RESUME`,
//! `PROBE`, `POSE?`) with `NAK reason=refused`. Each capture is announced once subscribed, with
//! the plan's pose as both commanded and encoder pose.

use super::listing::ArchiveCapture;
use crate::protocol::{format, parse, ToController};
use std::collections::VecDeque;

/// The `rig` of the `IDENT` it sends.
pub(crate) const RIG_ID: &str = "files";

pub struct ArchiveController {
    session: String,
    planned: usize,
    seq: u32,
    /// Every capture announced or waiting to be, by index.
    captures: Vec<ArchiveCapture>,
    /// How many of `captures` have been announced on this subscription.
    announced: usize,
    subscribed: bool,
    /// The time of the last capture, once the set is complete.
    done: Option<f64>,
    out: VecDeque<String>,
}

fn pose_text(p: &[f64; 4]) -> String {
    format!("{:.4},{:.4},{:.4},{:.4}", p[0], p[1], p[2], p[3])
}

impl ArchiveController {
    /// A controller for session `session` of `planned` captures.
    pub fn new(session: &str, planned: usize) -> Self {
        ArchiveController {
            session: session.into(),
            planned,
            seq: 0,
            captures: Vec::new(),
            announced: 0,
            subscribed: false,
            done: None,
            out: VecDeque::new(),
        }
    }

    fn send(&mut self, verb: &str, fields: &[(&str, String)]) {
        self.out.push_back(format(self.seq, verb, fields));
        self.seq = self.seq.wrapping_add(1);
    }

    fn ident(&mut self) {
        let fields = [
            ("rig", RIG_ID.to_string()),
            (
                "fw",
                concat!("goniowatch-", env!("CARGO_PKG_VERSION")).to_string(),
            ),
            ("proto", "1".to_string()),
            ("session", self.session.clone()),
            ("captures", self.planned.to_string()),
            ("boot", "1".to_string()),
        ];
        self.send("IDENT", &fields);
    }

    fn state(&self) -> &'static str {
        if self.done.is_some() {
            "done"
        } else {
            "running"
        }
    }

    fn now(&self) -> f64 {
        self.done
            .or_else(|| self.captures.last().map(|c| c.t))
            .unwrap_or(0.0)
    }

    fn status(&mut self) {
        let fields = [
            ("state", self.state().to_string()),
            ("t", format!("{:.3}", self.now())),
            ("next", self.captures.len().to_string()),
        ];
        self.send("STATUS", &fields);
    }

    fn capture(&mut self, idx: usize, replay: bool) {
        let Some(c) = self.captures.get(idx).cloned() else {
            return;
        };
        let pose = pose_text(&c.pose);
        let mut fields = vec![
            ("idx", idx.to_string()),
            ("entry", c.entry.to_string()),
            ("file", c.file.clone()),
            ("t", format!("{:.3}", c.t)),
            ("cmd", pose.clone()),
            ("enc", pose),
            ("exp", "file".to_string()),
        ];
        if let Some(s) = c.sub {
            fields.push(("sub", format!("{s:.4}")));
        }
        if let Some(e) = c.exposure {
            fields.push(("exposure", format!("{e}")));
        }
        if replay {
            fields.push(("replay", "1".to_string()));
        }
        self.send("CAPTURE", &fields);
    }

    fn announce_new(&mut self) {
        if !self.subscribed {
            return;
        }
        while self.announced < self.captures.len() {
            self.capture(self.announced, false);
            self.announced += 1;
        }
    }

    /// The link opened: a controller that has just booted introduces itself.
    pub fn handle_connect(&mut self) {
        self.subscribed = false;
        self.announced = 0;
        self.seq = 0;
        self.out.clear();
        self.ident();
    }

    /// One line from the daemon.
    pub fn handle_line(&mut self, line: &str) {
        let Ok(m) = parse(line) else {
            self.send("NAK", &[("ref", "-1".into()), ("reason", "bad-crc".into())]);
            return;
        };
        let r = m.seq.to_string();
        let command = match ToController::from_message(&m) {
            Ok(c) => c,
            Err(e) => {
                self.send("NAK", &[("ref", r), ("reason", e.nak_reason().into())]);
                return;
            }
        };
        match command {
            ToController::Hello { .. } => self.ident(),
            ToController::Subscribe => {
                self.send("ACK", &[("ref", r)]);
                self.status();
                self.subscribed = true;
                // announced before the subscription: the daemon asks with RESYNC
                self.announced = self.captures.len();
            }
            ToController::Resync { from } => {
                let from = usize::try_from(from).unwrap_or(usize::MAX);
                let upto = if self.subscribed {
                    self.announced
                } else {
                    self.captures.len()
                };
                for idx in from..upto {
                    self.capture(idx, true);
                }
                let count = upto.saturating_sub(from);
                let fields = [
                    ("ref", r),
                    ("count", count.to_string()),
                    ("next", upto.to_string()),
                    ("state", self.state().to_string()),
                ];
                self.send("ACK", &fields);
            }
            // a folder has no arm to pause, probe or read
            ToController::Pause
            | ToController::Resume
            | ToController::Probe { .. }
            | ToController::PoseQuery => {
                self.send("NAK", &[("ref", r), ("reason", "refused".into())]);
            }
        }
    }

    /// A capture file is ready (in acquisition order).
    pub fn handle_capture(&mut self, capture: ArchiveCapture) {
        if self.done.is_some() {
            return;
        }
        self.captures.push(capture);
        self.announce_new();
    }

    /// The set is complete: no further capture will come.
    pub fn handle_end(&mut self) {
        if self.done.is_none() {
            self.done = Some(self.now());
            if self.subscribed {
                self.status();
            }
        }
    }

    /// The next line to send to the daemon.
    pub fn poll_line(&mut self) -> Option<String> {
        self.out.pop_front()
    }

    pub fn captures(&self) -> usize {
        self.captures.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{parse_message, FromController};

    fn capture(entry: usize, t: f64) -> ArchiveCapture {
        ArchiveCapture {
            file: format!("c{entry}.hdr"),
            entry,
            t,
            pose: [0.0, 90.0, -90.0, 15.0],
            sub: None,
            exposure: None,
        }
    }

    fn drain(c: &mut ArchiveController) -> Vec<FromController> {
        std::iter::from_fn(|| c.poll_line())
            .map(|l| parse_message(&l).unwrap().message)
            .collect()
    }

    fn daemon(seq: u32, command: ToController) -> String {
        command.encode(seq)
    }

    #[test]
    fn it_speaks_the_controller_side_of_the_protocol() {
        let mut c = ArchiveController::new("set", 6561);
        c.handle_connect();
        c.handle_capture(capture(0, 0.0));
        c.handle_capture(capture(1, 7.0));
        let first = drain(&mut c);
        assert!(
            matches!(&first[..], [FromController::Ident(i)] if i.captures == Some(6561) && i.rig.as_deref() == Some(RIG_ID))
        );
        // nothing is announced before the subscription; RESYNC gives what there is
        c.handle_line(&daemon(0, ToController::Subscribe));
        let sub = drain(&mut c);
        assert!(
            matches!(&sub[..], [FromController::Ack(_), FromController::Status(s)] if s.state.as_deref() == Some("running") && s.next == Some(2))
        );
        c.handle_line(&daemon(1, ToController::Resync { from: 0 }));
        let rs = drain(&mut c);
        assert_eq!(rs.len(), 3);
        assert!(matches!(&rs[0], FromController::Capture(a) if a.idx == 0 && a.replay));
        assert!(matches!(&rs[2], FromController::Ack(a) if a.next == Some(2)));
        // new captures go out at once; the end is a STATUS done
        c.handle_capture(capture(5, 14.0));
        c.handle_end();
        let tail = drain(&mut c);
        assert!(matches!(&tail[0], FromController::Capture(a) if a.idx == 2 && !a.replay));
        assert!(
            matches!(&tail[1], FromController::Status(s) if s.state.as_deref() == Some("done") && s.next == Some(3))
        );
        // what needs a rig is refused; a garbled line gets a bad-crc NAK
        c.handle_line(&daemon(2, ToController::Pause));
        c.handle_line(&daemon(3, ToController::Probe { entry: 4 }));
        c.handle_line("garbage");
        // a verb the protocol does not have, and a RESYNC without its index
        c.handle_line(&format(4, "DANCE", &[]));
        c.handle_line(&format(5, "RESYNC", &[]));
        let naks = drain(&mut c);
        assert_eq!(naks.len(), 5);
        let reasons: Vec<&str> = naks
            .iter()
            .map(|m| match m {
                FromController::Nak(n) => n.reason.as_deref().unwrap_or("?"),
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(
            reasons,
            ["refused", "refused", "bad-crc", "unknown-verb", "bad-args"]
        );
        // a capture after the end is ignored
        c.handle_capture(capture(9, 99.0));
        assert_eq!(c.captures(), 3);
    }
}
