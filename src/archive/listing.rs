//! A capture folder's files → the captures of the plan, in acquisition order, with their times.
//!
//! A file is placed by its name (the `[source] pattern`) or by its row in a sidecar table. The
//! angles must lie within `angle_tolerance_deg` of a plan direction; a file that cannot be placed
//! is listed in [`Listing::skipped`] with the reason, never guessed. Sidecar rows whose file is
//! absent are kept as captures, so that the ingestion records them as missing.

use super::{OrderRule, SourceSpec};
use crate::measure::geometry::{angle_between, Spherical};
use crate::measure::kinematics::Rig;
use crate::measure::plan::SamplingPlan;
use regex::Regex;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use thiserror::Error;

/// What the listing knows of one file (the shell reads the folder; time is data).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FileFact {
    /// Path relative to the capture folder, with `/` separators.
    pub name: String,
    /// Modification time, seconds since the Unix epoch.
    pub mtime_s: Option<f64>,
    /// Size in bytes (with the time, how watch mode tells that a file changed).
    pub size: Option<u64>,
}

/// One row of a sidecar table.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SidecarRow {
    pub file: String,
    #[serde(default)]
    pub theta_i: Option<f64>,
    #[serde(default)]
    pub phi_i: Option<f64>,
    #[serde(default)]
    pub theta_o: Option<f64>,
    #[serde(default)]
    pub phi_o: Option<f64>,
    #[serde(default)]
    pub entry: Option<usize>,
    #[serde(default)]
    pub idx: Option<u64>,
    #[serde(default)]
    pub t: Option<f64>,
    /// Relative exposure of a low-dynamic-range capture (not used for HDR files).
    #[serde(default)]
    pub exposure: Option<f64>,
}

#[derive(Debug, Error, PartialEq)]
pub(crate) enum ListingError {
    #[error("source.pattern does not compile: {0}")]
    Pattern(String),
    #[error("source.pattern needs the named groups tl, pl, tv and pv, or entry")]
    PatternGroups,
    #[error("source.order = \"index\" needs an idx group in the pattern or an idx column in the sidecar")]
    NoIndex,
    #[error("source.order = \"time\" needs a sidecar with a t column")]
    NoTimes,
    #[error("sidecar line {line}: {message}")]
    Sidecar { line: usize, message: String },
}

/// Why a file is not among the captures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SkipReason {
    /// Its name does not end in one of `[source] extensions`.
    NotACapture,
    /// Its name does not match the pattern.
    NoMatch,
    /// The sidecar has no row for it.
    NotInSidecar,
    /// Its angles or entry are not in the plan.
    NotInPlan(String),
    /// Another file stands for the same plan entry and is preferred by [`DUPLICATE_RULE`].
    Duplicate { entry: usize, kept: String },
    /// The order or time it needs is missing.
    Unordered(String),
    /// A symbolic link: links are not followed (a capture is a file of the folder).
    Link,
    /// Its name is not valid UTF-8 (shown with the invalid bytes replaced).
    NameNotUtf8,
}

impl SkipReason {
    /// The reason's kind, as the summary counts skipped files.
    pub(crate) fn kind(&self) -> &'static str {
        match self {
            SkipReason::NotACapture => "not-a-capture",
            SkipReason::NoMatch => "no-match",
            SkipReason::NotInSidecar => "not-in-sidecar",
            SkipReason::NotInPlan(_) => "not-in-plan",
            SkipReason::Duplicate { .. } => "duplicate",
            SkipReason::Unordered(_) => "unordered",
            SkipReason::Link => "link",
            SkipReason::NameNotUtf8 => "name-not-utf8",
        }
    }
}

impl std::fmt::Display for SkipReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SkipReason::NotACapture => write!(f, "not a capture file type"),
            SkipReason::NoMatch => write!(f, "the name does not match source.pattern"),
            SkipReason::NotInSidecar => write!(f, "no row in the sidecar"),
            SkipReason::NotInPlan(why) => write!(f, "not in the plan: {why}"),
            SkipReason::Duplicate { entry, kept } => {
                write!(f, "plan entry {entry} again ({kept} is kept)")
            }
            SkipReason::Unordered(why) => write!(f, "{why}"),
            SkipReason::Link => write!(
                f,
                "a symbolic link: links are not followed; copy the file into the folder"
            ),
            SkipReason::NameNotUtf8 => write!(f, "the name is not valid UTF-8; rename the file"),
        }
    }
}

/// Where the capture times come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub(crate) enum TimeSource {
    Sidecar,
    Mtime,
    /// No times: capture position × this many seconds.
    Index {
        seconds_per_capture: f64,
    },
}

/// One capture of the listing, in acquisition order.
#[derive(Debug, Clone, PartialEq)]
pub struct ArchiveCapture {
    pub file: String,
    pub entry: usize,
    /// Seconds since the first capture.
    pub t: f64,
    /// The plan's pose for the entry (q1, q2, q3, wagon), as commanded and as read.
    pub pose: [f64; 4],
    /// θi used when the plan entry needs a substitute pose.
    pub sub: Option<f64>,
    /// Relative exposure from the sidecar (the capture's linear values are divided by it).
    pub exposure: Option<f64>,
}

/// Which of several files placed on one plan entry stands for it, in both `check` and watch
/// mode (said in docs/commands.md and the alarm).
pub(crate) const DUPLICATE_RULE: &str = "the file fewest folders deep, then the one with the shortest name (copies add \" copy\" or \" (1)\"), then the one whose extension is written as in source.extensions, then the earliest in the capture order, then the first by name";

/// Files placed on the same plan entry: the one kept by [`DUPLICATE_RULE`] and the others.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DuplicateGroup {
    pub entry: usize,
    /// The file checked for the entry.
    pub kept: String,
    pub others: Vec<String>,
    /// Watch mode only: the file the rule keeps, when it arrived after `kept` was checked (a
    /// checked capture is not taken back; `check` of the finished folder keeps this one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rule_prefers: Option<String>,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Listing {
    pub captures: Vec<ArchiveCapture>,
    /// The absolute time (seconds; since the Unix epoch for modification times) that the
    /// captures' `t` count from: 0 when the times are capture positions.
    pub origin_s: f64,
    /// Plan entries that more than one file was placed on, in entry order.
    pub duplicates: Vec<DuplicateGroup>,
    pub skipped: Vec<(String, SkipReason)>,
    pub order: OrderRule,
    pub times: TimeSource,
    /// The plan's entries that no capture stands for (no file, or only files that were
    /// skipped), in entry order.
    pub unfilled: Vec<usize>,
}

impl Listing {
    /// One paragraph for the operator: what was found, the order and the times used.
    pub(crate) fn describe(&self) -> String {
        let order = match self.order {
            OrderRule::Index => "the capture index in the names or the sidecar",
            OrderRule::Time => "the sidecar's times",
            OrderRule::Mtime => "the files' modification times",
            OrderRule::Plan | OrderRule::Auto => "the plan's acquisition order of the entries",
        };
        let times = match self.times {
            TimeSource::Sidecar => "times from the sidecar".to_string(),
            TimeSource::Mtime => "times from the files' modification times".to_string(),
            TimeSource::Index {
                seconds_per_capture,
            } => format!(
                "no capture times: capture index × {seconds_per_capture} s (source.seconds_per_capture), so drift rates are per capture index, not per hour of the run"
            ),
        };
        let unfilled = match self.unfilled.len() {
            0 => String::new(),
            n => {
                let first: Vec<String> = self
                    .unfilled
                    .iter()
                    .take(8)
                    .map(|e| e.to_string())
                    .collect();
                format!(
                    "; {n} plan entries have no capture ({}{}): they are reported as not captured",
                    first.join(", "),
                    if n > 8 { ", …" } else { "" }
                )
            }
        };
        format!(
            "{} captures placed, {} files skipped{unfilled}; order: {order}; {times}",
            self.captures.len(),
            self.skipped.len()
        )
    }
}

/// Parse a sidecar's text: CSV with a header row when `csv`, else JSON lines.
pub(crate) fn parse_sidecar(text: &str, csv: bool) -> Result<Vec<SidecarRow>, ListingError> {
    if csv {
        let mut r = ::csv::ReaderBuilder::new()
            .trim(::csv::Trim::All)
            .from_reader(text.as_bytes());
        r.deserialize()
            .enumerate()
            .map(|(k, row)| {
                row.map_err(|e| ListingError::Sidecar {
                    line: k + 2,
                    message: e.to_string(),
                })
            })
            .collect()
    } else {
        text.lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
            .map(|(k, l)| {
                serde_json::from_str(l).map_err(|e| ListingError::Sidecar {
                    line: k + 1,
                    message: e.to_string(),
                })
            })
            .collect()
    }
}

/// Compile and check `[source] pattern`.
pub(crate) fn compile_pattern(pattern: &str) -> Result<Regex, ListingError> {
    let re = Regex::new(pattern).map_err(|e| ListingError::Pattern(e.to_string()))?;
    let names: BTreeSet<&str> = re.capture_names().flatten().collect();
    let angles = ["tl", "pl", "tv", "pv"].iter().all(|g| names.contains(g));
    if !angles && !names.contains("entry") {
        return Err(ListingError::PatternGroups);
    }
    Ok(re)
}

/// Where one file says it belongs.
#[derive(Debug, Clone, Copy)]
struct Placement {
    angles: Option<[f64; 4]>,
    entry: Option<usize>,
    idx: Option<u64>,
    t: Option<f64>,
    mtime: Option<f64>,
    exposure: Option<f64>,
}

fn wanted(name: &str, spec: &SourceSpec) -> bool {
    let lower = name.to_ascii_lowercase();
    spec.extensions
        .iter()
        .any(|e| lower.ends_with(&format!(".{}", e.to_ascii_lowercase())))
}

/// A file's place in [`DUPLICATE_RULE`] before the capture order: folders deep, length of its
/// own name, and whether its extension is written otherwise than in `source.extensions`.
fn duplicate_rank(name: &str, spec: &SourceSpec) -> (usize, usize, bool) {
    let depth = name.matches('/').count();
    let own = name.rsplit('/').next().unwrap_or(name);
    let ext = own.rsplit_once('.').map(|(_, e)| e).unwrap_or("");
    let as_configured = spec.extensions.iter().any(|e| e == ext);
    (depth, own.chars().count(), !as_configured)
}

/// The farthest a capture's modification time may lie from the set's median under
/// `order = "mtime"`: the span of controller time a CAPTURE line may carry (1e7 s, 116 days).
const MAX_MTIME_SPREAD_S: f64 = 1e7;

/// Whether (θ, φ) in degrees names a direction without wrapping: θ ∈ [0, 90], φ ∈ [0, 360]
/// (false for NaN).
fn angles_in_range(theta: f64, phi: f64) -> bool {
    (0.0..=90.0).contains(&theta) && (0.0..=360.0).contains(&phi)
}

/// The plan direction within `tol_deg` of (θ, φ), if any (the nearest).
fn direction_of(plan: &SamplingPlan, theta: f64, phi: f64, tol_deg: f64) -> Option<usize> {
    let v = Spherical::from_deg(theta, phi).to_vector();
    plan.directions()
        .iter()
        .map(|d| {
            (
                d.index,
                angle_between(&v, &d.spherical().to_vector()).to_degrees(),
            )
        })
        .filter(|(_, a)| *a <= tol_deg)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// A file placed by its name (the pattern) or its sidecar row, before the plan is consulted.
type Named = (String, Placement);
/// A placed file and its plan entry.
type Placed = (String, Placement, usize);
type Skipped = Vec<(String, SkipReason)>;

/// What each file says of its capture: by the sidecar's rows when there is one, else by the
/// pattern; the files that say nothing are skipped with why.
fn placements(
    files: &[FileFact],
    sidecar: Option<&[SidecarRow]>,
    spec: &SourceSpec,
) -> Result<(Vec<Named>, Skipped), ListingError> {
    let mut skipped: Skipped = Vec::new();
    let mut placed: Vec<Named> = Vec::new();
    let mtimes: BTreeMap<&str, Option<f64>> =
        files.iter().map(|f| (f.name.as_str(), f.mtime_s)).collect();
    let sidecar_name = spec
        .sidecar
        .as_ref()
        .map(|p| p.to_string_lossy().replace('\\', "/"));
    match sidecar {
        Some(rows) => {
            let listed: BTreeSet<&str> = rows.iter().map(|r| r.file.as_str()).collect();
            for f in files {
                if Some(&f.name) == sidecar_name.as_ref() {
                    continue;
                }
                if !listed.contains(f.name.as_str()) {
                    let why = if wanted(&f.name, spec) {
                        SkipReason::NotInSidecar
                    } else {
                        SkipReason::NotACapture
                    };
                    skipped.push((f.name.clone(), why));
                }
            }
            for r in rows {
                let angles = match (r.theta_i, r.phi_i, r.theta_o, r.phi_o) {
                    (Some(a), Some(b), Some(c), Some(d)) => Some([a, b, c, d]),
                    _ => None,
                };
                placed.push((
                    r.file.clone(),
                    Placement {
                        angles,
                        entry: r.entry,
                        idx: r.idx,
                        t: r.t,
                        mtime: mtimes.get(r.file.as_str()).copied().flatten(),
                        exposure: r.exposure,
                    },
                ));
            }
        }
        None => {
            let re = compile_pattern(&spec.pattern)?;
            for f in files {
                if !wanted(&f.name, spec) {
                    skipped.push((f.name.clone(), SkipReason::NotACapture));
                    continue;
                }
                let Some(c) = re.captures(&f.name) else {
                    skipped.push((f.name.clone(), SkipReason::NoMatch));
                    continue;
                };
                let num = |g: &str| c.name(g).and_then(|m| m.as_str().parse::<f64>().ok());
                let angles = match (num("tl"), num("pl"), num("tv"), num("pv")) {
                    (Some(a), Some(b), Some(cc), Some(d)) => Some([a, b, cc, d]),
                    _ => None,
                };
                placed.push((
                    f.name.clone(),
                    Placement {
                        angles,
                        entry: c.name("entry").and_then(|m| m.as_str().parse().ok()),
                        idx: c.name("idx").and_then(|m| m.as_str().parse().ok()),
                        t: None,
                        mtime: f.mtime_s,
                        exposure: None,
                    },
                ));
            }
        }
    }
    Ok((placed, skipped))
}

/// The plan entry a placement names: its entry, or the plan directions within `tol` degrees of
/// its angles; why not, when it names none.
fn entry_of(p: &Placement, plan: &SamplingPlan, tol: f64) -> Result<usize, String> {
    match (p.entry, p.angles) {
        (Some(e), _) if e < plan.capture_count() => Ok(e),
        (Some(e), _) => Err(format!("entry {e} (the plan has {})", plan.capture_count())),
        (None, Some([tl, pl, tv, pv])) if !angles_in_range(tl, pl) || !angles_in_range(tv, pv) => {
            // a θ below 0 or beyond 90° or a φ outside [0°, 360°] would wrap onto another
            // direction (θ = −15° is θ = 15° turned by 180°): a wrong name, never a placement
            Err(format!(
                "light ({tl}°, {pl}°) or camera ({tv}°, {pv}°) is outside θ ∈ [0°, 90°], φ ∈ [0°, 360°]"
            ))
        }
        (None, Some([tl, pl, tv, pv])) => {
            let finite = [tl, pl, tv, pv].iter().all(|v| v.is_finite());
            match (
                finite.then(|| direction_of(plan, tl, pl, tol)).flatten(),
                finite.then(|| direction_of(plan, tv, pv, tol)).flatten(),
            ) {
                (Some(l), Some(c)) => plan
                    .index_of(l, c)
                    .ok_or_else(|| "no such entry".to_string()),
                _ => Err(format!(
                    "light ({tl}°, {pl}°) or camera ({tv}°, {pv}°) is more than {tol}° from every plan direction"
                )),
            }
        }
        (None, None) => Err("no angles and no entry".into()),
    }
}

/// Under `order = "mtime"`: the placed files that have a modification time near the set's
/// median, in order; the others are skipped with why.
fn with_usable_mtimes(entries: Vec<Placed>, skipped: &mut Skipped) -> Vec<Placed> {
    let (with, without): (Vec<_>, Vec<_>) =
        entries.into_iter().partition(|(_, p, _)| p.mtime.is_some());
    for (name, _, _) in without {
        skipped.push((
            name,
            SkipReason::Unordered("no modification time (the file is absent)".into()),
        ));
    }
    // a modification time far from the set's median (a file from 1970, a copy that reset
    // its time) would put every other capture beyond the longest run a controller time may
    // span, and the whole set would be refused: that file is left out instead
    let mut times: Vec<f64> = with.iter().filter_map(|(_, p, _)| p.mtime).collect();
    times.sort_by(f64::total_cmp);
    let median = times.get(times.len() / 2).copied().unwrap_or(0.0);
    let (kept, far): (Vec<_>, Vec<_>) = with.into_iter().partition(|(_, p, _)| {
        p.mtime
            .is_some_and(|m| (m - median).abs() <= MAX_MTIME_SPREAD_S)
    });
    for (name, p, _) in far {
        skipped.push((
            name,
            SkipReason::Unordered(format!(
                "its modification time is {:.0} days from the set's median ({:.0} s since 1970 against {median:.0}): a clock or a copy changed it, so it cannot be ordered by time; set source.order = \"plan\" (or a sidecar with times) to place it",
                (p.mtime.unwrap_or(0.0) - median).abs() / 86_400.0,
                p.mtime.unwrap_or(0.0)
            )),
        ));
    }
    kept
}

/// One file per plan entry, by [`DUPLICATE_RULE`] (`order_of`: the capture order); the others
/// are skipped and grouped.
fn one_per_entry(
    entries: Vec<Placed>,
    spec: &SourceSpec,
    order_of: &dyn Fn(&Placed, &Placed) -> std::cmp::Ordering,
    skipped: &mut Skipped,
) -> (Vec<Placed>, Vec<DuplicateGroup>) {
    let mut by_entry: BTreeMap<usize, Vec<Placed>> = BTreeMap::new();
    for e in entries {
        by_entry.entry(e.2).or_default().push(e);
    }
    let mut duplicates = Vec::new();
    let mut entries = Vec::new();
    for (entry, mut files) in by_entry {
        files.sort_by(|a, b| {
            duplicate_rank(&a.0, spec)
                .cmp(&duplicate_rank(&b.0, spec))
                .then_with(|| order_of(a, b))
        });
        let mut files = files.into_iter();
        let Some(kept) = files.next() else { continue };
        let others: Vec<String> = files.map(|(name, _, _)| name).collect();
        for name in &others {
            skipped.push((
                name.clone(),
                SkipReason::Duplicate {
                    entry,
                    kept: kept.0.clone(),
                },
            ));
        }
        if !others.is_empty() {
            duplicates.push(DuplicateGroup {
                entry,
                kept: kept.0.clone(),
                others,
                rule_prefers: None,
            });
        }
        entries.push(kept);
    }
    (entries, duplicates)
}

/// The capture of a placed file at time `t` (seconds from the first): the plan's pose by the
/// rig model; why not, when the entry, the pose, the time or the exposure cannot be used.
fn capture_of(
    name: &str,
    p: &Placement,
    entry: usize,
    t: Option<f64>,
    plan: &SamplingPlan,
    rig: &Rig,
) -> Result<ArchiveCapture, SkipReason> {
    let pe = plan
        .entry(entry)
        .map_err(|e| SkipReason::NotInPlan(e.to_string()))?;
    let dirs = plan.directions();
    let planned = rig
        .plan_pose(dirs[pe.light].spherical(), dirs[pe.camera].spherical())
        .map_err(|_| {
            SkipReason::NotInPlan(format!("the rig model cannot take plan entry {entry}"))
        })?;
    let t = t
        .filter(|t| t.is_finite() && *t >= 0.0)
        .ok_or_else(|| SkipReason::Unordered("no usable time".into()))?;
    if let Some(e) = p.exposure.filter(|e| !(e.is_finite() && *e > 0.0)) {
        return Err(SkipReason::NotInPlan(format!(
            "exposure {e} is not a positive number"
        )));
    }
    let j = planned.pose.joints_deg;
    Ok(ArchiveCapture {
        file: name.to_string(),
        entry,
        t,
        pose: [j[0], j[1], j[2], planned.pose.wagon_deg],
        sub: planned.substitute.map(|(_, used)| used),
        exposure: p.exposure,
    })
}

/// Place `files` (and the sidecar's rows, when given) on `plan`.
pub(crate) fn build(
    files: &[FileFact],
    sidecar: Option<&[SidecarRow]>,
    spec: &SourceSpec,
    plan: &SamplingPlan,
    rig: &Rig,
) -> Result<Listing, ListingError> {
    let (placed, mut skipped) = placements(files, sidecar, spec)?;
    // the plan entry of each placed file
    let tol = spec.angle_tolerance_deg;
    let mut entries: Vec<Placed> = Vec::new();
    for (name, p) in placed {
        let entry = entry_of(&p, plan, tol);
        match entry {
            Ok(e) => entries.push((name, p, e)),
            Err(why) => skipped.push((name, SkipReason::NotInPlan(why))),
        }
    }
    // the order
    let has_idx = !entries.is_empty() && entries.iter().all(|(_, p, _)| p.idx.is_some());
    let has_t = !entries.is_empty() && entries.iter().all(|(_, p, _)| p.t.is_some());
    let order = match spec.order {
        OrderRule::Auto if has_idx => OrderRule::Index,
        OrderRule::Auto if has_t => OrderRule::Time,
        OrderRule::Auto => OrderRule::Plan,
        OrderRule::Index if !has_idx && !entries.is_empty() => return Err(ListingError::NoIndex),
        OrderRule::Time if !has_t && !entries.is_empty() => return Err(ListingError::NoTimes),
        o => o,
    };
    if order == OrderRule::Mtime {
        entries = with_usable_mtimes(entries, &mut skipped);
    }
    let key = |p: &Placement, e: usize| -> (f64, usize) {
        match order {
            OrderRule::Index => (p.idx.unwrap_or(u64::MAX) as f64, e),
            OrderRule::Time => (p.t.unwrap_or(f64::INFINITY), e),
            OrderRule::Mtime => (p.mtime.unwrap_or(f64::INFINITY), e),
            _ => (e as f64, e),
        }
    };
    let order_of = |a: &Placed, b: &Placed| {
        let (ka, kb) = (key(&a.1, a.2), key(&b.1, b.2));
        ka.0.total_cmp(&kb.0)
            .then(ka.1.cmp(&kb.1))
            .then(a.0.cmp(&b.0))
    };
    let (mut entries, duplicates) = one_per_entry(entries, spec, &order_of, &mut skipped);
    entries.sort_by(order_of);
    // times, relative to the first capture
    let times = match order {
        OrderRule::Time => TimeSource::Sidecar,
        OrderRule::Mtime => TimeSource::Mtime,
        _ if has_t => TimeSource::Sidecar,
        _ => TimeSource::Index {
            seconds_per_capture: spec.seconds_per_capture,
        },
    };
    let t0 = match times {
        TimeSource::Sidecar => entries
            .iter()
            .filter_map(|e| e.1.t)
            .fold(f64::INFINITY, f64::min),
        TimeSource::Mtime => entries
            .iter()
            .filter_map(|e| e.1.mtime)
            .fold(f64::INFINITY, f64::min),
        TimeSource::Index { .. } => 0.0,
    };
    let mut seen: BTreeMap<usize, String> = BTreeMap::new();
    let mut captures = Vec::new();
    for (name, p, entry) in entries {
        let t = match times {
            TimeSource::Sidecar => p.t.map(|t| t - t0),
            TimeSource::Mtime => p.mtime.map(|t| t - t0),
            TimeSource::Index {
                seconds_per_capture,
            } => Some(captures.len() as f64 * seconds_per_capture),
        };
        match capture_of(&name, &p, entry, t, plan, rig) {
            Ok(c) => {
                seen.insert(entry, name);
                captures.push(c);
            }
            Err(why) => skipped.push((name, why)),
        }
    }
    skipped.sort_by(|a, b| a.0.cmp(&b.0));
    let unfilled = (0..plan.capture_count())
        .filter(|e| !seen.contains_key(e))
        .collect();
    let origin_s = match times {
        TimeSource::Index { .. } => 0.0,
        _ if t0.is_finite() => t0,
        _ => 0.0,
    };
    Ok(Listing {
        captures,
        origin_s,
        duplicates,
        skipped,
        order,
        times,
        unfilled,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::archive::{SourceKind, BONN_PATTERN};
    use crate::measure::kinematics::RigSpec;

    fn setup() -> (SamplingPlan, Rig, SourceSpec) {
        let spec = SourceSpec {
            kind: SourceKind::Files,
            ..SourceSpec::default()
        };
        (
            SamplingPlan::ubo(),
            Rig::new(RigSpec::default()).unwrap(),
            spec,
        )
    }

    fn bonn(plan: &SamplingPlan, entry: usize, idx: Option<usize>) -> String {
        let e = plan.entry(entry).unwrap();
        let (l, c) = (plan.directions()[e.light], plan.directions()[e.camera]);
        let name = format!(
            "tl{:03.0}_pl{:03.0}_tv{:03.0}_pv{:03.0}.hdr",
            l.theta_deg, l.phi_deg, c.theta_deg, c.phi_deg
        );
        match idx {
            Some(i) => format!("{i:05} {name}"),
            None => format!("set/{name}"),
        }
    }

    fn facts(names: &[String]) -> Vec<FileFact> {
        names
            .iter()
            .map(|n| FileFact {
                name: n.clone(),
                mtime_s: None,
                size: None,
            })
            .collect()
    }

    #[test]
    fn bonn_names_are_placed_on_their_plan_entries_in_plan_order() {
        let (plan, rig, spec) = setup();
        let entries = [5usize, 0, 81 * 40 + 7, 6560, 100];
        let names: Vec<String> = entries.iter().map(|&e| bonn(&plan, e, None)).collect();
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        assert!(l.skipped.is_empty(), "{:?}", l.skipped);
        assert_eq!(l.order, OrderRule::Plan);
        let got: Vec<usize> = l.captures.iter().map(|c| c.entry).collect();
        assert_eq!(got, [0, 5, 100, 81 * 40 + 7, 6560]);
        // no times: position × seconds_per_capture, and the listing says so
        assert_eq!(l.captures[2].t, 14.0);
        assert!(l.describe().contains("per capture index"));
        // entry 0 (light = camera) needs the rig's substitute pose, as the controller would send
        let want = rig
            .plan_pose(
                plan.directions()[0].spherical(),
                plan.directions()[0].spherical(),
            )
            .unwrap();
        assert_eq!(l.captures[0].sub, want.substitute.map(|s| s.1));
        assert!(l.captures[0].sub.is_some());
    }

    /// A full Bonn set with twelve files deleted and one entry present only as a file that
    /// cannot be placed: the thirteen entries are the listing's unfilled ones, and it says so.
    #[test]
    fn plan_entries_without_a_placed_file_are_listed_as_unfilled() {
        let (plan, rig, spec) = setup();
        let gone: Vec<usize> = (0..12).map(|k| 17 + k * 521).collect();
        let mut names: Vec<String> = (0..plan.capture_count())
            .filter(|e| !gone.contains(e) && *e != 6000)
            .map(|e| bonn(&plan, e, None))
            .collect();
        // entry 6000's file under a name the pattern does not match
        names.push("set/IMG_6000.hdr".into());
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        let mut want = gone.clone();
        want.push(6000);
        want.sort();
        assert_eq!(l.unfilled, want);
        assert_eq!(l.captures.len(), plan.capture_count() - 13);
        assert!(
            l.describe()
                .contains("13 plan entries have no capture (17, 538,"),
            "{}",
            l.describe()
        );
    }

    #[test]
    fn a_leading_index_orders_the_captures() {
        let (plan, rig, spec) = setup();
        let names = vec![
            bonn(&plan, 9, Some(2)),
            bonn(&plan, 3, Some(1)),
            bonn(&plan, 7, Some(0)),
        ];
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.order, OrderRule::Index);
        let got: Vec<usize> = l.captures.iter().map(|c| c.entry).collect();
        assert_eq!(got, [7, 3, 9]);
    }

    #[test]
    fn what_cannot_be_placed_is_skipped_with_its_reason() {
        let (plan, rig, spec) = setup();
        let names = vec![
            "readme.txt".to_string(),
            "IMG_0001.hdr".to_string(),
            "tl017_pl000_tv000_pv000.hdr".to_string(),
            "tl015_pl000_tv000_pv000.hdr".to_string(),
            "copy/tl015_pl000_tv000_pv000.EXR".to_string(),
        ];
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures.len(), 1);
        let why: BTreeMap<&str, &SkipReason> =
            l.skipped.iter().map(|(n, r)| (n.as_str(), r)).collect();
        assert_eq!(why["readme.txt"], &SkipReason::NotACapture);
        assert_eq!(why["IMG_0001.hdr"], &SkipReason::NoMatch);
        assert!(matches!(
            why["tl017_pl000_tv000_pv000.hdr"],
            SkipReason::NotInPlan(_)
        ));
        // the same entry twice: the top-level file is kept, the other named
        let dup = why
            .iter()
            .find(|(_, r)| matches!(r, SkipReason::Duplicate { .. }))
            .unwrap();
        assert_eq!(*dup.0, "copy/tl015_pl000_tv000_pv000.EXR");
        assert!(dup.1.to_string().contains("is kept"), "{}", dup.1);
    }

    /// Copies, a sub-folder, an upper-case twin and a later index of one entry: the original
    /// is kept whatever the byte order of the names, and the group names the others.
    #[test]
    fn duplicates_are_settled_by_the_rule_not_by_the_byte_order_of_names() {
        let (plan, rig, spec) = setup();
        let name = bonn(&plan, 100, None)
            .trim_start_matches("set/")
            .to_string();
        let stem = name.trim_end_matches(".hdr");
        let names = vec![
            format!("rejected/{name}"),
            format!("{stem} copy.hdr"),
            format!("{stem} (1).hdr"),
            format!("{}.HDR", stem.to_uppercase()),
            name.clone(),
        ];
        for rotate in 0..names.len() {
            let mut n = names.clone();
            n.rotate_left(rotate);
            let l = build(&facts(&n), None, &spec, &plan, &rig).unwrap();
            assert_eq!(l.captures.len(), 1);
            assert_eq!(l.captures[0].file, name);
            assert_eq!(l.duplicates.len(), 1);
            let g = &l.duplicates[0];
            assert_eq!((g.entry, g.kept.as_str()), (100, name.as_str()));
            let mut others = g.others.clone();
            others.sort();
            let mut want: Vec<String> = names.iter().filter(|x| **x != name).cloned().collect();
            want.sort();
            assert_eq!(others, want);
        }
        // two indexed captures of one entry: the earlier in the capture order is kept
        let n = vec![bonn(&plan, 100, Some(7)), bonn(&plan, 100, Some(3))];
        let l = build(&facts(&n), None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures[0].file, n[1]);
    }

    /// Watch mode and `check` share the time origin: times count from the earliest capture's
    /// absolute time, which the listing gives.
    #[test]
    fn the_listing_gives_the_absolute_origin_of_its_times() {
        let (plan, rig, mut spec) = setup();
        spec.order = OrderRule::Mtime;
        let names = [bonn(&plan, 3, None), bonn(&plan, 4, None)];
        let files: Vec<FileFact> = names
            .iter()
            .zip([1_700_000_007.0, 1_700_000_000.0])
            .map(|(n, m)| FileFact {
                name: n.clone(),
                mtime_s: Some(m),
                size: Some(10),
            })
            .collect();
        let l = build(&files, None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.origin_s, 1_700_000_000.0);
        assert_eq!(
            l.captures
                .iter()
                .map(|c| (c.entry, c.t))
                .collect::<Vec<_>>(),
            [(4, 0.0), (3, 7.0)]
        );
        spec.order = OrderRule::Plan;
        assert_eq!(
            build(&files, None, &spec, &plan, &rig).unwrap().origin_s,
            0.0
        );
    }

    #[test]
    fn angles_within_the_tolerance_are_placed_and_hue_of_phi_wraps() {
        let (plan, rig, mut spec) = setup();
        spec.angle_tolerance_deg = 0.5;
        // φ = 359.8° is 0.2° from φ = 0 at θ = 75°: about 0.19° on the sphere
        spec.pattern =
            r"tl(?P<tl>[\d.]+)_pl(?P<pl>[\d.]+)_tv(?P<tv>[\d.]+)_pv(?P<pv>[\d.]+)".into();
        let names = vec!["tl75_pl359.8_tv30.2_pv0.hdr".to_string()];
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures.len(), 1, "{:?}", l.skipped);
        let e = plan.entry(l.captures[0].entry).unwrap();
        assert_eq!(plan.directions()[e.light].theta_deg, 75.0);
        assert_eq!(plan.directions()[e.light].phi_deg, 0.0);
        spec.angle_tolerance_deg = 0.1;
        let l = build(&facts(&names), None, &spec, &plan, &rig).unwrap();
        assert!(l.captures.is_empty());
    }

    /// An angle that would wrap onto another direction (θ = −15°, θ = 95°, φ = 375°, φ = −15°)
    /// is skipped with its reason, never placed.
    /// One file from 1970 among files of today, ordered by modification time: that file is
    /// skipped with its reason; the others keep their times relative to the first of them.
    #[test]
    fn a_modification_time_far_from_the_rest_is_left_out_not_the_set() {
        let (plan, rig, mut spec) = setup();
        spec.order = OrderRule::Mtime;
        let names: Vec<String> = [
            "tl000_pl000_tv015_pv000.hdr",
            "tl000_pl000_tv015_pv060.hdr",
            "tl000_pl000_tv015_pv120.hdr",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let mut f = facts(&names);
        let now = 1.7e9;
        f[0].mtime_s = Some(now);
        f[1].mtime_s = Some(86_400.0);
        f[2].mtime_s = Some(now + 7.0);
        let l = build(&f, None, &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures.len(), 2, "{:?}", l.skipped);
        assert_eq!(l.captures[1].t, 7.0);
        let (_, why) = l.skipped.iter().find(|(n, _)| n == &names[1]).unwrap();
        assert!(why.to_string().contains("modification time"), "{why}");
    }

    #[test]
    fn angles_that_would_wrap_are_skipped_not_placed() {
        let (plan, rig, mut spec) = setup();
        spec.sidecar = Some("captures.csv".into());
        let csv = "file,theta_i,phi_i,theta_o,phi_o,t\n\
                   a.hdr,-15,0,30,0,0\n\
                   b.hdr,15,375,30,0,7\n\
                   c.hdr,15,0,95,0,14\n\
                   d.hdr,15,0,30,-15,21\n\
                   e.hdr,15,0,30,0,28\n";
        let rows = parse_sidecar(csv, true).unwrap();
        let names: Vec<String> = ["a.hdr", "b.hdr", "c.hdr", "d.hdr", "e.hdr", "captures.csv"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let l = build(&facts(&names), Some(&rows), &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures.len(), 1, "{:?}", l.skipped);
        assert_eq!(l.captures[0].file, "e.hdr");
        for f in ["a.hdr", "b.hdr", "c.hdr", "d.hdr"] {
            let (_, why) = l.skipped.iter().find(|(n, _)| n == f).unwrap();
            assert!(why.to_string().contains("outside θ"), "{f}: {why}");
        }
    }

    #[test]
    fn a_sidecar_gives_entries_times_and_order_and_keeps_absent_files() {
        let (plan, rig, mut spec) = setup();
        spec.sidecar = Some("captures.csv".into());
        let csv = "file,theta_i,phi_i,theta_o,phi_o,t\n\
                   b.hdr,15,0,0,0,20.5\n\
                   a.hdr,0,0,15,0,10.5\n\
                   gone.hdr,15,60,15,0,30.5\n";
        let rows = parse_sidecar(csv, true).unwrap();
        let names: Vec<String> = ["a.hdr", "b.hdr", "captures.csv", "stray.hdr"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let l = build(&facts(&names), Some(&rows), &spec, &plan, &rig).unwrap();
        assert_eq!(l.order, OrderRule::Time);
        assert_eq!(l.times, TimeSource::Sidecar);
        let got: Vec<(&str, f64)> = l.captures.iter().map(|c| (c.file.as_str(), c.t)).collect();
        assert_eq!(got, [("a.hdr", 0.0), ("b.hdr", 10.0), ("gone.hdr", 20.0)]);
        assert_eq!(
            l.skipped,
            [("stray.hdr".to_string(), SkipReason::NotInSidecar)]
        );
        // JSON lines, with entries instead of angles
        let rows = parse_sidecar(
            "{\"file\":\"x.png\",\"entry\":12,\"exposure\":0.5}\n\n{\"file\":\"y.png\",\"entry\":13,\"exposure\":-1}\n",
            false,
        )
        .unwrap();
        let names = ["x.png".to_string(), "y.png".to_string()];
        let l = build(&facts(&names), Some(&rows), &spec, &plan, &rig).unwrap();
        assert_eq!(l.captures.len(), 1);
        assert_eq!(
            (l.captures[0].entry, l.captures[0].exposure),
            (12, Some(0.5))
        );
        assert!(
            l.skipped[0].1.to_string().contains("exposure"),
            "{:?}",
            l.skipped
        );
        // a bad row names its line
        let e = parse_sidecar("file,theta_i\nx.hdr,abc\n", true).unwrap_err();
        assert!(matches!(e, ListingError::Sidecar { line: 2, .. }), "{e}");
        let e = parse_sidecar("{\"file\":\"x\",\"colour\":1}\n", false).unwrap_err();
        assert!(e.to_string().contains("line 1"), "{e}");
    }

    #[test]
    fn modification_times_order_and_time_the_captures() {
        let (plan, rig, mut spec) = setup();
        spec.order = OrderRule::Mtime;
        let mut f = facts(&[bonn(&plan, 1, None), bonn(&plan, 2, None)]);
        f[0].mtime_s = Some(1_000_100.0);
        f[1].mtime_s = Some(1_000_000.0);
        let l = build(&f, None, &spec, &plan, &rig).unwrap();
        let got: Vec<(usize, f64)> = l.captures.iter().map(|c| (c.entry, c.t)).collect();
        assert_eq!(got, [(2, 0.0), (1, 100.0)]);
        assert_eq!(l.times, TimeSource::Mtime);
    }

    #[test]
    fn a_pattern_without_angle_or_entry_groups_is_refused() {
        assert_eq!(
            compile_pattern("(?P<x>\\d+)").unwrap_err(),
            ListingError::PatternGroups
        );
        assert!(matches!(
            compile_pattern("(").unwrap_err(),
            ListingError::Pattern(_)
        ));
        assert!(compile_pattern(BONN_PATTERN).is_ok());
        assert!(compile_pattern("e(?P<entry>\\d+)").is_ok());
        let (plan, rig, mut spec) = setup();
        spec.order = OrderRule::Index;
        let e = build(&facts(&[bonn(&plan, 1, None)]), None, &spec, &plan, &rig).unwrap_err();
        assert_eq!(e, ListingError::NoIndex);
    }
}
