//! The session engine: a deterministic state machine between the shell and the checks.
//!
//! It consumes the session's inputs in the order the shell received them (serial lines, link
//! events, capture outcomes), and returns what to do: lines to send, captures to ingest, and the
//! records to append to the results. It holds no clock, file or port, so feeding it the journal
//! of a session reproduces that session's results byte for byte (replay, crash recovery).
//!
//! Protocol handling follows docs/protocol.md: HELLO on connect, SUBSCRIBE + RESYNC after IDENT,
//! RESYNC after a sequence gap, a capture-index gap or a reboot; CAPTURE lines are keyed by index
//! (idempotent). Outcomes are handed to the checker in capture-index order.

use crate::checks::{
    CaptureInput, CaptureRecord, CaptureStatus, CheckCounts, Checker, IsotropyRecord, Outcome,
    PairRecord, ProbeSetup, Table2,
};
mod alarms;
mod ledger;
mod link;
mod probes;

use crate::checks::alarm::{Alarm, AlarmCode, AlarmKind, Severity};
use crate::checks::evidence::{self, Evidence};
use crate::config::{AlarmSpec, Config, ConfigError};
use crate::protocol::{
    self, Ack, Announcement, FromController, Ident, LineError, Nak, Status, ToController,
    PROTO_VERSION,
};
use crate::setup::Setup;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// An input of the engine; also the unit of the session journal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum Input {
    /// The serial port was opened.
    Connected,
    /// The serial port was lost (EOF, EIO, unplugged).
    Disconnected { reason: String },
    /// One received line, without its LF.
    Rx { line: String },
    /// A received line that could not even be framed (too long, not UTF-8).
    RxBad { reason: String },
    /// The ingestion's verdict on an announced capture.
    Outcome { idx: u64, outcome: Outcome },
    /// Files in the session's capture folder that no CAPTURE line announced.
    Unannounced { files: Vec<String> },
    /// A files source placed more than one file on these plan entries (the listing's
    /// duplicate rule kept one of each).
    Duplicates {
        groups: Vec<crate::archive::listing::DuplicateGroup>,
    },
    /// A files source found that the times of its files went back at capture `idx` and
    /// removed the step from that capture's time on (the engine alarms it when `idx` is checked).
    TimeSteppedBack {
        idx: u64,
        step: crate::measure::timeline::StepBack,
    },
    /// A files source's final listing: the files it did not place, with why (at most as many
    /// as a journal line holds), and how many there are of each reason's kind.
    Skipped {
        files: Vec<(String, crate::archive::listing::SkipReason)>,
        counts: BTreeMap<String, u64>,
    },
    /// The daemon restarted on an existing session (after a crash or a stop).
    Restart,
    /// Nothing arrived from the controller for a while (the shell's clock decides how long);
    /// the engine asks again where the controller stands, in case a reply or the final STATUS
    /// was lost.
    Idle,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ManifestRecord {
    pub idx: u64,
    pub file: String,
    pub status: crate::checks::CaptureStatus,
    pub size: Option<u64>,
    pub sha256: Option<String>,
    pub error: Option<String>,
}

/// What the shell must do or record.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    Send(String),
    Ingest {
        idx: u64,
        file: String,
    },
    Capture(CaptureRecord),
    Pair(PairRecord),
    Isotropy(IsotropyRecord),
    Sweep(crate::detect::sweeps::SweepRecord),
    Alarm(Alarm),
    Manifest(ManifestRecord),
    /// The drift probes' pose was chosen (no `[probes] entry` configured); probes follow.
    ProbePose(crate::detect::probes::ProbePose),
    /// The joint-3 sentinel's pose was chosen (anisotropic sample with probes); every probe is
    /// followed by a sentinel probe of it.
    SentinelPose(crate::detect::sentinel::SentinelPose),
    /// Every capture the controller announced as taken is checked and the run is done.
    Finished,
}

pub(crate) use link::LinkStats;

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub session: Option<String>,
    pub rig: Option<String>,
    pub captures_planned: u64,
    pub captures_announced: u64,
    /// Plan entries no announced capture stands for (a file source's entries without a file,
    /// a run that ended early): once the session is finished they will not be captured.
    #[serde(default)]
    pub entries_not_captured: u64,
    /// A files source: files under the capture folder that were not placed as captures, by
    /// reason (`SkipReason::kind`; files left out by the duplicate rule included).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub files_skipped: BTreeMap<String, u64>,
    /// A files source: plan entries more than one file was placed on (one of them is checked).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub entries_with_duplicates: u64,
    pub checked: CheckCounts,
    pub table2: Table2,
    pub isotropy: Table2,
    /// Table 2 over the occlusion substitutes' interpolated pairs.
    #[serde(default)]
    pub interpolated: Table2,
    /// Table 2 over the exact pairs with a capture placed by the commanded pose during a steady
    /// encoder offset (a subset of `table2`; absent when there are none).
    #[serde(default, skip_serializing_if = "Table2::is_empty")]
    pub by_command: Table2,
    /// Gain drift estimate from the probes (%/h), when probes are enabled.
    pub probe_drift: Option<crate::detect::drift::DriftEstimate>,
    /// The pose the daemon chose for the probes (none configured), once chosen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe_pose: Option<crate::detect::probes::ProbePose>,
    /// Arm joint 3 from the sentinel probes (anisotropic samples with probes), once chosen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint3_sentinel: Option<crate::detect::sentinel::SentinelSummary>,
    /// Gain drift estimate from isotropy classes (isotropic samples).
    #[serde(default)]
    pub isotropy_drift: Option<crate::detect::drift::DriftEstimate>,
    /// The lamp's colour drift: from isotropy classes (isotropic samples), else from the probes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour_drift: Option<crate::checks::ColourDriftEstimate>,
    /// What the session's detectors watch and cannot see, with remedies.
    #[serde(default)]
    pub observability: crate::checks::observability::Observability,
    /// Gain steps the light sweeps found, as fitted in the isotropy drift model.
    #[serde(default)]
    pub isotropy_steps: Vec<crate::detect::drift::StepEffect>,
    /// The off-centre mount's pattern, once the isotropy drift model carries it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_off_centre: Option<crate::detect::drift::MountPattern>,
    /// The light-sweep checks (isotropic samples in a light-outer order).
    #[serde(default)]
    pub sweeps: Option<crate::detect::sweeps::SweepSummary>,
    pub alarms: BTreeMap<String, u64>,
    /// Captures that raised `dark-capture` (not in the summary file: its counts are per kind).
    #[serde(skip)]
    pub dark_captures: u64,
    pub link: LinkStats,
    pub finished: bool,
}

pub struct Engine {
    checker: Checker,
    spec: AlarmSpec,
    link: link::Link,
    ledger: ledger::Ledger,
    done: bool,
    finished: bool,
    /// Controller time of the last checked capture (the time of end-of-session results).
    last_t: f64,
    /// Capture times in check order, with steps back removed.
    timeline: crate::measure::timeline::TimeLine,
    /// Steps back that a files source removed from its times, by the capture they came at.
    steps_back: BTreeMap<u64, crate::measure::timeline::StepBack>,
    /// A files source's files not placed, by reason's kind (its last listing).
    files_skipped: BTreeMap<String, u64>,
    /// Plan entries a files source placed more than one file on.
    duplicate_entries: BTreeSet<usize>,
    alarm_book: alarms::AlarmBook,
    paused_for: BTreeSet<AlarmCode>,
    captures_planned: u64,
    /// When a probe round is asked for (what it holds is the checker's).
    probes: probes::ProbeCadence,
    /// The sequence numbers of the last probe round's `PROBE` commands: a `NAK` of one of them
    /// that refuses it withdraws the probes.
    probe_requests: Vec<u32>,
    /// Inputs handled so far (the alarm aggregation's clock).
    inputs: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// The alarm for the files a files source did not place, when any is not a duplicate (those
/// have their own alarm).
fn skipped_alarm(
    files: &[(String, crate::archive::listing::SkipReason)],
    counts: &BTreeMap<String, u64>,
) -> Option<Alarm> {
    use crate::archive::listing::SkipReason;
    let total: u64 = counts
        .iter()
        .filter(|(k, _)| k.as_str() != "duplicate")
        .map(|(_, n)| n)
        .sum();
    if total == 0 {
        return None;
    }
    let listed: Vec<&(String, SkipReason)> = files
        .iter()
        .filter(|(_, r)| !matches!(r, SkipReason::Duplicate { .. }))
        .collect();
    let by_kind = counts
        .iter()
        .filter(|(k, _)| k.as_str() != "duplicate")
        .map(|(k, n)| format!("{n} {k}"))
        .collect::<Vec<_>>()
        .join(", ");
    let first = listed
        .iter()
        .take(3)
        .map(|(f, r)| format!("{f} ({r})"))
        .collect::<Vec<_>>()
        .join("; ");
    // files of other types (notes, thumbnails) are said, not warned of
    let severity = if counts
        .keys()
        .all(|k| k == "duplicate" || k == "not-a-capture")
    {
        Severity::Info
    } else {
        Severity::Warning
    };
    Some(
        Alarm::new(
            AlarmKind::CaptureQuality,
            severity,
            AlarmCode::SkippedFiles,
            format!("{total} file(s) under the capture folder were not placed as captures ({by_kind}): {first}"),
        )
        .with(Evidence::SkippedFiles(evidence::SkippedFiles {
            counts: counts.clone(),
            files: listed
                .iter()
                .map(|(f, r)| evidence::SkippedFile {
                    file: f.clone(),
                    kind: r.kind().to_string(),
                    why: r.to_string(),
                })
                .collect(),
        }))
        .advise(
            "The report lists each file not placed and why. A capture among them needs a name that source.pattern matches (or a sidecar row) and angles on the plan; other files can stay or be moved out of the capture folder.",
            None,
        ),
    )
}

/// The alarm for files placed on one plan entry.
fn duplicate_alarm(groups: &[crate::archive::listing::DuplicateGroup]) -> Option<Alarm> {
    use crate::archive::listing::DUPLICATE_RULE;
    let g = groups.first()?;
    let others = g
        .others
        .iter()
        .take(5)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    let more = match g.others.len() {
        n if n > 5 => format!(" and {} more", n - 5),
        _ => String::new(),
    };
    let prefers = match &g.rule_prefers {
        Some(p) => format!(
            "; {p} arrived after {} was checked and is what `goniowatch check` of the finished folder keeps",
            g.kept
        ),
        None => String::new(),
    };
    let rest = match groups.len() {
        1 => String::new(),
        n => format!(
            " ({} more plan entries have more than one file; the evidence lists them all)",
            n - 1
        ),
    };
    Some(
        Alarm::new(
            AlarmKind::CaptureQuality,
            Severity::Warning,
            AlarmCode::DuplicateFiles,
            format!(
                "plan entry {} has {} files: {} is checked, {others}{more} left out{prefers}{rest}; the rule: {DUPLICATE_RULE}",
                g.entry,
                g.others.len() + 1,
                g.kept
            ),
        )
        .with(Evidence::DuplicateFiles(evidence::DuplicateFiles {
            groups: groups
                .iter()
                .map(|g| evidence::DuplicateGroup {
                    entry: g.entry,
                    kept: g.kept.clone(),
                    others: g.others.clone(),
                    rule_prefers: g.rule_prefers.clone(),
                })
                .collect(),
        }))
        .advise(
            "Move the copies and rejected files out of the capture folder (or rename them so the pattern does not match), so that each plan entry has one file.",
            None,
        ),
    )
}

/// The manifest's record of a checked capture.
fn manifest_record(idx: u64, file: &str, outcome: &Outcome) -> ManifestRecord {
    let (status, size, sha256, error) = match outcome {
        Outcome::Ok { size, sha256, .. } => {
            (CaptureStatus::Ok, Some(*size), Some(sha256.clone()), None)
        }
        Outcome::Failed { error } => (CaptureStatus::Failed, None, None, Some(error.clone())),
        Outcome::Missing { reason } => (CaptureStatus::Missing, None, None, Some(reason.clone())),
    };
    ManifestRecord {
        idx,
        file: file.to_string(),
        status,
        size,
        sha256,
        error,
    }
}

/// An outstanding RESYNC whose ACK has not come after this many received lines is sent again.
const RESYNC_LINES: u32 = 64;

/// A RESYNC from the same capture as the one before waits 2ⁿ received lines (n: how often it
/// was sent in a row), at most this many; the idle timer sends it regardless. A controller that
/// answers every RESYNC with the same unacceptable line is thus asked at a falling rate, not in
/// a loop.
const RESYNC_BACKOFF_MAX_LINES: u64 = 1024;

/// Capture indices beyond the plan's count by more than this are refused as garbage (probes
/// add captures beyond the plan, but not millions).
const INDEX_ALLOWANCE: u64 = 100_000;

impl Engine {
    /// The engine of a session with this configuration: its checker, alarm settings and
    /// probe cadence.
    pub fn from_config(cfg: &Config) -> Result<Engine, ConfigError> {
        let setup = Setup::new(cfg)?;
        let mut checker = Checker::new(
            setup.plan,
            setup.rig,
            setup.colour,
            cfg.checks.clone(),
            cfg.sample.isotropic,
            setup.probes.clone(),
        );
        if setup.probes.cadence() > 0 {
            checker.set_probe_entry(setup.probe_entry);
        }
        Ok(Engine::new(checker, cfg.alarms.clone()))
    }

    pub fn new(checker: Checker, spec: AlarmSpec) -> Self {
        let captures_planned = checker.plan().capture_count() as u64;
        let checker_every = checker.probe_every();
        Engine {
            checker,
            spec,
            link: link::Link::default(),
            ledger: ledger::Ledger::default(),
            done: false,
            finished: false,
            last_t: 0.0,
            timeline: crate::measure::timeline::TimeLine::default(),
            steps_back: BTreeMap::new(),
            files_skipped: BTreeMap::new(),
            duplicate_entries: BTreeSet::new(),
            alarm_book: alarms::AlarmBook::default(),
            paused_for: BTreeSet::new(),
            captures_planned,
            probes: probes::ProbeCadence::new(checker_every),
            probe_requests: Vec::new(),
            inputs: 0,
        }
    }

    /// Ask for the probe round that is due, if it can be asked for now: the lamp probe, then
    /// the joint-3 sentinel right after it (the lamp's gain cancels between the two). The next
    /// round is due at the next multiple of the cadence, so a late round does not shift the
    /// ones after it.
    fn ask_probes_if_due(&mut self, out: &mut Vec<Output>) {
        if !self.probes.is_due() {
            return;
        }
        let Some((lamp, sentinel)) = self.checker.probe_round() else {
            return;
        };
        // after the run's last regular capture the controller takes no more captures
        if !(self.link.is_connected() && self.link.is_subscribed())
            || self.done
            || self.probes.announced() >= self.captures_planned
        {
            return;
        }
        self.probe_requests.clear();
        let seq = self.send(out, ToController::Probe { entry: lamp });
        self.probe_requests.push(seq);
        if let Some(entry) = sentinel {
            let seq = self.send(out, ToController::Probe { entry });
            self.probe_requests.push(seq);
        }
        self.probes.handle_asked();
    }

    /// Captures checked so far (the next index to check).
    pub fn checked_through(&self) -> u64 {
        self.ledger.next_check
    }
    /// Captures expected in this session (the controller's count once known).
    pub(crate) fn captures_planned(&self) -> u64 {
        self.captures_planned
    }
    pub fn is_finished(&self) -> bool {
        self.finished
    }
    pub(crate) fn alarm_count(&self) -> u64 {
        self.alarm_book.total()
    }
    /// Whether any critical alarm was raised in this session, including before a resume and
    /// those held back by aggregation (the run's exit status).
    pub fn critical_raised(&self) -> bool {
        self.alarm_book.criticals() > 0
    }
    pub fn table2(&self) -> &Table2 {
        self.checker.table2()
    }

    /// Announced captures still waiting for an outcome (to re-ingest after a restart).
    pub(crate) fn pending_ingest(&self) -> Vec<(u64, String)> {
        self.ledger.pending_ingest()
    }

    /// Every announced capture in index order, and whether it is known to be usable: `Some(false)`
    /// when its file failed or never appeared, `Some(true)` once checked otherwise, `None` while
    /// it waits (for a files source's watch mode to resume where it stood).
    pub(crate) fn announced_captures(&self) -> Vec<(Announcement, Option<bool>)> {
        self.ledger
            .announced
            .iter()
            .map(|(i, a)| {
                let usable = if self.ledger.unusable.contains(i) {
                    Some(false)
                } else if *i < self.ledger.next_check {
                    Some(true)
                } else {
                    None
                };
                (a.clone(), usable)
            })
            .collect()
    }

    /// Every file name the controller announced in this session.
    pub(crate) fn announced_files(&self) -> impl Iterator<Item = &str> {
        self.ledger.announced.values().map(|a| a.file.as_str())
    }

    /// Alarm conditions that hold right now (evaluated on start and resume).
    pub fn active_conditions(&self) -> Vec<Alarm> {
        let mut v = Vec::new();
        if self.link.is_lost() {
            v.push(Alarm::new(
                AlarmKind::Link,
                Severity::Warning,
                AlarmCode::PortLost,
                "the serial link is down; reconnecting".into(),
            ));
        }
        if self.link.version_refused {
            v.push(Alarm::new(
                AlarmKind::Link,
                Severity::Critical,
                AlarmCode::UnsupportedVersion,
                format!("the controller does not speak protocol version {PROTO_VERSION}"),
            ));
        }
        if self.link.crc.active {
            v.push(Alarm::new(
                AlarmKind::Link,
                Severity::Warning,
                AlarmCode::CrcErrors,
                "many lines are failing their CRC".into(),
            ));
        }
        let waiting = self.pending_ingest().len();
        if waiting > 0 {
            v.push(Alarm::new(
                AlarmKind::CaptureQuality,
                Severity::Info,
                AlarmCode::CapturesPending,
                format!("{waiting} announced captures are waiting to be checked"),
            ));
        }
        v.extend(self.checker.open_conditions());
        v
    }

    /// The planned entries (the first `captures_planned` of the plan, in acquisition order)
    /// that no announced regular capture stands for, in entry order.
    pub(crate) fn entries_not_captured(&self) -> Vec<usize> {
        let taken: std::collections::BTreeSet<usize> = self
            .ledger
            .announced
            .values()
            .filter(|a| !a.probe)
            .map(|a| a.entry)
            .collect();
        let planned = usize::try_from(self.captures_planned).unwrap_or(usize::MAX);
        (0..planned.min(self.checker.plan().capture_count()))
            .filter(|e| !taken.contains(e))
            .collect()
    }

    pub fn summary(&self) -> Summary {
        Summary {
            session: self.link.session.clone(),
            rig: self.link.rig_id.clone(),
            captures_planned: self.captures_planned,
            captures_announced: self.ledger.announced.len() as u64,
            entries_not_captured: self.entries_not_captured().len() as u64,
            files_skipped: self.files_skipped.clone(),
            entries_with_duplicates: self.duplicate_entries.len() as u64,
            checked: self.checker.counts().clone(),
            table2: self.checker.table2().clone(),
            isotropy: self.checker.isotropy_table().clone(),
            interpolated: self.checker.interpolated_table().clone(),
            by_command: self.checker.by_command_table().clone(),
            probe_drift: self.checker.probe_drift(),
            probe_pose: self.checker.probe_pose(),
            joint3_sentinel: self.checker.sentinel(),
            isotropy_drift: self.checker.isotropy_drift(),
            colour_drift: self.checker.colour_drift(),
            observability: self.checker.observability(),
            isotropy_steps: self.checker.isotropy_steps(),
            sample_off_centre: self.checker.sample_off_centre(),
            sweeps: self.checker.sweeps(),
            alarms: self.alarm_book.counts().clone(),
            dark_captures: self
                .alarm_book
                .count_of(crate::checks::alarm::AlarmCode::DarkCapture),
            link: self.link.stats.clone(),
            finished: self.finished,
        }
    }

    fn send(&mut self, out: &mut Vec<Output>, command: ToController) -> u32 {
        let seq = self.link.tx_seq;
        out.push(Output::Send(command.encode(seq)));
        self.link.tx_seq = (self.link.tx_seq + 1) % protocol::SEQ_MOD;
        seq
    }

    fn hello(&mut self, out: &mut Vec<Output>) {
        let client = format!("goniowatch/{}", env!("CARGO_PKG_VERSION"));
        self.send(
            out,
            ToController::Hello {
                proto: PROTO_VERSION.to_string(),
                client,
            },
        );
    }

    /// Raise an alarm: counted always (the summary counts every occurrence), sent to the
    /// controller as a PAUSE when critical and configured so, and emitted in full unless its
    /// code is storming (then the window's aggregate reports it).
    fn alarm(&mut self, out: &mut Vec<Output>, a: Alarm) {
        self.alarm_book.count(&a);
        if a.severity == Severity::Critical
            && self.spec.pause_on_critical
            && self.link.is_connected()
            && self.paused_for.insert(a.code)
        {
            self.send(out, ToController::Pause);
        }
        if let Some(a) = self.alarm_book.admit(a, self.inputs) {
            out.push(Output::Alarm(a));
        }
    }

    /// End the aggregation windows that are over (all of them when `all`).
    fn flush_storms(&mut self, out: &mut Vec<Output>, all: bool) {
        out.extend(
            self.alarm_book
                .flush(self.inputs, all)
                .into_iter()
                .map(Output::Alarm),
        );
    }

    /// Capture indices at or above this are garbage.
    fn index_limit(&self) -> u64 {
        self.captures_planned.saturating_add(INDEX_ALLOWANCE)
    }

    /// The lowest capture index neither announced nor known to be missing.
    fn lowest_unseen(&self) -> u64 {
        self.ledger.lowest_unseen()
    }

    fn request_resync(&mut self, out: &mut Vec<Output>) {
        self.resync(out, false);
    }

    /// Send `RESYNC from=lowest unseen`, unless one is outstanding, the link is not ready, or
    /// (without `now`) the same `from` was asked too recently: then it stays needed.
    fn resync(&mut self, out: &mut Vec<Output>, now: bool) {
        if !self.link.is_connected()
            || !self.link.is_subscribed()
            || self.link.resync.outstanding.is_some()
        {
            self.link.resync.needed = true;
            return;
        }
        let from = self.lowest_unseen();
        let repeats = match self.link.resync.last {
            Some((f, n)) if f == from => n,
            _ => 0,
        };
        let spacing = 1u64
            .checked_shl(repeats)
            .unwrap_or(u64::MAX)
            .min(RESYNC_BACKOFF_MAX_LINES);
        if !now && repeats > 0 && self.link.resync.lines_since < spacing {
            self.link.resync.needed = true;
            return;
        }
        self.link.resync.needed = false;
        self.link.resync.gap_during = false;
        let seq = self.send(out, ToController::Resync { from });
        self.link.resync.outstanding = Some(seq);
        self.link.resync.note_sent(seq);
        self.link.resync.age = 0;
        self.link.resync.lines_since = 0;
        self.link.resync.last = Some((from, repeats.saturating_add(1).min(32)));
        self.link.stats.resyncs += 1;
    }

    /// A CAPTURE line for `idx` that cannot be accepted. The first time, the controller is asked
    /// to send it again (it may have been garbled at the source); when it comes again just as
    /// unacceptable, the capture is skipped with an alarm and checking goes on past it.
    fn refuse_announcement(&mut self, out: &mut Vec<Output>, idx: Option<u64>, why: String) {
        self.link.stats.framing_errors += 1;
        let Some(i) = idx.filter(|i| *i < self.index_limit()) else {
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::Link,
                    Severity::Warning,
                    AlarmCode::BadAnnouncement,
                    format!("a CAPTURE line was malformed and names no readable capture index ({why}); asking {} again", self.source_name()),
                ),
            );
            self.request_resync(out);
            return;
        };
        if i < self.ledger.next_check || self.ledger.announced.contains_key(&i) {
            return; // already have it: a stray bad copy changes nothing
        }
        let n = self.ledger.refused.entry(i).or_default();
        *n += 1;
        if *n == 1 {
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::Link,
                    Severity::Warning,
                    AlarmCode::BadAnnouncement,
                    format!("the CAPTURE line for capture {i} was malformed ({why}); asking {} to send it again", self.source_name()),
                )
                .at(Some(i), None),
            );
            self.request_resync(out);
        } else if self.ledger.missing.insert(i) {
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    AlarmCode::AnnouncementRefused,
                    format!("{} sent the same malformed CAPTURE line for capture {i} again ({why}); capture {i} is skipped and checking goes on", self.source_name()),
                )
                .at(Some(i), None)
                .with(Evidence::AnnouncementRefused(evidence::AnnouncementRefused {
                    idx: i,
                    reason: why.to_string(),
                })),
            );
            self.drain(out);
        }
    }

    /// Feed one input; returns what to do, in order.
    pub fn handle(&mut self, input: &Input) -> Vec<Output> {
        let mut out = Vec::new();
        self.inputs += 1;
        self.flush_storms(&mut out, false);
        match input {
            Input::Connected => {
                self.link.opened();
                if self.link.stats.connects > 1 {
                    let n = self.link.stats.connects;
                    self.alarm(
                        &mut out,
                        Alarm::new(
                            AlarmKind::Link,
                            Severity::Info,
                            AlarmCode::PortBack,
                            format!("serial port open again (connection {n})"),
                        ),
                    );
                }
                self.hello(&mut out);
            }
            Input::Disconnected { reason } => {
                if self.link.is_connected() {
                    self.link.stats.disconnects += 1;
                    self.alarm(
                        &mut out,
                        Alarm::new(
                            AlarmKind::Link,
                            Severity::Warning,
                            AlarmCode::PortLost,
                            format!("serial port lost ({reason}); reconnecting, then resyncing from capture {}", self.lowest_unseen()),
                        ),
                    );
                }
                self.link.lost();
                // a controller that said it is done and whose captures are all checked needs
                // no link to finish the session
                self.drain(&mut out);
            }
            Input::Restart => {
                self.link.restarted();
                self.alarm(
                    &mut out,
                    Alarm::new(
                        AlarmKind::Link,
                        Severity::Info,
                        AlarmCode::DaemonRestart,
                        format!(
                            "goniowatch restarted on this session; {} captures already checked",
                            self.ledger.next_check
                        ),
                    ),
                );
            }
            Input::RxBad { reason } => {
                self.link.stats.framing_errors += 1;
                self.note_crc(&mut out, true, reason);
            }
            Input::Rx { line } => self.rx(&mut out, line),
            Input::Outcome { idx, outcome } => {
                if self.ledger.announced.contains_key(idx) && *idx >= self.ledger.next_check {
                    self.ledger.outcomes.insert(*idx, outcome.clone());
                    self.drain(&mut out);
                }
            }
            Input::Idle => {
                if self.link.is_connected() && !self.finished && !self.link.version_refused {
                    if self.link.is_subscribed() {
                        self.link.resync.outstanding = None;
                        self.resync(&mut out, true);
                    } else {
                        // the HELLO or its IDENT was lost: ask again
                        self.hello(&mut out);
                    }
                }
            }
            Input::TimeSteppedBack { idx, step } => {
                self.steps_back.insert(*idx, *step);
            }
            Input::Skipped { files, counts } => {
                self.files_skipped = counts.clone();
                if let Some(a) = skipped_alarm(files, counts) {
                    self.alarm(&mut out, a);
                }
            }
            Input::Duplicates { groups } => {
                self.duplicate_entries
                    .extend(groups.iter().map(|g| g.entry));
                // one alarm a listing, whatever the number of entries (no storm to thin)
                if let Some(a) = duplicate_alarm(groups) {
                    self.alarm(&mut out, a);
                }
            }
            Input::Unannounced { files } => {
                if !files.is_empty() {
                    self.alarm(
                        &mut out,
                        Alarm::new(
                            AlarmKind::CaptureQuality,
                            Severity::Warning,
                            AlarmCode::UnannouncedFiles,
                            format!(
                                "{} file(s) in the capture folder {}: {}",
                                files.len(),
                                if self.captures_are_files() {
                                    "were not placed as captures (the skipped files say why)"
                                } else {
                                    "were never announced by the controller"
                                },
                                files.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
                            ),
                        )
                        .with(Evidence::UnannouncedFiles(
                            evidence::UnannouncedFiles {
                                files: files.clone(),
                            },
                        )),
                    );
                }
            }
        }
        out
    }

    fn note_crc(&mut self, out: &mut Vec<Output>, bad: bool, what: &str) {
        let (window, threshold) = (self.spec.crc_window, self.spec.crc_errors_alarm);
        if let Some((n_bad, seen)) = self.link.crc.note(bad, window, threshold) {
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::Link,
                    Severity::Warning,
                    AlarmCode::CrcErrors,
                    format!(
                        "{n_bad} of the last {seen} lines from the controller were corrupt (threshold {threshold}); latest: {what}"
                    ),
                )
                .with(Evidence::CrcErrors(evidence::CrcErrors {
                    bad_lines: n_bad as u64,
                    window: seen as u64,
                })),
            );
        }
    }

    fn rx(&mut self, out: &mut Vec<Output>, line: &str) {
        self.link.stats.lines += 1;
        self.link.stats.bytes += line.len() as u64 + 1;
        self.link.resync.lines_since = self.link.resync.lines_since.saturating_add(1);
        let parsed = protocol::parse_message(line);
        // replayed CAPTURE lines are the answer arriving, not silence; a live CAPTURE of the
        // lowest index not yet seen is the controller working through a backlog sent before it
        // read the RESYNC (a files source's first listing of thousands of captures): neither
        // says the reply was lost, and asking again would be answered with the whole backlog
        // once more, for every 64 lines of it
        let lowest = self.lowest_unseen();
        let answering = match &parsed {
            Ok(l) => {
                matches!(&l.message, FromController::Capture(a) if a.replay || a.idx == lowest)
            }
            Err(LineError::Content { replay, .. }) => *replay,
            Err(LineError::Frame(_)) => false,
        };
        if self.link.resync.outstanding.is_some() && !answering {
            self.link.resync.age += 1;
            if self.link.resync.age > RESYNC_LINES {
                // the reply was lost on the wire: ask again
                self.link.resync.outstanding = None;
                self.link.resync.needed = true;
            }
        }
        let (seq, ident, content) = match parsed {
            Ok(l) => (
                l.seq,
                matches!(l.message, FromController::Ident(_)),
                Ok(l.message),
            ),
            Err(LineError::Frame(e)) => {
                if matches!(e, protocol::FrameError::BadCrc { .. }) {
                    self.link.stats.crc_errors += 1;
                } else {
                    self.link.stats.framing_errors += 1;
                }
                self.note_crc(out, true, &e.to_string());
                return;
            }
            // intact on the wire: its sequence number counts, its content is refused below
            Err(LineError::Content {
                seq,
                verb,
                idx,
                error,
                ..
            }) => (seq, verb == "IDENT", Err((verb, idx, error))),
        };
        self.note_crc(out, false, "");
        // sequence check (an IDENT with seq 0 starts a new count: reboot or first contact)
        let restart = ident && seq == 0;
        let gap = self.link.expect_seq.is_some_and(|e| seq != e && !restart);
        if gap {
            self.link.stats.sequence_gaps += 1;
            if self.link.resync.outstanding.is_some() {
                self.link.resync.gap_during = true;
            }
        }
        self.link.expect_seq = Some((seq + 1) % protocol::SEQ_MOD);
        match content {
            Ok(message) => self.handle_message(out, message),
            Err((verb, idx, error)) if verb == "CAPTURE" => {
                self.refuse_announcement(out, idx, error.to_string())
            }
            Err((verb, _, error)) => {
                self.link.stats.framing_errors += 1;
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::Link,
                        Severity::Warning,
                        AlarmCode::BadLine,
                        format!("a {verb} line from the controller was intact but malformed ({error}); it is ignored"),
                    ),
                );
            }
        }
        if gap || (self.link.resync.needed && self.link.resync.outstanding.is_none()) {
            self.request_resync(out);
        }
    }

    fn handle_message(&mut self, out: &mut Vec<Output>, message: FromController) {
        match message {
            FromController::Ident(i) => self.ident(out, &i),
            FromController::Ack(a) => self.ack(out, &a),
            FromController::Nak(n) => self.nak(out, &n),
            FromController::Status(s) => self.status(out, &s),
            FromController::Capture(a) => {
                let limit = self.index_limit();
                if a.idx >= limit {
                    let why = format!(
                        "idx {} is beyond any plausible capture index (limit {limit})",
                        a.idx
                    );
                    self.refuse_announcement(out, Some(a.idx), why);
                } else {
                    self.announce(out, a.idx, a);
                }
            }
            FromController::Info => {}
            FromController::Unknown(_) => self.link.stats.unknown_verbs += 1,
        }
    }

    fn ack(&mut self, out: &mut Vec<Output>, a: &Ack) {
        // the answer to the RESYNC outstanding, or to an earlier one it replaced: an answer can
        // come late (the daemon busy, the controller slow), and it tells the same
        let Some(r) = a.reference else {
            return;
        };
        if !self.link.resync.answers(r) {
            return;
        }
        self.link.resync.outstanding = None;
        self.link.resync.unanswered.clear();
        if a.state.as_deref() == Some("done") {
            self.done = true;
        }
        if let Some(next) = a.next.filter(|n| *n <= self.index_limit()) {
            self.ledger.controller_next = self.ledger.controller_next.max(next);
            if !self.link.resync.gap_during {
                self.note_never_announced(out, next);
            } else {
                self.link.resync.needed = true;
            }
        }
        self.drain(out);
        if self.link.resync.needed {
            self.request_resync(out);
        }
    }

    /// After a clean resync: the controller's log has nothing below `next` that is not yet
    /// announced, so those captures are missing for good.
    /// A capture whose line was refused is not lost: the controller has it. The first clean
    /// resync that passes it without a readable line asks once more; the second skips it.
    fn note_never_announced(&mut self, out: &mut Vec<Output>, next: u64) {
        let (refused, lost): (Vec<u64>, Vec<u64>) = (self.ledger.next_check..next)
            .filter(|i| !self.ledger.announced.contains_key(i) && !self.ledger.missing.contains(i))
            .partition(|i| self.ledger.refused.contains_key(i));
        for i in refused {
            if self.ledger.resend_asked.insert(i) {
                self.link.resync.needed = true;
                continue;
            }
            self.ledger.missing.insert(i);
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Warning,
                    AlarmCode::AnnouncementRefused,
                    format!("{} did not send a readable CAPTURE line for capture {i} when asked again; capture {i} is skipped and checking goes on", self.source_name()),
                )
                .at(Some(i), None)
                .with(Evidence::AnnouncementRefused(evidence::AnnouncementRefused {
                    idx: i,
                    reason: "no readable line after a resend was asked".into(),
                })),
            );
        }
        self.ledger.missing.extend(lost.iter().copied());
        if lost.len() <= 20 {
            for i in lost {
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::CaptureQuality,
                        Severity::Warning,
                        AlarmCode::CaptureNeverAnnounced,
                        format!(
                            "capture {i} is not in {}'s capture log (resync reports next = {next})",
                            self.source_name()
                        ),
                    )
                    .at(Some(i), None),
                );
            }
        } else {
            let (first, last) = (lost[0], lost[lost.len() - 1]);
            self.alarm(
                out,
                Alarm::new(
                    AlarmKind::CaptureQuality,
                    Severity::Critical,
                    AlarmCode::CaptureNeverAnnounced,
                    format!("{} captures between {first} and {last} are not in {}'s capture log (resync reports next = {next})", lost.len(), self.source_name()),
                )
                .with(Evidence::NeverAnnounced(evidence::NeverAnnounced {
                    count: lost.len() as u64,
                    first,
                    last,
                })),
            );
        }
    }

    fn nak(&mut self, out: &mut Vec<Output>, n: &Nak) {
        self.link.stats.naks += 1;
        match n.reason.as_deref() {
            Some("unsupported-version") => {
                let supported = n.supported.as_deref().unwrap_or("?").to_string();
                self.version_refused(out, &supported);
            }
            // one of our lines was corrupted: resend what is pending
            Some("bad-crc") if self.link.resync.outstanding.take().is_some() => {
                self.request_resync(out)
            }
            Some("bad-crc") if !self.link.is_subscribed() && !self.link.version_refused => {
                self.hello(out)
            }
            Some("not-subscribed") => {
                self.send(out, ToController::Subscribe);
                self.link.subscribed();
                self.request_resync(out);
            }
            // a rig that does not allow probes, or does not know them: watch without them
            Some(reason @ ("refused" | "unknown-verb"))
                if n.reference
                    .is_some_and(|r| self.probe_requests.contains(&r)) =>
            {
                let reason = reason.to_string();
                self.probes_refused(out, &reason);
            }
            _ => {}
        }
    }

    /// The controller refused a probe: no more rounds, and the checks watch the lamp without
    /// them (the pairs, the isotropy classes and the sweeps).
    fn probes_refused(&mut self, out: &mut Vec<Output>, reason: &str) {
        self.probe_requests.clear();
        self.probes = probes::ProbeCadence::new(0);
        self.checker.withdraw_probes();
        let probes_taken = self.checker.counts().probes;
        let lost = if self.checker.watches_isotropy() {
            "a lamp step is flagged later (by the sweeps, not within a probe interval)"
        } else {
            "a lamp step is flagged later, the lamp's colour and arm joint 3 go unwatched"
        };
        self.alarm(
            out,
            Alarm::new(
                AlarmKind::Drift,
                Severity::Warning,
                AlarmCode::ProbesRefused,
                format!(
                    "the controller refused the drift probes (NAK reason={reason}) after {probes_taken} probes; the lamp is watched from the pairs and the sweeps from now on: {lost}. Enable remote actions at the rig to get them back"
                ),
            )
            .at(None, Some(self.last_t))
            .with(Evidence::ProbesRefused(evidence::ProbesRefused {
                reason: reason.to_string(),
                probes_taken,
            })),
        );
    }

    fn status(&mut self, out: &mut Vec<Output>, s: &Status) {
        if let Some(next) = s.next.filter(|n| *n <= self.index_limit()) {
            self.ledger.controller_next = self.ledger.controller_next.max(next);
        }
        match s.state.as_deref() {
            Some("done") => {
                self.done = true;
                // make sure nothing before `next` is unseen
                if self.lowest_unseen() < self.ledger.controller_next {
                    self.request_resync(out);
                }
                self.drain(out);
            }
            Some("fault") => {
                let reason = s.reason.as_deref().unwrap_or("no reason given");
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::Link,
                        Severity::Critical,
                        AlarmCode::ControllerFault,
                        format!("the controller reports a fault: {reason}"),
                    )
                    .at(None, s.t),
                );
            }
            _ => {}
        }
    }

    fn ident(&mut self, out: &mut Vec<Output>, m: &Ident) {
        // the unsolicited IDENT after boot and the reply to HELLO say the same: subscribe once
        if self.link.is_subscribed() && m.boot == self.link.boot && self.link.boot.is_some() {
            return;
        }
        let proto_ok = m
            .proto
            .as_deref()
            .is_some_and(|p| p == PROTO_VERSION.to_string());
        if !proto_ok {
            let theirs = m.proto.as_deref().unwrap_or("?").to_string();
            self.version_refused(out, &theirs);
            return;
        }
        if let Some(n) = m.captures {
            self.captures_planned = n;
        }
        let boot = m.boot;
        if let (Some(old), Some(new)) = (self.link.boot, boot) {
            if new != old {
                self.link.stats.reboots += 1;
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::Link,
                        Severity::Warning,
                        AlarmCode::ControllerReboot,
                        format!("the controller restarted (boot {old} → {new}); re-subscribing and resyncing from capture {}", self.lowest_unseen()),
                    ),
                );
            }
        }
        self.link.boot = boot.or(self.link.boot);
        let session = m.session.clone();
        match (&self.link.session, &session) {
            (Some(a), Some(b)) if a != b => {
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::Link,
                        Severity::Critical,
                        AlarmCode::SessionChanged,
                        format!("the controller now reports session '{b}', but this goniowatch session belongs to '{a}'"),
                    ),
                );
            }
            (None, Some(_)) => self.link.session = session,
            _ => {}
        }
        self.link.rig_id = m.rig.clone().or(self.link.rig_id.take());
        self.link.subscribed();
        self.link.resync.outstanding = None;
        self.send(out, ToController::Subscribe);
        self.request_resync(out);
    }

    fn version_refused(&mut self, out: &mut Vec<Output>, theirs: &str) {
        self.link.version_refused = true;
        self.alarm(
            out,
            Alarm::new(
                AlarmKind::Link,
                Severity::Critical,
                AlarmCode::UnsupportedVersion,
                format!("the controller speaks protocol version {theirs}, goniowatch speaks {PROTO_VERSION}; goniowatch keeps listening but cannot check this run"),
            ),
        );
    }

    fn announce(&mut self, out: &mut Vec<Output>, idx: u64, a: Announcement) {
        if let Some(prev) = self.ledger.announced.get(&idx) {
            self.link.stats.duplicate_announcements += 1;
            if prev.file != a.file || prev.entry != a.entry {
                let msg = format!(
                    "capture index {idx} was announced twice: first {} (entry {}), now {} (entry {}); the first is kept",
                    prev.file, prev.entry, a.file, a.entry
                );
                self.alarm(
                    out,
                    Alarm::new(
                        AlarmKind::CaptureQuality,
                        Severity::Warning,
                        AlarmCode::DuplicateIndex,
                        msg,
                    )
                    .at(Some(idx), Some(a.t))
                    .with(Evidence::DuplicateIndex(evidence::DuplicateIndex {
                        kept: prev.file.clone(),
                        ignored: a.file.clone(),
                    })),
                );
            }
            return;
        }
        if idx < self.ledger.next_check {
            return; // already checked (e.g. replayed after a restart)
        }
        let expected = self
            .ledger
            .announced
            .keys()
            .next_back()
            .map(|k| k.saturating_add(1))
            .unwrap_or(0)
            .max(self.ledger.next_check);
        out.push(Output::Ingest {
            idx,
            file: a.file.clone(),
        });
        self.ledger.missing.remove(&idx);
        let regular = !a.probe;
        self.ledger.announced.insert(idx, a);
        if regular {
            self.probes.handle_announced();
            self.ask_probes_if_due(out);
        }
        self.ledger.controller_next = self.ledger.controller_next.max(idx.saturating_add(1));
        if idx > expected && self.lowest_unseen() < idx {
            self.request_resync(out);
        }
    }

    /// Whether the captures are files placed by goniowatch itself (`check`, watch mode), not
    /// announced by a controller: the messages then name the folder, not a controller.
    fn captures_are_files(&self) -> bool {
        self.link.rig_id.as_deref() == Some(crate::archive::controller::RIG_ID)
    }

    /// Who announces the captures, for the messages.
    fn source_name(&self) -> &'static str {
        if self.captures_are_files() {
            "the capture folder's listing"
        } else {
            "the controller"
        }
    }

    fn step_back_alarm(
        &self,
        input: &CaptureInput,
        step: crate::measure::timeline::StepBack,
    ) -> Alarm {
        let whose = if self.captures_are_files() {
            "the capture times (the files' modification times, or the sidecar's times)"
        } else {
            "the controller's clock"
        };
        Alarm::new(
            AlarmKind::Link,
            Severity::Warning,
            AlarmCode::TimeSteppedBack,
            format!(
                "{whose} went back by {:.1} s at capture {} ({:.3} s after {:.3} s): a clock was set back or the times were changed; from this capture on, times go on from the capture before it in capture order (the step is removed), so drift rates do not see the same time twice",
                step.step_s, input.idx, step.announced_s, step.previous_s
            ),
        )
        .at(Some(input.idx), Some(input.t))
        .with(Evidence::TimeStep(evidence::TimeStep {
            step_s: step.step_s,
            announced_t: step.announced_s,
            previous_t: step.previous_s,
            shift_s: step.shift_s,
        }))
        .advise(
            "Check the clock of the rig's computer (a manual correction, a time-zone change, a failing clock battery) and keep it from stepping during a run; the drift rates across the step are approximate.",
            None,
        )
    }

    /// After a regular capture is checked: the probes' poses the checker chose (or the alarm
    /// that none qualifies), and a probe round that fell due before the pose was known.
    fn after_regular_capture(&mut self, out: &mut Vec<Output>, idx: u64, t: f64) {
        for setup in self.checker.after_regular_capture(idx, t) {
            match setup {
                ProbeSetup::ProbePose(pose) => out.push(Output::ProbePose(pose)),
                ProbeSetup::SentinelPose(pose) => out.push(Output::SentinelPose(pose)),
                ProbeSetup::Alarm(a) => self.alarm(out, *a),
            }
        }
        self.ask_probes_if_due(out);
        self.ask_recapture_if_wanted(out);
    }

    /// Ask for the two re-captures a slip the sweeps named waits for, back to back (the lamp's
    /// gain cancels between them). Not while the link is down or after the run's last regular
    /// capture: the slip is then named from the sweeps alone when its wait runs out.
    fn ask_recapture_if_wanted(&mut self, out: &mut Vec<Output>) {
        if !(self.link.is_connected() && self.link.is_subscribed())
            || self.done
            || self.probes.announced() >= self.captures_planned
        {
            return;
        }
        let Some(entries) = self.checker.recapture_wanted() else {
            return;
        };
        for entry in entries {
            let seq = self.send(out, ToController::Probe { entry });
            self.probe_requests.push(seq);
        }
    }

    fn drain(&mut self, out: &mut Vec<Output>) {
        loop {
            let i = self.ledger.next_check;
            if let Some(a) = self.ledger.announced.get(&i) {
                let Some(outcome) = self.ledger.outcomes.remove(&i) else {
                    break;
                };
                let (t, step_back) = self.timeline.handle_capture(a.t);
                let step_back = step_back.or_else(|| self.steps_back.remove(&i));
                let input = CaptureInput {
                    idx: i,
                    entry: a.entry,
                    file: a.file.clone(),
                    t,
                    cmd: a.cmd,
                    enc: a.enc,
                    substitute: a.substitute,
                    probe: a.probe,
                    outcome: at_exposure(outcome.clone(), a.exposure),
                };
                if !matches!(outcome, Outcome::Ok { .. }) {
                    self.ledger.unusable.insert(i);
                }
                out.push(Output::Manifest(manifest_record(i, &a.file, &outcome)));
                if let Some(step) = step_back {
                    let a = self.step_back_alarm(&input, step);
                    self.alarm(out, a);
                }
                let res = self.checker.check(&input);
                self.last_t = input.t;
                if let Some(c) = res.capture {
                    out.push(Output::Capture(c));
                }
                for p in res.pairs {
                    out.push(Output::Pair(p));
                }
                for r in res.isotropy {
                    out.push(Output::Isotropy(r));
                }
                for r in res.sweeps {
                    out.push(Output::Sweep(r));
                }
                for al in res.alarms {
                    self.alarm(out, al);
                }
                self.ledger.next_check += 1;
                if !input.probe {
                    self.after_regular_capture(out, input.idx, input.t);
                }
            } else if self.ledger.missing.contains(&i) {
                self.ledger.next_check += 1;
            } else {
                break;
            }
        }
        if self.done
            && !self.finished
            && self.ledger.next_check >= self.ledger.controller_next
            && self.link.resync.outstanding.is_none()
        {
            self.finished = true;
            let res = self.checker.finish(self.last_t);
            for p in res.pairs {
                out.push(Output::Pair(p));
            }
            for al in res.alarms {
                self.alarm(out, al);
            }
            self.flush_storms(out, true);
            out.push(Output::Finished);
        }
    }
}

/// A capture's outcome with its announced relative exposure divided out of the mean (the counts
/// are of the pixels as stored and stay).
fn at_exposure(outcome: Outcome, exposure: Option<f64>) -> Outcome {
    match (outcome, exposure) {
        (
            Outcome::Ok {
                mut stats,
                width,
                height,
                size,
                sha256,
            },
            Some(e),
        ) => {
            for c in &mut stats.mean_rgb {
                *c /= e;
            }
            stats.max_value /= e;
            Outcome::Ok {
                stats,
                width,
                height,
                size,
                sha256,
            }
        }
        (o, _) => o,
    }
}
