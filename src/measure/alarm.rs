//! Alarms: what was seen, against what threshold, with the evidence. Deterministic (controller
//! time and capture index only; wall-clock time is added by the shell's sinks, never here).

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AlarmKind {
    Link,
    CaptureQuality,
    ReciprocityOutlier,
    Isotropy,
    Drift,
    Positioning,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    Info,
    Warning,
    Critical,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    pub kind: AlarmKind,
    pub severity: Severity,
    /// A stable short name for the condition, e.g. `missing-file`, `crc-errors`.
    pub code: String,
    /// The capture the alarm is about, when there is one.
    pub idx: Option<u64>,
    /// Controller time (s) of the evidence, when known.
    pub t: Option<f64>,
    /// A sentence that explains itself: what was seen, against what threshold.
    pub message: String,
    /// The numbers behind the message.
    pub evidence: serde_json::Value,
    /// What the operator can do about it. Every drift, positioning and reciprocity alarm that
    /// opens a condition says it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub action: Option<String>,
    /// Which captures the condition affects, and what the output does about them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub affects: Option<Affects>,
}

/// What the operator can do, for the conditions several stages raise. Each says what to check,
/// what the output does meanwhile, and whether anything must be taken again.
pub mod action {
    /// A gain drift (a rate).
    pub const GAIN_DRIFT: &str = "Let the lamp warm up and settle, or check its supply; the corrected colours divide the drift out, so no capture needs taking again. If the rate keeps growing, pause the run and re-seat or replace the lamp.";
    /// A gain step.
    pub const GAIN_STEP: &str = "Check the lamp, its supply and anything that may shade the sample or reflect onto it; the step is fitted and divided out of the corrected colours. Steps that recur mean an unstable lamp: pause the run and fix it.";
    /// The sample sits off the arm's rotation centre.
    pub const SAMPLE_OFF_CENTRE: &str = "Check that the sample is centred in its holder and lies flat at the holder's height; at the next chance re-centre it. The drift checks model the pattern from now on, at some cost in precision; drift probes ([probes] every = N) measure the lamp free of it.";
    /// A colour drift of the lamp.
    pub const COLOUR_DRIFT: &str = "Let the lamp settle or check its supply voltage (a colour drift at a steady luminance is the filament's temperature); the corrected colours divide the drift out.";
}

/// What the output does about the captures a condition affects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Handling {
    /// The corrected output divides the condition out: nothing needs taking again.
    Corrected,
    /// The captures are on the retake list.
    Retake,
    /// Neither: the data may be right; the operator has to look.
    Inspect,
}

impl Handling {
    pub fn as_str(self) -> &'static str {
        match self {
            Handling::Corrected => "corrected",
            Handling::Retake => "retake",
            Handling::Inspect => "inspect",
        }
    }
}

/// The captures an alarm's condition affects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scope", rename_all = "kebab-case")]
pub enum Affects {
    /// These captures.
    Captures { idx: Vec<u64>, handling: Handling },
    /// Every capture from `from_idx` on, for as long as the condition lasts.
    Since { from_idx: u64, handling: Handling },
    /// The captures from `from_idx` to `to_idx`, both included: the condition has ended.
    Between {
        from_idx: u64,
        to_idx: u64,
        handling: Handling,
    },
}

impl Affects {
    pub fn handling(&self) -> Handling {
        match self {
            Affects::Captures { handling, .. }
            | Affects::Since { handling, .. }
            | Affects::Between { handling, .. } => *handling,
        }
    }

    /// Whether capture `idx` is among the affected ones.
    pub fn contains(&self, idx: u64) -> bool {
        match self {
            Affects::Captures { idx: v, .. } => v.contains(&idx),
            Affects::Since { from_idx, .. } => idx >= *from_idx,
            Affects::Between {
                from_idx, to_idx, ..
            } => (*from_idx..=*to_idx).contains(&idx),
        }
    }

    /// The captures of both (for alarms of one code aggregated into one): a union of lists,
    /// else from the earliest first capture on; the more demanding handling (retake, then
    /// inspect, then corrected). A list is kept to `max_listed` captures, beyond which it
    /// becomes "from its first on".
    pub fn merge(self, other: Affects, max_listed: usize) -> Affects {
        let rank = |h: Handling| match h {
            Handling::Retake => 2,
            Handling::Inspect => 1,
            Handling::Corrected => 0,
        };
        let handling = if rank(other.handling()) > rank(self.handling()) {
            other.handling()
        } else {
            self.handling()
        };
        let first = |a: &Affects| match a {
            Affects::Captures { idx, .. } => idx.iter().min().copied().unwrap_or(0),
            Affects::Since { from_idx, .. } | Affects::Between { from_idx, .. } => *from_idx,
        };
        let from_idx = first(&self).min(first(&other));
        match (self, other) {
            (Affects::Captures { idx: mut a, .. }, Affects::Captures { idx: b, .. }) => {
                a.extend(b);
                a.sort_unstable();
                a.dedup();
                if a.len() > max_listed {
                    Affects::Since { from_idx, handling }
                } else {
                    Affects::Captures { idx: a, handling }
                }
            }
            _ => Affects::Since { from_idx, handling },
        }
    }

    /// A short phrase for the surfaces, e.g. "captures 3280 on: corrected".
    pub fn describe(&self) -> String {
        let which = match self {
            Affects::Captures { idx, .. } => {
                let list: Vec<String> = idx.iter().map(u64::to_string).collect();
                format!(
                    "capture{} {}",
                    if idx.len() == 1 { "" } else { "s" },
                    list.join(", ")
                )
            }
            Affects::Since { from_idx, .. } => format!("captures {from_idx} on"),
            Affects::Between {
                from_idx, to_idx, ..
            } => format!("captures {from_idx}–{to_idx}"),
        };
        format!("{which}: {}", self.handling().as_str())
    }
}

impl Alarm {
    pub fn new(kind: AlarmKind, severity: Severity, code: &str, message: String) -> Self {
        Alarm {
            kind,
            severity,
            code: code.to_string(),
            idx: None,
            t: None,
            message,
            evidence: serde_json::Value::Null,
            action: None,
            affects: None,
        }
    }
    pub fn at(mut self, idx: Option<u64>, t: Option<f64>) -> Self {
        self.idx = idx;
        self.t = t;
        self
    }
    pub fn with(mut self, evidence: serde_json::Value) -> Self {
        self.evidence = evidence;
        self
    }
    /// What the operator can do, and the captures the condition affects.
    pub fn advise(mut self, action: &str, affects: Option<Affects>) -> Self {
        self.action = Some(action.to_string());
        self.affects = affects;
        self
    }
    /// The captures the condition affects, without an action (a condition that has ended).
    pub fn affecting(mut self, affects: Affects) -> Self {
        self.affects = Some(affects);
        self
    }
}
