//! Watch mode's memory of a capture folder between listings: which files were announced as
//! which captures, what they looked like then, and what became of them.
//!
//! A pure state machine: `handle_listing` for each listing of the folder (with each file's size
//! and modification time), `handle_outcome` for the ingestion's verdict on a capture. From a
//! listing it gives the captures to announce, in the listing's order:
//!
//! - a file placed on a plan entry no capture stands for yet;
//! - a file announced before that changed since, when its capture failed or its file never
//!   appeared (a file written in two halves, a sidecar row written before its file), or, for a
//!   usable capture, when its content is no longer what was checked (a retake written over it).
//!   Such a recheck is a new capture of the same entry; the checks keep the first usable one
//!   and the retake list drops a failed capture whose entry was taken again. At most
//!   [`MAX_RECHECKS`] per file.
//!
//! Times count from the first listing's origin for the whole session (a later listing's
//! earliest file does not move it). A file time earlier than the capture announced before it
//! (a clock set back, times copied with the files) is a step back: the follower removes it
//! from that capture's time on, on its own time line (the announced times never go back, nor
//! below 0), and reports it for the engine to alarm. Positions as times (no time source) count
//! the announced captures.

use super::listing::{ArchiveCapture, DuplicateGroup, Listing, TimeSource};
use crate::measure::timeline::{StepBack, TimeLine};
use std::collections::BTreeMap;

/// How often one file is checked again after it changed.
pub(crate) const MAX_RECHECKS: u32 = 5;

/// What a listing says of a file: its size and modification time; `None` when it is absent.
pub(crate) type Fingerprint = Option<(u64, Option<f64>)>;

#[derive(Debug, Clone, PartialEq)]
enum Seen {
    /// As at the listing that announced it.
    At(Fingerprint),
    /// Announced before a restart: not known.
    Unknown,
}

#[derive(Debug, Clone, PartialEq)]
enum Verdict {
    Waiting,
    /// Checked; the SHA-256 of the bytes checked, when known.
    Usable(Option<String>),
    /// Failed to decode or never appeared.
    Unusable,
}

#[derive(Debug, Clone)]
struct Followed {
    entry: usize,
    idx: u64,
    seen: Seen,
    verdict: Verdict,
    rechecks: u32,
}

/// What one listing asks of the link.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Step {
    /// Captures to announce, in order; `idx` is the capture index each will get.
    pub announce: Vec<(u64, ArchiveCapture)>,
    /// How many of `announce` are rechecks of a file announced before.
    pub rechecks: usize,
    /// Duplicate groups not reported before (or changed since).
    pub duplicates: Vec<DuplicateGroup>,
    /// Steps back of the file times, by the capture index they came at.
    pub steps_back: Vec<(u64, StepBack)>,
}

#[derive(Debug, Clone, Default)]
pub(crate) struct Follower {
    /// The absolute time the session's capture times count from.
    origin: Option<f64>,
    files: BTreeMap<String, Followed>,
    by_entry: BTreeMap<usize, String>,
    by_idx: BTreeMap<u64, String>,
    next_idx: u64,
    last_t: f64,
    timeline: TimeLine,
    reported: BTreeMap<usize, DuplicateGroup>,
}

impl Follower {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// A capture announced before a restart, in index order (its `t` on the session's time
    /// line); `usable` is what the session knows of it. The journal does not hold the first
    /// capture's absolute time: the origin is taken from the first listing, as for a new
    /// session (the same while the earliest file is the same). Returns false, and takes nothing more,
    /// once the indices are not consecutive from 0.
    pub(crate) fn handle_prior(
        &mut self,
        idx: u64,
        capture: &ArchiveCapture,
        usable: Option<bool>,
    ) -> bool {
        if idx != self.next_idx {
            return false;
        }
        let verdict = match usable {
            Some(true) => Verdict::Usable(None),
            Some(false) => Verdict::Unusable,
            None => Verdict::Waiting,
        };
        self.follow(idx, capture, Seen::Unknown, verdict);
        self.next_idx += 1;
        self.last_t = self.last_t.max(capture.t);
        self.timeline.handle_capture(capture.t);
        true
    }

    /// Remember that `c`'s file was announced as capture `idx` (a file announced again keeps
    /// its count of rechecks; its entry keeps its first file).
    fn follow(&mut self, idx: u64, c: &ArchiveCapture, seen: Seen, verdict: Verdict) {
        let rechecks = self.files.get(&c.file).map_or(0, |f| f.rechecks);
        self.files.insert(
            c.file.clone(),
            Followed {
                entry: c.entry,
                idx,
                seen,
                verdict,
                rechecks,
            },
        );
        self.by_entry
            .entry(c.entry)
            .or_insert_with(|| c.file.clone());
        self.by_idx.insert(idx, c.file.clone());
    }

    /// The ingestion's verdict on capture `idx`: `Some(sha256)` of the bytes checked when it
    /// decoded, `None` when it failed or its file never appeared.
    pub(crate) fn handle_outcome(&mut self, idx: u64, checked: Option<String>) {
        let Some(name) = self.by_idx.get(&idx) else {
            return;
        };
        if let Some(f) = self.files.get_mut(name) {
            if f.idx == idx {
                f.verdict = match checked {
                    Some(sha) => Verdict::Usable(Some(sha)),
                    None => Verdict::Unusable,
                };
            }
        }
    }

    /// One listing of the folder. `prints`: each listed file's fingerprint; `content`: the
    /// SHA-256 of a file's bytes now (asked only of a usable capture's file that changed).
    pub(crate) fn handle_listing(
        &mut self,
        listing: &Listing,
        prints: &BTreeMap<String, (u64, Option<f64>)>,
        content: &mut dyn FnMut(&str) -> Option<String>,
    ) -> Step {
        let mut step = Step::default();
        if self.origin.is_none() && !listing.captures.is_empty() {
            self.origin = Some(listing.origin_s);
        }
        let origin = self.origin.unwrap_or(listing.origin_s);
        for c in &listing.captures {
            let print: Fingerprint = prints.get(&c.file).copied();
            let recheck = match self.files.get_mut(&c.file) {
                None if self.by_entry.contains_key(&c.entry) => continue,
                None => false,
                Some(f) if f.rechecks >= MAX_RECHECKS || f.entry != c.entry => continue,
                Some(f) => {
                    let changed = match &f.seen {
                        Seen::At(p) => *p != print,
                        Seen::Unknown => print.is_some(),
                    };
                    let again = match &f.verdict {
                        Verdict::Waiting => false,
                        Verdict::Unusable => changed && print.is_some(),
                        Verdict::Usable(Some(sha)) if changed => {
                            let differs = content(&c.file).is_some_and(|now| now != *sha);
                            if !differs {
                                // touched, not rewritten: not hashed again until it changes
                                f.seen = Seen::At(print);
                            }
                            differs
                        }
                        Verdict::Usable(_) => false,
                    };
                    if !again {
                        continue;
                    }
                    true
                }
            };
            let idx = self.next_idx;
            let mut capture = c.clone();
            capture.t = match listing.times {
                TimeSource::Index {
                    seconds_per_capture,
                } => idx as f64 * seconds_per_capture,
                // a file checked again is a later capture: it keeps the time line going
                _ if recheck => self.last_t,
                _ => {
                    let (t, back) = self
                        .timeline
                        .handle_capture(c.t + listing.origin_s - origin);
                    if let Some(back) = back {
                        step.steps_back.push((idx, back));
                    }
                    t.max(0.0)
                }
            };
            if recheck {
                if let Some(f) = self.files.get_mut(&c.file) {
                    f.rechecks += 1;
                }
                step.rechecks += 1;
            }
            self.next_idx += 1;
            self.last_t = self.last_t.max(capture.t);
            self.follow(idx, &capture, Seen::At(print), Verdict::Waiting);
            step.announce.push((idx, capture));
        }
        for g in &listing.duplicates {
            let group = match self.by_entry.get(&g.entry) {
                Some(checked) if *checked != g.kept => {
                    let mut others: Vec<String> = std::iter::once(g.kept.clone())
                        .chain(g.others.iter().cloned())
                        .filter(|n| n != checked)
                        .collect();
                    others.sort();
                    DuplicateGroup {
                        entry: g.entry,
                        kept: checked.clone(),
                        others,
                        rule_prefers: Some(g.kept.clone()),
                    }
                }
                _ => g.clone(),
            };
            if self.reported.get(&g.entry) != Some(&group) {
                self.reported.insert(g.entry, group.clone());
                step.duplicates.push(group);
            }
        }
        step
    }

    /// Whether every one of `planned` entries has a capture announced.
    pub(crate) fn complete(&self, planned: usize) -> bool {
        self.by_entry.len() >= planned
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::archive::OrderRule;

    fn cap(file: &str, entry: usize, t: f64) -> ArchiveCapture {
        ArchiveCapture {
            file: file.into(),
            entry,
            t,
            pose: [0.0, 90.0, -90.0, 15.0],
            sub: None,
            exposure: None,
        }
    }

    fn listing(captures: Vec<ArchiveCapture>, origin_s: f64, times: TimeSource) -> Listing {
        Listing {
            captures,
            origin_s,
            duplicates: Vec::new(),
            skipped: Vec::new(),
            order: OrderRule::Mtime,
            times,
            unfilled: Vec::new(),
        }
    }

    fn prints(v: &[(&str, u64, f64)]) -> BTreeMap<String, (u64, Option<f64>)> {
        v.iter()
            .map(|(n, s, m)| (n.to_string(), (*s, Some(*m))))
            .collect()
    }

    fn no_content(_: &str) -> Option<String> {
        None
    }

    #[test]
    fn new_files_are_announced_once_with_times_from_the_first_origin() {
        let mut f = Follower::new();
        let l = listing(
            vec![cap("a", 0, 0.0), cap("b", 1, 7.0)],
            1000.0,
            TimeSource::Mtime,
        );
        let s = f.handle_listing(
            &l,
            &prints(&[("a", 5, 1000.0), ("b", 5, 1007.0)]),
            &mut no_content,
        );
        assert_eq!(
            s.announce
                .iter()
                .map(|(i, c)| (*i, c.t))
                .collect::<Vec<_>>(),
            [(0, 0.0), (1, 7.0)]
        );
        // a later listing whose earliest file is earlier (a clock set back): the origin holds
        let l = listing(
            vec![cap("c", 2, 0.0), cap("a", 0, 3590.0), cap("b", 1, 3597.0)],
            -2590.0,
            TimeSource::Mtime,
        );
        let p = prints(&[("a", 5, 1000.0), ("b", 5, 1007.0), ("c", 5, -2590.0)]);
        let s = f.handle_listing(&l, &p, &mut no_content);
        assert_eq!(s.announce.len(), 1);
        // the step is removed (the time line goes on from b's 7 s) and reported
        assert_eq!((s.announce[0].0, s.announce[0].1.t), (2, 7.0));
        assert_eq!(s.steps_back.len(), 1);
        let (at, back) = s.steps_back[0];
        assert_eq!(
            (at, back.step_s, back.announced_s, back.previous_s),
            (2, 3597.0, -3590.0, 7.0)
        );
        let again = f.handle_listing(&l, &p, &mut no_content);
        assert!(again.announce.is_empty() && again.steps_back.is_empty());
        // files after the step keep their spacing
        let mut l2 = l.clone();
        l2.captures.push(cap("d", 3, 7.0));
        let mut p2 = p.clone();
        p2.insert("d".into(), (5, Some(-2583.0)));
        let s = f.handle_listing(&l2, &p2, &mut no_content);
        assert_eq!((s.announce[0].0, s.announce[0].1.t), (3, 14.0));
        assert!(s.steps_back.is_empty());
    }

    #[test]
    fn a_failed_or_missing_capture_is_checked_again_when_its_file_changes() {
        let mut f = Follower::new();
        let idx = TimeSource::Index {
            seconds_per_capture: 7.0,
        };
        let l = listing(vec![cap("a", 0, 0.0), cap("b", 1, 7.0)], 0.0, idx);
        // b is a sidecar row whose file is not there yet
        let s = f.handle_listing(&l, &prints(&[("a", 100, 1.0)]), &mut no_content);
        assert_eq!(s.announce.len(), 2);
        f.handle_outcome(0, None); // a: half written, failed
        f.handle_outcome(1, None); // b: missing
                                   // nothing changed: nothing again
        assert!(f
            .handle_listing(&l, &prints(&[("a", 100, 1.0)]), &mut no_content)
            .announce
            .is_empty());
        // a is complete, b appears
        let p = prints(&[("a", 200, 1.6), ("b", 200, 5.0)]);
        let s = f.handle_listing(&l, &p, &mut no_content);
        assert_eq!(s.rechecks, 2);
        assert_eq!(
            s.announce
                .iter()
                .map(|(i, c)| (*i, c.file.as_str(), c.entry, c.t))
                .collect::<Vec<_>>(),
            [(2, "a", 0, 14.0), (3, "b", 1, 21.0)]
        );
        // both check out now: no more
        f.handle_outcome(2, Some("x".into()));
        f.handle_outcome(3, Some("y".into()));
        assert!(f
            .handle_listing(&l, &p, &mut no_content)
            .announce
            .is_empty());
    }

    #[test]
    fn a_usable_capture_is_checked_again_only_when_its_content_changed() {
        let mut f = Follower::new();
        let l = listing(vec![cap("a", 0, 0.0)], 0.0, TimeSource::Mtime);
        f.handle_listing(&l, &prints(&[("a", 100, 1.0)]), &mut no_content);
        f.handle_outcome(0, Some("sha-a".into()));
        // touched, same bytes: not again
        let mut same = |_: &str| Some("sha-a".to_string());
        assert!(f
            .handle_listing(&l, &prints(&[("a", 100, 9.0)]), &mut same)
            .announce
            .is_empty());
        // written over with a retake
        let mut other = |_: &str| Some("sha-b".to_string());
        let s = f.handle_listing(&l, &prints(&[("a", 100, 12.0)]), &mut other);
        assert_eq!(s.rechecks, 1);
    }

    #[test]
    fn a_file_that_keeps_failing_is_checked_again_at_most_max_rechecks_times() {
        let mut f = Follower::new();
        let l = listing(vec![cap("a", 0, 0.0)], 0.0, TimeSource::Mtime);
        let mut announced = 0;
        for k in 0..20u64 {
            let s = f.handle_listing(&l, &prints(&[("a", 100 + k, k as f64)]), &mut no_content);
            for (i, _) in &s.announce {
                f.handle_outcome(*i, None);
            }
            announced += s.announce.len();
        }
        assert_eq!(announced as u32, 1 + MAX_RECHECKS);
    }

    #[test]
    fn another_file_for_an_announced_entry_is_a_reported_duplicate() {
        let mut f = Follower::new();
        let l = listing(vec![cap("sub/x.hdr", 4, 0.0)], 0.0, TimeSource::Mtime);
        f.handle_listing(&l, &prints(&[("sub/x.hdr", 1, 0.0)]), &mut no_content);
        // x.hdr at the top level arrives: the rule prefers it, the checked one stays
        let mut l = listing(vec![cap("x.hdr", 4, 5.0)], 0.0, TimeSource::Mtime);
        l.duplicates = vec![DuplicateGroup {
            entry: 4,
            kept: "x.hdr".into(),
            others: vec!["sub/x.hdr".into()],
            rule_prefers: None,
        }];
        let p = prints(&[("sub/x.hdr", 1, 0.0), ("x.hdr", 1, 5.0)]);
        let s = f.handle_listing(&l, &p, &mut no_content);
        assert!(s.announce.is_empty());
        assert_eq!(
            s.duplicates,
            [DuplicateGroup {
                entry: 4,
                kept: "sub/x.hdr".into(),
                others: vec!["x.hdr".into()],
                rule_prefers: Some("x.hdr".into()),
            }]
        );
        // said once
        assert!(f
            .handle_listing(&l, &p, &mut no_content)
            .duplicates
            .is_empty());
    }

    #[test]
    fn a_resumed_follower_numbers_on_from_the_captures_before() {
        let mut f = Follower::new();
        assert!(f.handle_prior(0, &cap("a", 0, 0.0), Some(true)));
        assert!(f.handle_prior(1, &cap("b", 1, 7.0), Some(false)));
        assert!(!f.handle_prior(5, &cap("c", 2, 9.0), None));
        let idx = TimeSource::Index {
            seconds_per_capture: 7.0,
        };
        let l = listing(
            vec![cap("a", 0, 0.0), cap("b", 1, 7.0), cap("d", 3, 14.0)],
            0.0,
            idx,
        );
        let s = f.handle_listing(
            &l,
            &prints(&[("a", 1, 0.0), ("b", 1, 0.0), ("d", 1, 0.0)]),
            &mut no_content,
        );
        // b failed before the restart and is there: checked again; d is new
        assert_eq!(
            s.announce
                .iter()
                .map(|(i, c)| (*i, c.file.as_str()))
                .collect::<Vec<_>>(),
            [(2, "b"), (3, "d")]
        );
        assert!(!f.complete(5));
    }
}
