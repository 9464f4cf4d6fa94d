//! The engine's capture ledger: which captures the controller announced, which outcomes wait in
//! the reorder buffer, which indices are known to be missing or were refused, and how far the
//! checks have got. Captures go to the checker strictly in index order from here.

use crate::checks::Outcome;
use crate::protocol::Announcement;
use std::collections::{BTreeMap, BTreeSet};

#[derive(Debug, Clone, Default)]
pub(super) struct Ledger {
    /// Every accepted announcement, by capture index.
    pub(super) announced: BTreeMap<u64, Announcement>,
    /// Outcomes of captures not yet checked (the reorder buffer).
    pub(super) outcomes: BTreeMap<u64, Outcome>,
    /// Indices the controller's log does not have, or whose announcement was refused: skipped.
    pub(super) missing: BTreeSet<u64>,
    /// Indices whose CAPTURE line could not be accepted, and how many times.
    pub(super) refused: BTreeMap<u64, u32>,
    /// Refused indices a clean resync passed over without a readable line: asked once more.
    pub(super) resend_asked: BTreeSet<u64>,
    /// Checked captures whose file failed to decode or never appeared.
    pub(super) unusable: BTreeSet<u64>,
    /// The next index to check.
    pub(super) next_check: u64,
    /// The controller's next index, as far as it has told.
    pub(super) controller_next: u64,
}

impl Ledger {
    /// The lowest capture index neither announced nor known to be missing.
    pub(super) fn lowest_unseen(&self) -> u64 {
        let mut i = self.next_check;
        while self.announced.contains_key(&i) || self.missing.contains(&i) {
            i += 1;
        }
        i
    }

    /// Announced captures still waiting for an outcome.
    pub(super) fn pending_ingest(&self) -> Vec<(u64, String)> {
        self.announced
            .range(self.next_check..)
            .filter(|(i, _)| !self.outcomes.contains_key(i))
            .map(|(i, a)| (*i, a.file.clone()))
            .collect()
    }
}
