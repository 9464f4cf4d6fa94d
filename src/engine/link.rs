//! The engine's link to the controller: where the link stands (`LinkState`, with its legal
//! transitions), the sequence numbers both ways, who the controller is, the resync in progress,
//! the window of corrupt lines, and the link counters. Pure state; the engine decides.

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Where the link to the controller stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) enum LinkState {
    /// No port yet: before the first connection and after a daemon restart (not a fault: the
    /// port is being opened).
    #[default]
    Closed,
    /// The port was lost (EOF, EIO, unplugged): reconnecting.
    Lost,
    /// The port is open and HELLO sent; the controller has not accepted a subscription yet.
    Greeting,
    /// Subscribed: the controller sends its events.
    Subscribed,
}

/// The resync in progress and its backoff.
#[derive(Debug, Clone, Default)]
pub(super) struct Resync {
    /// The sequence number of the RESYNC awaiting its ACK.
    pub(super) outstanding: Option<u32>,
    /// Lines received since it was sent that were not part of its answer.
    pub(super) age: u32,
    /// A RESYNC is needed as soon as the link and the backoff allow.
    pub(super) needed: bool,
    /// A sequence gap came while one was outstanding: its ACK cannot vouch for what is below
    /// its `next`.
    pub(super) gap_during: bool,
    /// Lines received since the last RESYNC was sent (the backoff's clock).
    pub(super) lines_since: u64,
    /// The `from` of the last RESYNC sent, and how many times in a row it was sent.
    pub(super) last: Option<(u64, u32)>,
    /// The RESYNCs sent on this connection since one was answered (at most `UNANSWERED_MAX`,
    /// the latest): an ACK of any of them answers.
    pub(super) unanswered: Vec<u32>,
}

/// RESYNCs remembered as unanswered, at most.
const UNANSWERED_MAX: usize = 64;

impl Resync {
    /// A RESYNC was sent with sequence number `seq`.
    pub(super) fn note_sent(&mut self, seq: u32) {
        self.unanswered.push(seq);
        if self.unanswered.len() > UNANSWERED_MAX {
            self.unanswered.remove(0);
        }
    }

    /// Whether an ACK of `reference` answers a RESYNC of this connection.
    pub(super) fn answers(&self, reference: u32) -> bool {
        self.outstanding == Some(reference) || self.unanswered.contains(&reference)
    }

    /// A new conversation or none: earlier sequence numbers mean nothing.
    fn forget(&mut self) {
        self.outstanding = None;
        self.unanswered.clear();
    }
}

/// Which of the latest lines were corrupt, and whether the CRC alarm is raised.
#[derive(Debug, Clone, Default)]
pub(super) struct CrcWindow {
    recent: VecDeque<bool>,
    pub(super) active: bool,
}

impl CrcWindow {
    /// Note one line; returns (corrupt lines, window length) when the alarm is to be raised
    /// now. The alarm clears once the window holds no corrupt line.
    pub(super) fn note(
        &mut self,
        bad: bool,
        window: usize,
        threshold: usize,
    ) -> Option<(usize, usize)> {
        self.recent.push_back(bad);
        while self.recent.len() > window {
            self.recent.pop_front();
        }
        let n_bad = self.recent.iter().filter(|b| **b).count();
        if !self.active && n_bad >= threshold {
            self.active = true;
            return Some((n_bad, self.recent.len()));
        }
        if self.active && n_bad == 0 {
            self.active = false;
        }
        None
    }
}

/// The link.
#[derive(Debug, Clone, Default)]
pub(super) struct Link {
    state: LinkState,
    /// The next sequence number to send.
    pub(super) tx_seq: u32,
    /// The sequence number the next received line should carry.
    pub(super) expect_seq: Option<u32>,
    pub(super) boot: Option<u64>,
    pub(super) session: Option<String>,
    pub(super) rig_id: Option<String>,
    /// The controller speaks another protocol version: goniowatch only listens.
    pub(super) version_refused: bool,
    pub(super) resync: Resync,
    pub(super) crc: CrcWindow,
    pub(super) stats: LinkStats,
}

impl Link {
    pub(super) fn is_connected(&self) -> bool {
        matches!(self.state, LinkState::Greeting | LinkState::Subscribed)
    }

    /// The port was lost and has not been opened again since (a daemon restart forgets it).
    pub(super) fn is_lost(&self) -> bool {
        self.state == LinkState::Lost
    }

    pub(super) fn is_subscribed(&self) -> bool {
        self.state == LinkState::Subscribed
    }

    /// The port was opened: a new conversation (HELLO next), sequence numbers from 0.
    pub(super) fn opened(&mut self) {
        self.state = LinkState::Greeting;
        self.stats.connects += 1;
        self.expect_seq = None;
        self.resync.forget();
        self.tx_seq = 0;
    }

    /// The port was lost.
    pub(super) fn lost(&mut self) {
        self.state = LinkState::Lost;
        self.resync.forget();
    }

    /// The daemon restarted on the session: no port, no conversation.
    pub(super) fn restarted(&mut self) {
        self.stats.restarts += 1;
        self.state = LinkState::Closed;
        self.resync.forget();
        self.expect_seq = None;
    }

    /// The controller took our subscription (only an open port can be subscribed).
    pub(super) fn subscribed(&mut self) {
        if self.is_connected() {
            self.state = LinkState::Subscribed;
        }
    }
}

/// Link counters (part of the summary; they depend on the traffic, so a resumed session's
/// differ from an uninterrupted one's).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkStats {
    pub lines: u64,
    pub bytes: u64,
    pub crc_errors: u64,
    pub framing_errors: u64,
    pub sequence_gaps: u64,
    pub connects: u64,
    pub disconnects: u64,
    pub reboots: u64,
    pub resyncs: u64,
    pub unknown_verbs: u64,
    pub naks: u64,
    pub duplicate_announcements: u64,
    pub restarts: u64,
}
