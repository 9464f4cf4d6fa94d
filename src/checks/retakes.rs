//! The retake list: which captures of a session hold data the operator should take again, and
//! why, from its result records and alarms. A pure function of them, so the report and a
//! replay agree.
//!
//! A capture is listed when its data is wrong and nothing in the output corrects it: it failed
//! or never appeared; it is dark, has non-finite or clipped pixels beyond the limits; the
//! pose was off the plan as placed (the whole episode); or an arm joint was found to have slipped
//! (every capture since the slip, to the end of the session). Lamp drift and steps are not
//! listed: the corrected colours divide them out. An entry taken again later, usable and
//! outside every listed episode, is not listed.

use super::records::{CaptureRecord, CaptureStatus};
use crate::checks::alarm::{Affects, Alarm, AlarmCode};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};

/// One capture to take again, or a plan entry never captured (no capture index).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Retake {
    pub idx: Option<u64>,
    pub entry: usize,
    pub light: usize,
    pub camera: usize,
    /// Why, most specific first, joined by "; ".
    pub why: String,
}

/// The retake list of a session, in capture order. A capture's own quality (dark, non-finite
/// or clipped pixels beyond `spec`'s limits) is judged from its record, not from the alarms,
/// which hold back all but a few of a code in a storm.
pub(crate) fn retakes(
    captures: &[CaptureRecord],
    alarms: &[Alarm],
    spec: &super::CheckSpec,
) -> Vec<Retake> {
    let last = captures.iter().map(|c| c.idx).max();
    let mut why: BTreeMap<u64, Vec<String>> = BTreeMap::new();
    let mut add = |idx: u64, reason: String| {
        let v = why.entry(idx).or_default();
        if !v.contains(&reason) {
            v.push(reason);
        }
    };
    for c in captures.iter().filter(|c| !c.probe) {
        match c.status {
            CaptureStatus::Failed => add(
                c.idx,
                format!("failed: {}", c.error.as_deref().unwrap_or("unreadable")),
            ),
            CaptureStatus::Missing => add(c.idx, "missing: announced, never written".into()),
            CaptureStatus::Ok => {
                // the same tests as the quality alarms (`capture::quality`)
                if c.nonfinite.is_some_and(|n| n > spec.nonfinite_max) {
                    add(c.idx, "non finite pixels".into());
                }
                if let (Some(k), Some(n)) = (c.clipped, c.pixels) {
                    if k as f64 / n.max(1) as f64 > spec.clipped_fraction_max {
                        add(c.idx, "clipped pixels".into());
                    }
                }
                if c.xyz.is_some_and(|xyz| xyz[1] <= spec.dark_y) {
                    add(c.idx, "dark capture".into());
                }
            }
        }
    }
    // episodes of the pose off the plan: closed ones carry their range; one still open at the
    // end runs from its opening capture to the last
    let mut open_pose: Option<u64> = None;
    for a in alarms {
        let ev = &a.evidence;
        match a.code {
            AlarmCode::PoseOffPlan if open_pose.is_none() => open_pose = a.idx,
            AlarmCode::PoseOffPlanCleared => {
                for i in ev.episode_range().map(|(f, t)| f..=t).into_iter().flatten() {
                    add(i, "the pose was off the plan".into());
                }
                open_pose = None;
            }
            AlarmCode::JointOffsetSuspected => {
                let slip = ev.slip();
                let (joint, offset) = slip.map_or((0, f64::NAN), |(j, o, _)| (j, o));
                // the captures the alarm says it affects; a session recorded before alarms
                // said so gives the start of the sweeps that showed the slip
                let since = match &a.affects {
                    Some(Affects::Since { from_idx, .. }) => Some(*from_idx),
                    _ => slip.map(|(_, _, since)| since).or(a.idx),
                };
                for i in since.zip(last).map(|(f, t)| f..=t).into_iter().flatten() {
                    add(
                        i,
                        format!(
                            "arm joint {joint} slipped by about {offset:+.2}° (since capture {})",
                            since.unwrap_or(i)
                        ),
                    );
                }
            }
            _ => {}
        }
    }
    if let Some(from) = open_pose {
        for i in (from..=last.unwrap_or(from)).filter(|i| *i >= from) {
            add(i, "the pose was off the plan".into());
        }
    }
    // an entry taken again later, usable and not listed itself, needs no retake
    let redone: BTreeSet<usize> = captures
        .iter()
        .filter(|c| !c.probe && c.status == CaptureStatus::Ok && !why.contains_key(&c.idx))
        .map(|c| c.entry)
        .collect();
    let by_idx: BTreeMap<u64, &CaptureRecord> = captures.iter().map(|c| (c.idx, c)).collect();
    why.into_iter()
        .filter_map(|(idx, reasons)| {
            let c = by_idx.get(&idx)?;
            if c.probe || redone.contains(&c.entry) {
                return None;
            }
            Some(Retake {
                idx: Some(idx),
                entry: c.entry,
                light: c.light,
                camera: c.camera,
                why: reasons.join("; "),
            })
        })
        .collect()
}

/// The retake list of a session with `plan` whose controller planned the first `planned`
/// entries (a shorter session than the plan takes the first ones in acquisition order):
/// `retakes`, then, once the session is `finished`, every one of those entries that no regular
/// capture stands for (a file source's entry without a file, a run that ended before it), in
/// entry order.
pub(crate) fn session_retakes(
    captures: &[CaptureRecord],
    alarms: &[Alarm],
    spec: &super::CheckSpec,
    plan: &crate::measure::plan::SamplingPlan,
    planned: usize,
    finished: bool,
) -> Vec<Retake> {
    let mut list = retakes(captures, alarms, spec);
    if finished {
        let taken: BTreeSet<usize> = captures
            .iter()
            .filter(|c| !c.probe)
            .map(|c| c.entry)
            .collect();
        for entry in (0..planned.min(plan.capture_count())).filter(|e| !taken.contains(e)) {
            let Ok(pe) = plan.entry(entry) else {
                continue;
            };
            list.push(Retake {
                idx: None,
                entry,
                light: pe.light,
                camera: pe.camera,
                why: "not captured: the session ended with no capture of this plan entry".into(),
            });
        }
    }
    list
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::alarm::{AlarmCode, AlarmKind, Severity};
    use crate::checks::evidence::Evidence;
    use serde_json::json;

    fn cap(idx: u64, entry: usize, status: CaptureStatus) -> CaptureRecord {
        let v = json!({
            "idx": idx, "entry": entry, "light": entry / 81, "camera": entry % 81, "probe": false,
            "t": idx as f64 * 7.0, "file": format!("c{idx}.hdr"), "status": status.as_str(),
            "error": if status == CaptureStatus::Failed { Some("truncated") } else { None },
            "mean_rgb": null, "xyz": null, "lab": null, "pixels": null, "nonfinite": null,
            "clipped": null, "negative": null, "angles": null, "substitute": null,
            "pose_error_deg": null
        });
        serde_json::from_value(v).unwrap()
    }

    fn spec() -> crate::checks::CheckSpec {
        crate::checks::CheckSpec::default()
    }

    /// Ten dark captures and 361 clipped ones: every one is listed, although a storm of alarms
    /// of one code shows only the first few in full.
    #[test]
    fn every_bad_capture_is_listed_whatever_the_alarms_held_back() {
        let mut caps: Vec<CaptureRecord> = (0..400)
            .map(|i| cap(i, i as usize, CaptureStatus::Ok))
            .collect();
        for c in caps.iter_mut() {
            c.xyz = Some([50.0, 50.0, 50.0]);
            c.pixels = Some(256);
            c.clipped = Some(if c.idx < 361 { 200 } else { 0 });
            c.nonfinite = Some(0);
        }
        for c in caps.iter_mut().filter(|c| (370..380).contains(&c.idx)) {
            c.xyz = Some([0.0, 0.0, 0.0]);
        }
        let r = retakes(&caps, &[], &spec());
        assert_eq!(r.iter().filter(|x| x.why.contains("clipped")).count(), 361);
        assert_eq!(r.iter().filter(|x| x.why.contains("dark")).count(), 10);
        assert_eq!(r.len(), 371);
    }

    /// An alarm whose evidence is read as a result file holds it.
    fn alarm(code: AlarmCode, idx: u64, evidence: serde_json::Value) -> Alarm {
        Alarm::new(
            AlarmKind::Positioning,
            Severity::Warning,
            code,
            String::new(),
        )
        .at(Some(idx), None)
        .with(Evidence::read(code, evidence))
    }

    #[test]
    fn failures_episodes_and_slips_are_listed_with_why_and_retaken_entries_are_not() {
        let mut caps: Vec<CaptureRecord> = (0..100)
            .map(|i| cap(i, i as usize, CaptureStatus::Ok))
            .collect();
        caps[3] = cap(3, 3, CaptureStatus::Failed);
        caps[4] = cap(4, 4, CaptureStatus::Missing);
        caps[5] = cap(5, 5, CaptureStatus::Failed);
        // entry 5 was taken again later and is fine (before the slip)
        caps[60] = cap(60, 5, CaptureStatus::Ok);
        // capture 7 is dark by its record (its alarm may have been held back in a storm)
        caps[7].xyz = Some([0.0, 0.0, 0.0]);
        let alarms = vec![
            alarm(AlarmCode::PoseOffPlan, 20, json!({})),
            alarm(
                AlarmCode::PoseOffPlanCleared,
                23,
                json!({"axis": "pose", "captures": 3, "first_idx": 20, "last_idx": 22, "worst_deg": 0.5, "by_command": 0}),
            ),
            alarm(
                AlarmCode::JointOffsetSuspected,
                95,
                json!({"joint": 2, "offset_deg": 1.1, "since_idx": 90, "se_deg": 0.2, "estimate_sweeps": 1, "run_mean_deg": 1.1, "sweeps": 1, "statistic": 9.0, "threshold": 6.0, "other_joints": []}),
            ),
        ];
        let r = retakes(&caps, &alarms, &spec());
        let idx: Vec<u64> = r.iter().map(|x| x.idx.unwrap()).collect();
        assert_eq!(
            idx,
            vec![3, 4, 7, 20, 21, 22, 90, 91, 92, 93, 94, 95, 96, 97, 98, 99]
        );
        assert!(r[0].why.starts_with("failed: truncated"));
        assert!(r[1].why.starts_with("missing"));
        assert_eq!(r[2].why, "dark capture");
        assert!(r[3].why.contains("off the plan"));
        assert!(r[6].why.contains("joint 2") && r[6].why.contains("+1.10°"));
        // an alarm that says which captures a slip affects is taken at its word
        let slip = alarm(
            AlarmCode::JointOffsetSuspected,
            95,
            json!({"joint": 2, "offset_deg": 1.1, "since_idx": 90, "se_deg": 0.2, "estimate_sweeps": 1, "run_mean_deg": 1.1, "sweeps": 1, "statistic": 9.0, "threshold": 6.0, "other_joints": []}),
        )
        .advise(
            "check joint 2",
            Some(Affects::Since {
                from_idx: 85,
                handling: crate::checks::alarm::Handling::Retake,
            }),
        );
        let r = retakes(&caps[..], &[slip], &spec());
        assert_eq!(r.first().map(|x| x.idx), Some(Some(3)));
        let slipped: Vec<u64> = r
            .iter()
            .filter(|x| x.why.contains("joint"))
            .map(|x| x.idx.unwrap())
            .collect();
        assert_eq!(slipped, (85..100).collect::<Vec<u64>>());
    }

    #[test]
    fn an_episode_open_at_the_end_runs_to_the_last_capture_and_a_clean_session_has_none() {
        let caps: Vec<CaptureRecord> = (0..10)
            .map(|i| cap(i, i as usize, CaptureStatus::Ok))
            .collect();
        assert!(retakes(&caps, &[], &spec()).is_empty());
        let r = retakes(
            &caps,
            &[alarm(AlarmCode::PoseOffPlan, 7, json!({}))],
            &spec(),
        );
        assert_eq!(
            r.iter().map(|x| x.idx.unwrap()).collect::<Vec<_>>(),
            vec![7, 8, 9]
        );
        assert!(retakes(&[], &[alarm(AlarmCode::PoseOffPlan, 7, json!({}))], &spec()).is_empty());
    }

    /// A finished session lists the plan entries no capture stands for after its captures;
    /// an unfinished one does not (they may still come).
    #[test]
    fn a_finished_session_lists_its_never_captured_entries() {
        let plan = crate::measure::plan::SamplingPlan::ubo();
        let caps: Vec<CaptureRecord> = (0..plan.capture_count() as u64)
            .filter(|&i| i != 17 && i != 4000)
            .map(|i| cap(i, i as usize, CaptureStatus::Ok))
            .collect();
        let n = plan.capture_count();
        let r = session_retakes(&caps, &[], &spec(), &plan, n, true);
        let entries: Vec<(Option<u64>, usize)> = r.iter().map(|x| (x.idx, x.entry)).collect();
        assert_eq!(entries, [(None, 17), (None, 4000)]);
        assert_eq!((r[1].light, r[1].camera), (4000 / 81, 4000 % 81));
        assert!(r[0].why.starts_with("not captured"));
        assert!(session_retakes(&caps, &[], &spec(), &plan, n, false).is_empty());
        // a session planned as the first 4,000 entries misses only entry 17
        assert_eq!(
            session_retakes(&caps, &[], &spec(), &plan, 4000, true).len(),
            1
        );
    }
}
