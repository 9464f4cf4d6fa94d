//! The engine's alarm book: every alarm is counted (the summary's counts), and alarm storms are
//! aggregated: per code, at most `ALARM_BURST` alarms in full per window of `ALARM_WINDOW`
//! engine inputs; the rest are counted and reported as one alarm when the window ends. Windows
//! are counted in inputs, not wall time, so a replay aggregates exactly as the live run did.

use crate::checks::alarm::{Affects, Alarm, AlarmCode, Severity};
use crate::checks::evidence::{Aggregated, Evidence};
use std::collections::BTreeMap;

const ALARM_BURST: u32 = 5;
const ALARM_WINDOW: u64 = 2000;
/// Capture indices an aggregated alarm lists at most.
const ALARM_LIST_MAX: usize = 200;

/// The alarms of one code held back in the current window.
#[derive(Debug, Clone, Default)]
struct Storm {
    window_start: u64,
    emitted: u32,
    held: u64,
    captures: Vec<u64>,
    /// The held alarms' affected captures, merged; and their action when they all had the
    /// same one (None: differing, or none).
    affects: Option<Affects>,
    action: Option<Option<String>>,
    latest: Option<Alarm>,
    /// The highest severity held back in this window.
    held_worst: Option<Severity>,
    /// The highest severity emitted in full in this window.
    worst: Option<Severity>,
}

/// Counts per alarm kind, and the storms of the current windows.
#[derive(Debug, Clone, Default)]
pub(super) struct AlarmBook {
    counts: BTreeMap<String, u64>,
    /// Occurrences per code (the summary's own counts are per kind, as its files hold them).
    codes: BTreeMap<AlarmCode, u64>,
    /// Critical occurrences, emitted in full or held back.
    criticals: u64,
    storms: BTreeMap<AlarmCode, Storm>,
}

impl AlarmBook {
    /// Count an occurrence under its kind.
    pub(super) fn count(&mut self, a: &Alarm) {
        *self.counts.entry(a.kind.as_str().to_string()).or_default() += 1;
        *self.codes.entry(a.code).or_default() += 1;
        if a.severity == Severity::Critical {
            self.criticals += 1;
        }
    }

    /// The alarm to emit now, or None (held for the aggregate). An alarm is emitted while its
    /// code is within its burst, and always when it is more severe than any emitted in full in
    /// the window (a warning that turns critical is never held back). `inputs` is the engine's
    /// input count.
    pub(super) fn admit(&mut self, a: Alarm, inputs: u64) -> Option<Alarm> {
        let storm = self.storms.entry(a.code).or_insert_with(|| Storm {
            window_start: inputs,
            ..Storm::default()
        });
        if storm.emitted < ALARM_BURST || storm.worst.is_none_or(|w| a.severity > w) {
            storm.emitted += 1;
            storm.worst = storm.worst.max(Some(a.severity));
            return Some(a);
        }
        storm.held += 1;
        storm.held_worst = storm.held_worst.max(Some(a.severity));
        if let Some(i) = a.idx {
            if storm.captures.len() < ALARM_LIST_MAX {
                storm.captures.push(i);
            }
        }
        storm.affects = match (storm.affects.take(), a.affects.clone()) {
            (Some(s), Some(x)) => Some(s.merge(x, ALARM_LIST_MAX)),
            (s, x) => s.or(x),
        };
        storm.action = Some(match storm.action.take() {
            None => a.action.clone(),
            Some(same) if same == a.action => same,
            Some(_) => None,
        });
        storm.latest = Some(a);
        None
    }

    /// End the windows that are over at input `now` (all of them when `all`): each code that
    /// held alarms back gets one alarm with their count, their captures and the latest of them.
    pub(super) fn flush(&mut self, now: u64, all: bool) -> Vec<Alarm> {
        let mut out = Vec::new();
        for (code, storm) in self.storms.iter_mut() {
            if !all && now < storm.window_start.saturating_add(ALARM_WINDOW) {
                continue;
            }
            if let Some(latest) = storm.latest.take() {
                out.push(aggregate(code, storm, latest, now));
            }
            *storm = Storm {
                window_start: now,
                ..Storm::default()
            };
        }
        if all {
            self.storms.clear();
        }
        out
    }

    pub(super) fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Occurrences of one code, emitted in full or held back.
    pub(super) fn count_of(&self, code: AlarmCode) -> u64 {
        self.codes.get(&code).copied().unwrap_or(0)
    }

    /// Critical occurrences since the session began (the run's exit status).
    pub(super) fn criticals(&self) -> u64 {
        self.criticals
    }

    pub(super) fn total(&self) -> u64 {
        self.counts.values().sum()
    }
}

/// The one alarm that reports a window's held-back alarms of `code`.
fn aggregate(code: &AlarmCode, storm: &Storm, latest: Alarm, now: u64) -> Alarm {
    let first = storm.window_start;
    let captures = if storm.captures.is_empty() {
        String::new()
    } else {
        format!(
            " for captures {}",
            storm
                .captures
                .iter()
                .take(20)
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ) + if storm.captures.len() > 20 {
            ", …"
        } else {
            ""
        }
    };
    let mut a = Alarm::new(
        latest.kind,
        storm.held_worst.unwrap_or(latest.severity).max(latest.severity),
        *code,
        format!(
            "{} more '{code}' alarm(s) were held back (more than {ALARM_BURST} in {ALARM_WINDOW} inputs){captures}; the latest: {}",
            storm.held, latest.message
        ),
    )
    .at(None, latest.t);
    // the held alarms' captures together, and their action if they shared one
    a.affects = storm.affects.clone();
    a.action = storm.action.clone().flatten();
    a = a.with(Evidence::Aggregated(Box::new(Aggregated {
        aggregated: storm.held,
        window_inputs: [first, now],
        captures: storm.captures.clone(),
        latest,
    })));
    a.idx = None;
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::alarm::AlarmKind;

    fn alarm(severity: Severity, idx: u64) -> Alarm {
        Alarm::new(
            AlarmKind::CaptureQuality,
            severity,
            AlarmCode::CaptureFailed,
            "x".into(),
        )
        .at(Some(idx), None)
    }

    #[test]
    fn a_storm_is_held_back_but_an_escalation_never_is() {
        let mut book = AlarmBook::default();
        let mut emitted = Vec::new();
        for i in 0..20 {
            let sev = if i < 12 {
                Severity::Warning
            } else {
                Severity::Critical
            };
            let a = alarm(sev, i);
            book.count(&a);
            emitted.extend(book.admit(a, i));
        }
        // five warnings in full, then the first critical at once, then held back again
        let sev: Vec<Severity> = emitted.iter().map(|a| a.severity).collect();
        assert_eq!(sev.len(), 6, "{sev:?}");
        assert_eq!(sev[5], Severity::Critical);
        assert_eq!(emitted[5].idx, Some(12));
        let agg = book.flush(20, true);
        assert_eq!(agg.len(), 1);
        assert_eq!(agg[0].evidence.to_json()["aggregated"], 14);
        assert_eq!(agg[0].severity, Severity::Critical);
        assert_eq!(book.total(), 20);
        assert_eq!(book.criticals(), 8);
    }

    #[test]
    fn an_aggregate_carries_the_worst_severity_it_holds() {
        let mut book = AlarmBook::default();
        // a critical in full, then criticals and warnings held back, the latest a warning
        for i in 0..12 {
            let sev = if i < 8 {
                Severity::Critical
            } else {
                Severity::Warning
            };
            let a = alarm(sev, i);
            book.count(&a);
            book.admit(a, i);
        }
        let agg = book.flush(12, true);
        assert_eq!(agg.len(), 1);
        assert_eq!(agg[0].severity, Severity::Critical);
        assert_eq!(book.criticals(), 8);
    }

    #[test]
    fn an_aggregate_affects_every_capture_its_alarms_did() {
        use crate::checks::alarm::Handling;
        let mut book = AlarmBook::default();
        // reciprocity outliers, each naming its pair; all with the same action
        for i in 0..9u64 {
            let a = Alarm::new(
                AlarmKind::ReciprocityOutlier,
                Severity::Warning,
                AlarmCode::ReciprocityOutlier,
                "x".into(),
            )
            .at(Some(100 + i), None)
            .advise(
                "look",
                Some(Affects::Captures {
                    idx: vec![i, 100 + i],
                    handling: Handling::Inspect,
                }),
            );
            book.admit(a, i);
        }
        let agg = book.flush(9, true);
        assert_eq!(agg.len(), 1);
        // the four held back: captures 5–8 and their partners 105–108
        assert_eq!(
            agg[0].affects,
            Some(Affects::Captures {
                idx: vec![5, 6, 7, 8, 105, 106, 107, 108],
                handling: Handling::Inspect
            })
        );
        assert_eq!(agg[0].action.as_deref(), Some("look"));
        // "from here on" conditions merge to the earliest, and the stronger handling
        let m = Affects::Since {
            from_idx: 50,
            handling: Handling::Corrected,
        }
        .merge(
            Affects::Captures {
                idx: vec![40],
                handling: Handling::Retake,
            },
            200,
        );
        assert_eq!(
            m,
            Affects::Since {
                from_idx: 40,
                handling: Handling::Retake
            }
        );
    }
}
