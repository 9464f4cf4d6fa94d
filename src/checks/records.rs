//! The checks' records: what goes into `captures.jsonl`, `pairs.jsonl`, `isotropy.jsonl` and the
//! summary, with typed statuses serialised as the strings the files have always held.

use crate::measure::averaging::CaptureStats;
use crate::measure::colour::{ColourDifference, Lab, Xyz};
use crate::measure::kinematics::Angles;
use serde::{Deserialize, Serialize};

/// What became of a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CaptureStatus {
    /// Decoded and averaged: its colour is in the record.
    Ok,
    /// The file was there but could not be used.
    Failed,
    /// The file never appeared.
    Missing,
}

impl CaptureStatus {
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            CaptureStatus::Ok => "ok",
            CaptureStatus::Failed => "failed",
            CaptureStatus::Missing => "missing",
        }
    }
}

impl std::fmt::Display for CaptureStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How a pair was scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PairStatus {
    /// Both captures at the mirrored poses: counted in Table 2.
    Exact,
    /// A partner is not at the mirrored pose: compared, not counted.
    NeedsResampling,
    /// cos θi below the limit: not compared.
    Grazing,
    /// An occlusion substitute against a partner interpolated at the mirrored pose.
    Interpolated,
    /// An occlusion substitute whose partner could not be interpolated.
    Unresolved,
}

impl PairStatus {
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            PairStatus::Exact => "exact",
            PairStatus::NeedsResampling => "needs-resampling",
            PairStatus::Grazing => "grazing",
            PairStatus::Interpolated => "interpolated",
            PairStatus::Unresolved => "unresolved",
        }
    }
}

impl std::fmt::Display for PairStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What the ingestion made of one announced capture.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum Outcome {
    Ok {
        stats: CaptureStats,
        width: usize,
        height: usize,
        size: u64,
        sha256: String,
    },
    Failed {
        error: String,
    },
    Missing {
        reason: String,
    },
}

/// One announced capture with its outcome, as the checker sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureInput {
    pub idx: u64,
    pub entry: usize,
    pub file: String,
    pub t: f64,
    pub cmd: [f64; 4],
    pub enc: [f64; 4],
    pub substitute: Option<f64>,
    pub probe: bool,
    pub outcome: Outcome,
}

/// One line of `captures.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaptureRecord {
    pub idx: u64,
    pub entry: usize,
    pub light: usize,
    pub camera: usize,
    pub probe: bool,
    /// A probe of the joint-3 sentinel's pose (`detect::sentinel`), not of the lamp's: it is
    /// no point of the lamp's gain curve.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub sentinel: bool,
    pub t: f64,
    pub file: String,
    pub status: CaptureStatus,
    pub error: Option<String>,
    pub mean_rgb: Option<[f64; 3]>,
    pub xyz: Option<Xyz>,
    pub lab: Option<Lab>,
    pub pixels: Option<u64>,
    pub nonfinite: Option<u64>,
    pub clipped: Option<u64>,
    pub negative: Option<u64>,
    /// Angles of the pose the capture was placed by: the encoder pose, or the commanded pose
    /// when `by_command`.
    pub angles: Option<Angles>,
    /// θi the rig used instead of the plan's (occlusion substitute).
    pub substitute: Option<f64>,
    /// Largest angle between a placed and a planned direction (degrees).
    pub pose_error_deg: Option<f64>,
    /// Placed by the commanded pose: its encoders disagreed with the commands by a steady
    /// offset while the commands were on the plan (`checks::capture`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub by_command: bool,
    /// The XYZ with the gain drift known at check time divided out, when there is an estimate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_corrected: Option<GainCorrected>,
}

/// A capture's drift-corrected colour: xyz / g(t), with g from the drift probes when enabled
/// (the current segment's line: its level includes steps) or else from isotropy classes (a rate
/// from the start of the run: steps are not in it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GainCorrected {
    pub xyz: Xyz,
    /// The gain divided out, g(t) relative to the start (probes: to the probe pose's original).
    pub gain: f64,
    /// Relative standard uncertainty of the correction.
    pub sigma_rel: f64,
    /// `probes` or `isotropy classes`.
    pub source: String,
    /// The lamp's colour change divided out of X and Z as well (from isotropy classes, else the
    /// probes): ln(X/Y) and ln(Z/Y) relative to the start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<[f64; 2]>,
}

/// One line of `pairs.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairRecord {
    /// Capture indices, earlier first.
    pub a: u64,
    pub b: u64,
    pub entries: [usize; 2],
    pub status: PairStatus,
    /// Largest angle between one capture's ωi and the other's ωo (degrees).
    pub mismatch_deg: f64,
    pub t: f64,
    pub xyz_a: Option<Xyz>,
    pub xyz_b: Option<Xyz>,
    pub diff: Option<ColourDifference>,
    /// Either capture was placed by the commanded pose, not by its encoders: the pair holds
    /// only if the arm went where it was told.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub by_command: bool,
    /// For an `interpolated` (or `unresolved`) pair: how the partner was made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolated: Option<Interpolation>,
}

/// The partner of an occlusion substitute, interpolated from the session's own captures of the
/// partner's light direction at the exact mirrored pose (`measure::resample`, slice layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Interpolation {
    /// The plan light direction whose captures were interpolated.
    pub light: usize,
    /// `cshep2d` or `qshep2d`; empty when unresolved.
    pub method: String,
    /// Captures used as nodes.
    pub nodes: usize,
    /// The interpolated partner's uncertainty: the nodal functions' spread per XYZ channel, in
    /// the units of the re-corrected partner `xyz_b`.
    pub spread_xyz: Option<Xyz>,
    /// ΔE00 between the partner and the partner moved by one spread: the pair's ΔE00 is only
    /// meaningful beyond this.
    pub sigma_de2000: Option<f64>,
    /// Why no partner could be interpolated.
    pub error: Option<String>,
}

/// One line of `isotropy.jsonl`: a capture against the mean of its class's earlier members.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IsotropyRecord {
    pub idx: u64,
    pub entry: usize,
    pub class: [f64; 3],
    pub earlier_members: usize,
    pub diff: ColourDifference,
}

/// Running means in the form of the paper's Table 2.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Table2 {
    pub pairs: u64,
    pub abs_dx: f64,
    pub abs_dy: f64,
    pub abs_dz: f64,
    pub de76: f64,
    pub dc: f64,
    pub dh: f64,
    pub de2000: f64,
}

impl Table2 {
    /// No pair taken yet.
    pub(crate) fn is_empty(&self) -> bool {
        self.pairs == 0
    }

    /// Take one difference into the running means. A difference with a non-finite value is
    /// left out: one NaN would poison every mean for the rest of the run.
    pub(crate) fn add(&mut self, d: &ColourDifference) {
        let values = [
            d.abs_dxyz[0],
            d.abs_dxyz[1],
            d.abs_dxyz[2],
            d.de76,
            d.dc,
            d.dh,
            d.de2000,
        ];
        if !values.iter().all(|v| v.is_finite()) {
            return;
        }
        let n = self.pairs as f64;
        let upd = |m: &mut f64, v: f64| *m = (*m * n + v) / (n + 1.0);
        upd(&mut self.abs_dx, d.abs_dxyz[0]);
        upd(&mut self.abs_dy, d.abs_dxyz[1]);
        upd(&mut self.abs_dz, d.abs_dxyz[2]);
        upd(&mut self.de76, d.de76);
        upd(&mut self.dc, d.dc);
        upd(&mut self.dh, d.dh);
        upd(&mut self.de2000, d.de2000);
        self.pairs += 1;
    }
}

/// Counters for the summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CheckCounts {
    pub captures: u64,
    pub ok: u64,
    pub failed: u64,
    pub missing: u64,
    pub probes: u64,
    pub pairs_exact: u64,
    pub pairs_needs_resampling: u64,
    pub pairs_grazing: u64,
    /// Occlusion substitutes scored against an interpolated partner, and those that could not be.
    #[serde(default)]
    pub pairs_interpolated: u64,
    #[serde(default)]
    pub pairs_unresolved: u64,
    pub isotropy_comparisons: u64,
    /// Interpolated pairs fed to the isotropy drift fit (weighted by their spread).
    #[serde(default)]
    pub drift_interpolated: u64,
    /// Pairs left out of the isotropy drift fit because their later capture comes after a
    /// named joint slip (the tilt moves the members of a class differently).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub drift_left_out_slip: u64,
    /// Captures placed off the plan, and captures whose encoders disagreed with the
    /// commanded pose (their alarms are raised once per episode).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub pose_off_plan: u64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub encoder_mismatch: u64,
    /// Captures placed by the commanded pose during a steady encoder offset.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub placed_by_command: u64,
    pub alarms: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// The drift probes' gain curve as the result files give it: each usable probe brighter than the
/// dark level, its Y over the Y of the first usable capture of the same plan entry. The one
/// definition the report, the status page and `compare` share.
#[derive(Debug, Clone, Default)]
pub struct ProbeGainCurve {
    dark_y: f64,
    /// Per plan entry: the time (s) and Y of its first usable capture.
    first: std::collections::BTreeMap<usize, (f64, f64)>,
}

impl ProbeGainCurve {
    pub fn new(dark_y: f64) -> Self {
        ProbeGainCurve {
            dark_y,
            first: Default::default(),
        }
    }

    /// Take the next capture record; a lamp probe gives its point (hours, gain).
    pub(crate) fn add(&mut self, c: &CaptureRecord) -> Option<(f64, f64)> {
        let xyz = c
            .xyz
            .filter(|_| c.status == CaptureStatus::Ok && !c.sentinel)?;
        if !c.probe {
            self.first.entry(c.entry).or_insert((c.t, xyz[1]));
            return None;
        }
        let &(_, y0) = self.first.get(&c.entry)?;
        (xyz[1] > self.dark_y && y0 > 0.0).then(|| (c.t / 3600.0, xyz[1] / y0))
    }

    /// The time (s) of the first usable capture of an entry, the curve's origin for its probes.
    pub(crate) fn origin_s(&self, entry: usize) -> Option<f64> {
        self.first.get(&entry).map(|(t, _)| *t)
    }
}
