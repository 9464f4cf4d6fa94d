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
}
