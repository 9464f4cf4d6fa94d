//! The light sweeps' findings as alarms: the words, the severity and what the operator should
//! do.

use super::evidence::{self, Evidence, Source};
use crate::checks::alarm::{action, Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use crate::detect::sweeps::{
    ApproachReading, AxisReading, JointSlip, LayerChange, LevelRun, PatternBelow, Recapture,
    RecaptureReading, SweepAt, SweepFinding, WagonBacklash, WagonOffset, LAYER_CHANGE_Z,
    PATTERN_BELOW_Z,
};

/// The alarm a finding of the sweep checks raises.
pub(crate) fn alarm(f: &SweepFinding) -> Alarm {
    let at = f.at();
    let alarm = match f {
        SweepFinding::GainStep {
            at,
            up,
            run,
            since_t,
            from_idx,
        } => gain_step(at, *up, run, *since_t, *from_idx),
        SweepFinding::LevelAfterSlip {
            at,
            run,
            joint,
            slip_from_idx,
        } => level_after_slip(at, run, *joint, *slip_from_idx),
        SweepFinding::GainStepWithdrawn {
            joint,
            step_idx,
            level_pct,
            slip_from_idx,
            ..
        } => gain_step_withdrawn(*joint, *step_idx, *level_pct, *slip_from_idx),
        SweepFinding::JointSlip { at, slip } => joint_slip(at, slip),
        SweepFinding::SlipRefuted {
            at,
            joint,
            offset_deg,
            reading,
        } => slip_refuted(at, *joint, *offset_deg, reading),
        SweepFinding::SlipUnverifiable {
            at,
            joint,
            offset_deg,
            checkable_deg,
        } => slip_unverifiable(at, *joint, *offset_deg, *checkable_deg),
        SweepFinding::SlipUnresolved {
            at,
            joint,
            offset_deg,
            change,
        } => slip_unresolved(at, *joint, *offset_deg, change),
        SweepFinding::StepUnresolved {
            at,
            up,
            run,
            below,
        } => step_unresolved(at, *up, run, below),
        SweepFinding::WagonBacklash { at, backlash } => wagon_backlash(at, backlash),
        SweepFinding::WagonOffset { offset, .. } => wagon_offset(offset),
        SweepFinding::LampUnstable {
            scatter_pct,
            limit_pct,
            sweeps,
            from_idx,
            ..
        } => lamp_unstable(*scatter_pct, *limit_pct, *sweeps, *from_idx),
        SweepFinding::LampSteady {
            scatter_pct,
            limit_pct,
            sweeps,
            ..
        } => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            AlarmCode::LampUnstableCleared,
            format!(
                "the lamp is steady again: the captures scatter by at most {scatter_pct:.2} % about the isotropy model (residual SD of each of the last {sweeps} light sweeps judged; lamp-unstable above {limit_pct} %)"
            ),
        )
        .with(Evidence::SweepScatter(evidence::SweepScatter {
            source: Source::LightSweeps,
            scatter_pct: *scatter_pct,
            limit_pct: *limit_pct,
            sweeps: *sweeps,
        })),
    };
    alarm.at(Some(at.last_idx), Some(at.last_t))
}

fn lamp_unstable(scatter_pct: f64, limit_pct: f64, sweeps: usize, from_idx: u64) -> Alarm {
    Alarm::new(
        AlarmKind::Drift,
        Severity::Warning,
        AlarmCode::LampUnstable,
        format!(
            "the lamp is unstable: the captures scatter by at least {scatter_pct:.2} % about the isotropy model (residual SD of each of the last {sweeps} light sweeps judged, θi ≤ 60°; a steady lamp leaves the model's misfit and the camera noise, lamp-unstable above {limit_pct} %; from isotropy classes, no probes)"
        ),
    )
    .with(Evidence::SweepScatter(evidence::SweepScatter {
        source: Source::LightSweeps,
        scatter_pct,
        limit_pct,
        sweeps,
    }))
    .advise(
        "Let the lamp warm up and settle; check its supply, its connections and any draught or fan near it; if the scatter stays, pause the run and fix the lamp. The captures since the first sweep judged carry the lamp's noise, which no correction removes; drift probes ([probes] every) would measure it directly.",
        Some(Affects::Since { from_idx, handling: Handling::Inspect }),
    )
}

/// The re-captures' reading as the evidence holds it.
fn reading_evidence(r: &RecaptureReading) -> evidence::RecaptureReading {
    evidence::RecaptureReading {
        entries: r.entries.clone(),
        change_pct: r.change_pct,
        sensitivity_pct_per_deg: r.sensitivity_pct_per_deg,
        offset_deg: r.offset_deg,
        se_deg: r.se_deg,
    }
}

/// Plan entries in words: "1, 2 and 3".
fn entry_list(entries: &[usize]) -> String {
    match entries {
        [] => String::new(),
        [one] => one.to_string(),
        [rest @ .., last] => format!(
            "{} and {last}",
            rest.iter()
                .map(|e| e.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The re-captures' reading in words.
fn reading_words(r: &RecaptureReading) -> String {
    let (up, down) = r.entries.split_at(r.entries.len() / 2);
    format!(
        "earlier poses re-captured back to back (entries {}, rising with the joint, against {}, falling) moved {:+.2} % against each other since they were first taken ({:+.2} %/° of joint {} between them): {:+.2}° ± {:.2}°",
        entry_list(up),
        entry_list(down),
        r.change_pct,
        r.sensitivity_pct_per_deg,
        r.joint,
        r.offset_deg,
        r.se_deg
    )
}

fn slip_refuted(at: &SweepAt, joint: usize, offset_deg: f64, r: &RecaptureReading) -> Alarm {
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Info,
        AlarmCode::SlipRefuted,
        format!(
            "no slip: the pattern across the cameras of light sweep {} (θi = {}°) follows joint {joint}'s sensitivity as an offset of {offset_deg:+.2}° would, but {}; the pattern is the geometry's (a lamp beam or a holder that follows the pose), which a re-capture shows unchanged",
            at.light,
            layer_deg(at),
            reading_words(r)
        ),
    )
    .with(Evidence::SlipRefuted(evidence::SlipRefuted {
        source: Source::Recaptures,
        joint,
        offset_deg,
        recapture: evidence::SlipRecapture::Refuted(reading_evidence(r)),
    }))
}

fn slip_unverifiable(at: &SweepAt, joint: usize, offset_deg: f64, checkable_deg: f64) -> Alarm {
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Info,
        AlarmCode::SlipUnverifiable,
        format!(
            "not named: the pattern across the cameras of light sweep {} (θi = {}°) follows joint {joint}'s sensitivity as an offset of {offset_deg:+.2}° would, which the sweeps alone cannot tell from a stationary pattern of the geometry (a lamp beam or a holder that follows the pose), and re-captures of earlier poses would show only an offset of {checkable_deg:.2}° or more; a pattern that grows to that is re-captured and named if they confirm it (later patterns of this layer below it are not reported again)",
            at.light,
            layer_deg(at),
        ),
    )
    .with(Evidence::SlipUnverifiable(evidence::SlipUnverifiable {
        source: Source::LightSweeps,
        joint,
        offset_deg,
        checkable_deg,
        layer_deg: layer_deg(at),
        light: at.light,
    }))
}

fn slip_unresolved(at: &SweepAt, joint: usize, offset_deg: f64, change: &LayerChange) -> Alarm {
    let layer = layer_deg(at);
    let against = match (change.before, change.change_z) {
        (Some((before, se)), Some(z)) => format!(
            "its {} sweep(s) tested before the pattern's run read {before:+.2}° ± {se:.2}, and the run departs from them by {z:+.1} standard errors, under {LAYER_CHANGE_Z:.1}",
            change.sweeps_before
        ),
        _ => "no sweep of the layer was tested before the pattern's run".to_string(),
    };
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Info,
        AlarmCode::SlipUnresolved,
        format!(
            "not named: the pattern across the cameras of light sweep {} (θi = {layer}°) follows joint {joint}'s sensitivity as an offset of {offset_deg:+.2}° would, but it has held since the layer began ({against}); without re-captures of earlier poses the sweeps cannot tell a slip at the layer's start from the new θi's geometry (a lamp beam or a holder that follows the pose); a slip later in this layer is still named against this pattern; drift probes ([probes] every) would tell them apart",
            at.light,
        ),
    )
    .with(Evidence::SlipUnresolved(evidence::SlipUnresolved {
        source: Source::LightSweeps,
        joint,
        offset_deg,
        layer_deg: layer,
        light: at.light,
        sweeps_before: change.sweeps_before,
        before_deg: change.before.map(|b| b.0),
        before_se_deg: change.before.map(|b| b.1),
        change_z: change.change_z,
        threshold_z: LAYER_CHANGE_Z,
    }))
}

fn step_unresolved(at: &SweepAt, up: bool, run: &LevelRun, below: &PatternBelow) -> Alarm {
    let layer = layer_deg(at);
    Alarm::new(
        AlarmKind::Drift,
        Severity::Info,
        AlarmCode::StepUnresolved,
        format!(
            "not raised: light sweep {} (captures up to {}) and the {} before it sit {:+.2} % off the earlier sweeps of θi = {layer}° (CUSUM {:.1} > {:.1}), but at the same light azimuths the θi = {}° layer departed from its own pattern by {:+.2} % ± {:.2} ({:.1} standard errors), which grown towards grazing at the lamp footprint's law (×{:.1}) accounts for it: a stationary pattern of the light's direction (a holder's shadow, a bowed sample) or a lamp step {}; without probes the sweeps tell them apart only as the light turns on, and the step is raised if the level stays off where the layer below does not account for it; drift probes ([probes] every) would tell them apart at once",
            at.light,
            at.last_idx,
            run.sweeps.saturating_sub(1),
            run.level_pct,
            run.statistic,
            run.threshold,
            below.below_deg,
            100.0 * below.departure,
            100.0 * below.se,
            if below.se > 0.0 { below.departure.abs() / below.se } else { f64::INFINITY },
            below.growth,
            if up { "up" } else { "down" },
        ),
    )
    .with(Evidence::StepUnresolved(evidence::StepUnresolved {
        source: Source::LightSweeps,
        level_pct: run.level_pct,
        sweeps: run.sweeps,
        since_idx: run.since_idx,
        statistic: run.statistic,
        threshold: run.threshold,
        layer_deg: layer,
        light: at.light,
        below_deg: below.below_deg,
        below_pct: 100.0 * below.departure,
        below_se_pct: 100.0 * below.se,
        growth: below.growth,
        threshold_z: PATTERN_BELOW_Z,
    }))
}

fn layer_deg(at: &SweepAt) -> f64 {
    at.layer_mdeg as f64 / 1000.0
}

fn gain_step(at: &SweepAt, up: bool, run: &LevelRun, since_t: Option<f64>, from_idx: u64) -> Alarm {
    Alarm::new(
        AlarmKind::Drift,
        Severity::Warning,
        AlarmCode::GainStep,
        format!(
            "the gain level stepped {}: light sweep {} (captures up to {}) and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}° beyond the modelled drift (CUSUM {:.1} > {:.1}; from isotropy classes, no probes); the step's size is fitted from the isotropy classes from now on",
            if up { "up" } else { "down" },
            at.light,
            at.last_idx,
            run.sweeps.saturating_sub(1),
            run.level_pct,
            layer_deg(at),
            run.statistic,
            run.threshold
        ),
    )
    .with(Evidence::SweepStep(evidence::SweepStep {
        source: Source::LightSweeps,
        level_pct: run.level_pct,
        sweeps: run.sweeps,
        since_idx: run.since_idx,
        since_t,
        statistic: run.statistic,
        threshold: run.threshold,
    }))
    .advise(
        action::GAIN_STEP,
        Some(Affects::Since {
            from_idx,
            handling: Handling::Corrected,
        }),
    )
}

fn level_after_slip(at: &SweepAt, run: &LevelRun, joint: usize, slip_from_idx: u64) -> Alarm {
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Info,
        AlarmCode::LevelAfterSlip,
        format!(
            "light sweep {} (captures up to {}) and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}°, beginning after joint {joint} was named (captures from {slip_from_idx}): read as the tilt's, not as a lamp step, and not taken into the drift model",
            at.light,
            at.last_idx,
            run.sweeps.saturating_sub(1),
            run.level_pct,
            layer_deg(at),
        ),
    )
    .with(Evidence::LevelAfterSlip(evidence::LevelAfterSlip {
        source: Source::LightSweeps,
        joint,
        level_pct: run.level_pct,
        sweeps: run.sweeps,
        since_idx: run.since_idx,
        slip_from_idx,
        statistic: run.statistic,
        threshold: run.threshold,
    }))
    .advise(
        "Nothing more than for the joint alarm: check the sample clamp and the joint; these captures are already on the retake list. A level change that persists after the joint is fixed is the lamp's.",
        Some(Affects::Since { from_idx: slip_from_idx, handling: Handling::Retake }),
    )
}

fn gain_step_withdrawn(joint: usize, step_idx: u64, level_pct: f64, slip_from_idx: u64) -> Alarm {
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Info,
        AlarmCode::GainStepWithdrawn,
        format!(
            "the gain step raised at capture {step_idx} ({level_pct:+.2} %) came after joint {joint} began to slip (captures from {slip_from_idx}): it is read as the tilt's, not the lamp's, and leaves the drift model",
        ),
    )
    .with(Evidence::StepWithdrawn(evidence::StepWithdrawn {
        source: Source::LightSweeps,
        joint,
        step_idx,
        level_pct,
        slip_from_idx,
    }))
    .advise(
        "Nothing more than for the joint alarm: check the sample clamp and the joint; these captures are on the retake list and the corrected colours no longer divide that step out.",
        Some(Affects::Since { from_idx: slip_from_idx, handling: Handling::Retake }),
    )
}

fn joint_slip(at: &SweepAt, x: &JointSlip) -> Alarm {
    let evidence = Evidence::JointSlip(evidence::JointSlip {
        joint: x.joint,
        offset_deg: x.offset_deg,
        se_deg: x.se_deg,
        estimate_sweeps: x.estimate_sweeps,
        run_mean_deg: x.run_mean_deg,
        sweeps: x.sweeps,
        since_idx: x.since_idx,
        statistic: x.statistic,
        threshold: x.threshold,
        other_joints: x
            .other_joints
            .iter()
            .map(|f| evidence::OtherJoint {
                joint: f.joint,
                offset_deg: f.offset_deg,
                se_deg: f.se_deg,
                cusum: f.cusum,
            })
            .collect(),
        attributed_level_pct: x.attributed_level_pct,
        recapture: match &x.recapture {
            Recapture::NoProbes | Recapture::NotAsked => None,
            Recapture::Confirmed(r) => {
                Some(evidence::SlipRecapture::Confirmed(reading_evidence(r)))
            }
            Recapture::Unanswered { entries } => Some(evidence::SlipRecapture::Unanswered {
                entries: entries.clone(),
            }),
        },
        axis: x.axis.as_ref().map(axis_evidence),
    });
    let recaptured = match &x.recapture {
        Recapture::NoProbes => "; from the light sweeps alone, which cannot tell a slip from a stationary pattern of the geometry that follows the pose (a lamp beam aimed beside the rotation centre, a holder's rim): on a rig that takes drift probes ([probes] every) earlier poses are re-captured to decide".to_string(),
        Recapture::NotAsked => "; from the light sweeps alone (no re-capture of earlier poses could check it yet)".to_string(),
        Recapture::Confirmed(r) => format!(
            "; confirmed by a re-capture: {}{}",
            reading_words(r),
            match &x.axis {
                Some(a) => format!("; {}: joint 1's, not the wagon's", axis_words(a)),
                None => String::new(),
            }
        ),
        Recapture::Unanswered { entries } => format!(
            "; not confirmed: the re-captures asked for (entries {}) were not taken",
            entry_list(entries)
        ),
    };
    let size = format!(
        "joint {} looks offset by about {:+.2}° (± {:.2}°, from {} light sweep(s) against the captures before the slip)",
        x.joint, x.offset_deg, x.se_deg, x.estimate_sweeps
    );
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Warning,
        AlarmCode::JointOffsetSuspected,
        match (&x.axis, x.attributed_level_pct) {
            (Some(_), _) => format!(
                "joint {} looks offset by about {:+.2}° (± {:.2}°, from the re-captured pair): two earlier poses re-captured back to back departed from their readings in control (CUSUM {:.1} > {:.1}), and re-captures chosen to tell joint 1 from the wagon read the joint's",
                x.joint, x.offset_deg, x.se_deg, x.statistic, x.threshold
            ),
            (None, Some(level_pct)) => format!(
                "{size}: light sweep {} and the {} before it sit {:+.2} % off the earlier sweeps of θi = {}°, and that joint's pattern across their cameras departs from the earlier sweeps' by {:.1} standard deviations (threshold {}) in the direction that explains the level, while the encoders agree with the commands: read as the tilt's, not as a lamp step, and not taken into the drift model; a slipped joint or a moved sample is likely",
                at.light,
                x.sweeps.saturating_sub(1),
                level_pct,
                layer_deg(at),
                x.statistic,
                x.threshold,
            ),
            (None, None) => format!(
                "{size}: the pattern across the cameras of light sweep {} and the {} before it follows that joint's sensitivity while the encoders agree with the commands; a slipped joint or a moved sample is likely (CUSUM {:.1} > {:.1})",
                at.light,
                x.sweeps.saturating_sub(1),
                x.statistic,
                x.threshold
            ),
        } + &recaptured,
    )
    .with(evidence)
    .advise(
        &format!(
            "Pause the run; check the sample clamp and arm joint {} (re-home the joint if it slipped, re-seat the sample if it moved), then resume; every capture since {} (the light sweep before the first one that showed it) is on the retake list.",
            x.joint, x.from_idx,
        ),
        Some(Affects::Since { from_idx: x.from_idx, handling: Handling::Retake }),
    )
}

/// A pose re-captured from both sides, for the alarms' evidence.
fn approach_evidence(r: &ApproachReading) -> evidence::ApproachReading {
    evidence::ApproachReading {
        entries: r.entries,
        change_pct: r.change_pct,
        sensitivity_pct_per_deg: r.sensitivity_pct_per_deg,
        backlash_deg: r.backlash_deg,
        se_deg: r.se_deg,
    }
}

/// Re-captures that told the wagon from joint 1, for the alarms' evidence.
fn axis_evidence(r: &AxisReading) -> evidence::AxisReading {
    evidence::AxisReading {
        entries: r.entries.clone(),
        up: r.up,
        change_pct: r.change_pct,
        joint1_pct: r.joint1_pct,
        wagon_pct: r.wagon_pct,
        se_pct: r.se_pct,
    }
}

/// What the re-captures that tell the wagon from joint 1 read, for a message.
fn axis_words(r: &AxisReading) -> String {
    format!(
        "{} earlier poses re-captured back to back to tell the wagon from joint 1 moved {:+.2} % against each other (± {:.2}), where the wagon would have moved them {:+.2} % and joint 1 {:+.2} %",
        r.entries.len(),
        r.change_pct,
        r.se_pct,
        r.wagon_pct,
        r.joint1_pct,
    )
}

fn wagon_backlash(at: &SweepAt, x: &WagonBacklash) -> Alarm {
    let message = match &x.approach {
        Some(r) => format!(
            "the wagon lags about {:.2}° (± {:.2}°) behind its commanded angle against the direction it last moved: after two earlier poses re-captured back to back moved {:+.2}° of wagon against each other (CUSUM {:.1} > {:.1}), plan entry {} re-captured once approached from below (after entry {}) and once from above (after entry {}) read {:+.2} % apart at {:+.2} %/° of wagon; a constant offset, an arm joint, the lamp and the geometry read the same from both sides (the change is measured; the size divides it by the smooth model's slope at the pose, which the plan's grid of camera directions reads low where the luminance turns within a degree, and the lag then reads too large)",
            r.backlash_deg,
            r.se_deg,
            x.offset_deg,
            x.statistic,
            x.threshold,
            r.entries[1],
            r.entries[0],
            r.entries[2],
            r.change_pct,
            r.sensitivity_pct_per_deg,
        ),
        None => format!(
            "the wagon lags about {:.2}° (± {:.2}°, from {} light sweep(s) against the captures before it) behind its commanded angle against the direction it last moved: the pattern across the cameras of light sweep {} and the {} before it follows the wagon's sensitivity signed by its direction of motion, which no arm joint and no constant offset makes (CUSUM {:.1} > {:.1}; the wagon's constant offset in that sweep {:+.2}°, not tested)",
            x.backlash_deg,
            x.se_deg,
            x.estimate_sweeps,
            at.light,
            x.sweeps.saturating_sub(1),
            x.statistic,
            x.threshold,
            x.offset_deg,
        ),
    };
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Warning,
        AlarmCode::WagonBacklashSuspected,
        message,
    )
    .with(Evidence::WagonBacklash(evidence::WagonBacklash {
        source: if x.approach.is_some() {
            Source::Recaptures
        } else {
            Source::LightSweeps
        },
        backlash_deg: x.backlash_deg,
        se_deg: x.se_deg,
        estimate_sweeps: x.estimate_sweeps,
        run_mean_deg: x.run_mean_deg,
        offset_deg: x.offset_deg,
        sweeps: x.sweeps,
        since_idx: x.since_idx,
        statistic: x.statistic,
        threshold: x.threshold,
        approach: x.approach.as_ref().map(approach_evidence),
    }))
    .advise(
        &format!(
            "Check the wagon's drive for play (belt, gear, coupling): take it up, or have the controller approach every camera position from one side; every capture since {} (the light sweep before the first one that showed it) is on the retake list.",
            x.from_idx,
        ),
        Some(Affects::Since { from_idx: x.from_idx, handling: Handling::Retake }),
    )
}

fn wagon_offset(x: &WagonOffset) -> Alarm {
    // told: the wagon; not told: the camera's pose moved, by the wagon or by joint 1
    let (code, opening, check) = if x.told {
        (
            AlarmCode::WagonOffsetSuspected,
            format!(
                "the wagon stands about {:+.2}° (± {:.2}°, from {} reading(s)) off its commanded angle",
                x.offset_deg, x.se_deg, x.readings
            ),
            "check the wagon against its reference mark on the arc (re-home it if it slipped)",
        )
    } else {
        (
            AlarmCode::CameraPoseMoved,
            format!(
                "the camera's pose moved: the wagon by about {:+.2}° (± {:.2}°, from {} reading(s)) or arm joint 1 by {:+.2}°, and nothing yet tells which",
                x.offset_deg,
                x.se_deg,
                x.readings,
                x.offset_deg / x.joint_leak[0]
            ),
            "check both the wagon against its reference mark on the arc and arm joint 1 (re-home whichever slipped, re-seat the sample if it moved)",
        )
    };
    Alarm::new(
        AlarmKind::Positioning,
        Severity::Warning,
        code,
        format!(
            "{opening}: two earlier poses (entries {} and {}, of light sweeps {} and {}), re-captured back to back, moved {:+.2} % against each other, at {:+.2} %/° of wagon (CUSUM {:.1} > {:.1}); a stationary effect of the geometry does not move a re-captured pose, the lamp cancels between the two, and a degree of joint 1 or 2 would read as {:+.2}° or {:+.2}° of wagon; {}{}",
            x.entries[0],
            x.entries[1],
            x.originals_lights[0],
            x.originals_lights[1],
            x.change_pct,
            x.sensitivity_pct_per_deg,
            x.statistic,
            x.threshold,
            x.joint_leak[0],
            x.joint_leak[1],
            match (x.sweeps_z, &x.axis) {
                (Some(z), _) => format!("the light sweeps since then show the wagon's offset, not a joint's, at {z:.1} standard deviations"),
                (None, Some(r)) if x.told => format!("{}: the wagon's", axis_words(r)),
                (None, Some(r)) => format!("the light sweeps since then name no axis, and {}: neither's", axis_words(r)),
                (None, None) => "the light sweeps since then name no axis, and no set of earlier poses could be re-captured to tell the two apart".to_string(),
            },
            match &x.approach {
                Some(r) => format!("; plan entry {} re-captured from below and from above read {:+.2} % apart ({:+.2}° ± {:.2}° of lag): not play in the drive", r.entries[1], r.change_pct, r.backlash_deg, r.se_deg),
                None => String::new(),
            },
        ),
    )
    .with(Evidence::WagonOffset(evidence::WagonOffset {
        source: Source::Recaptures,
        offset_deg: x.offset_deg,
        se_deg: x.se_deg,
        entries: x.entries,
        change_pct: x.change_pct,
        sensitivity_pct_per_deg: x.sensitivity_pct_per_deg,
        joint_leak: x.joint_leak,
        originals_lights: x.originals_lights,
        readings: x.readings,
        sweeps_z: x.sweeps_z,
        since_idx: x.since_idx,
        statistic: x.statistic,
        threshold: x.threshold,
        approach: x.approach.as_ref().map(approach_evidence),
        axis: x.axis.as_ref().map(axis_evidence),
    }))
    .advise(
        &format!(
            "Pause the run; {check}, then resume; every capture since {} (after the last reading in control) is on the retake list.",
            x.since_idx,
        ),
        Some(Affects::Since { from_idx: x.since_idx, handling: Handling::Retake }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::sweeps::JointFit;

    const AT: SweepAt = SweepAt {
        light: 47,
        last_idx: 3887,
        last_t: 25_000.5,
        layer_mdeg: 60_000,
    };

    fn run() -> LevelRun {
        LevelRun {
            level_pct: -2.5,
            sweeps: 3,
            since_idx: 3725,
            statistic: 7.25,
            threshold: 5.5,
        }
    }

    #[test]
    fn a_gain_step_is_a_corrected_drift_warning_from_its_runs_first_sweep() {
        let a = alarm(&SweepFinding::GainStep {
            at: AT,
            up: false,
            run: run(),
            since_t: Some(24_000.0),
            from_idx: 3645,
        });
        assert_eq!(
            (a.code, a.kind, a.severity),
            (AlarmCode::GainStep, AlarmKind::Drift, Severity::Warning)
        );
        assert_eq!((a.idx, a.t), (Some(3887), Some(25_000.5)));
        assert!(a.message.starts_with("the gain level stepped down: light sweep 47 (captures up to 3887) and the 2 before it sit -2.50 % off the earlier sweeps of θi = 60°"), "{}", a.message);
        assert_eq!(
            a.affects,
            Some(Affects::Since {
                from_idx: 3645,
                handling: Handling::Corrected
            })
        );
        assert_eq!(
            serde_json::to_value(&a).unwrap()["evidence"].to_string(),
            r#"{"level_pct":-2.5,"since_idx":3725,"since_t":24000.0,"source":"light sweeps","statistic":7.25,"sweeps":3,"threshold":5.5}"#
        );
    }

    #[test]
    fn a_level_change_after_a_slip_and_a_withdrawn_step_are_infos_that_retake_from_the_slip() {
        for f in [
            SweepFinding::LevelAfterSlip {
                at: AT,
                run: run(),
                joint: 2,
                slip_from_idx: 3564,
            },
            SweepFinding::GainStepWithdrawn {
                at: AT,
                joint: 2,
                step_idx: 3726,
                level_pct: -1.5,
                slip_from_idx: 3564,
            },
        ] {
            let a = alarm(&f);
            assert_eq!(
                (a.kind, a.severity),
                (AlarmKind::Positioning, Severity::Info)
            );
            assert!(
                a.message.contains("joint 2") && a.message.contains("3564"),
                "{}",
                a.message
            );
            assert_eq!(
                a.affects,
                Some(Affects::Since {
                    from_idx: 3564,
                    handling: Handling::Retake
                })
            );
            assert_eq!(
                serde_json::to_value(&a).unwrap()["evidence"]["slip_from_idx"],
                3564
            );
        }
    }

    #[test]
    fn a_pattern_the_re_captures_cannot_check_is_an_info_with_the_size_they_could() {
        let a = alarm(&SweepFinding::SlipUnverifiable {
            at: AT,
            joint: 2,
            offset_deg: 0.35,
            checkable_deg: 0.375,
        });
        assert_eq!(
            (a.code, a.kind, a.severity),
            (
                AlarmCode::SlipUnverifiable,
                AlarmKind::Positioning,
                Severity::Info
            )
        );
        assert_eq!(a.affects, None);
        assert!(
            a.message.starts_with("not named: the pattern across the cameras of light sweep 47 (θi = 60°) follows joint 2's sensitivity as an offset of +0.35° would")
                && a.message.contains("0.38° or more"),
            "{}",
            a.message
        );
        assert_eq!(
            serde_json::to_value(&a).unwrap()["evidence"].to_string(),
            r#"{"checkable_deg":0.375,"joint":2,"layer_deg":60.0,"light":47,"offset_deg":0.35,"source":"light sweeps"}"#
        );
    }

    #[test]
    fn a_pattern_no_change_within_its_layer_shows_is_an_info_that_says_what_would_decide() {
        let shown_not = LayerChange {
            sweeps_before: 1,
            before: Some((0.19, 0.23)),
            change_z: Some(2.14),
        };
        let a = alarm(&SweepFinding::SlipUnresolved {
            at: AT,
            joint: 2,
            offset_deg: 0.86,
            change: shown_not,
        });
        assert_eq!(
            (a.code, a.kind, a.severity),
            (
                AlarmCode::SlipUnresolved,
                AlarmKind::Positioning,
                Severity::Info
            )
        );
        assert_eq!(a.affects, None);
        assert!(
            a.message.starts_with("not named: the pattern across the cameras of light sweep 47 (θi = 60°) follows joint 2's sensitivity as an offset of +0.86° would, but it has held since the layer began (its 1 sweep(s) tested before the pattern's run read +0.19° ± 0.23, and the run departs from them by +2.1 standard errors, under 3.0)")
                && a.message.contains("drift probes ([probes] every) would tell them apart"),
            "{}",
            a.message
        );
        assert_eq!(
            serde_json::to_value(&a).unwrap()["evidence"].to_string(),
            r#"{"before_deg":0.19,"before_se_deg":0.23,"change_z":2.14,"joint":2,"layer_deg":60.0,"light":47,"offset_deg":0.86,"source":"light sweeps","sweeps_before":1,"threshold_z":3.0}"#
        );
        // none tested before: said so, and the evidence has nulls
        let a = alarm(&SweepFinding::SlipUnresolved {
            at: AT,
            joint: 1,
            offset_deg: -0.4,
            change: LayerChange::default(),
        });
        assert!(
            a.message
                .contains("(no sweep of the layer was tested before the pattern's run)"),
            "{}",
            a.message
        );
        let ev = serde_json::to_value(&a).unwrap()["evidence"].clone();
        assert_eq!(
            (ev["sweeps_before"].as_u64(), ev["change_z"].is_null()),
            (Some(0), true)
        );
        // the evidence reads back as its code's
        let back: Alarm = serde_json::from_value(serde_json::to_value(&a).unwrap()).unwrap();
        assert_eq!(back, a);
    }

    #[test]
    fn a_joint_slip_says_which_joint_to_check_and_retakes_from_the_sweep_before() {
        let slip = JointSlip {
            joint: 2,
            offset_deg: 1.25,
            se_deg: 0.25,
            estimate_sweeps: 2,
            run_mean_deg: 1.5,
            sweeps: 3,
            since_idx: 3725,
            from_idx: 3564,
            statistic: 9.5,
            threshold: 6.0,
            attributed_level_pct: None,
            recapture: Recapture::NotAsked,
            axis: None,
            other_joints: vec![JointFit {
                joint: 1,
                offset_deg: 0.5,
                se_deg: 0.25,
                z: Some(1.0),
                cusum: 0.5,
            }],
        };
        let a = alarm(&SweepFinding::JointSlip {
            at: AT,
            slip: slip.clone(),
        });
        assert_eq!(
            (a.code, a.severity),
            (AlarmCode::JointOffsetSuspected, Severity::Warning)
        );
        assert!(a
            .action
            .as_deref()
            .is_some_and(|s| s.contains("arm joint 2") && s.contains("since 3564")));
        assert_eq!(
            a.affects,
            Some(Affects::Since {
                from_idx: 3564,
                handling: Handling::Retake
            })
        );
        assert!(
            a.message.ends_with(
                "(CUSUM 9.5 > 6.0); from the light sweeps alone (no re-capture of earlier poses could check it yet)"
            ),
            "{}",
            a.message
        );
        // named by re-captures that told joint 1 from the wagon: the message says so, not
        // that a sweep's pattern showed it
        let by_axis = alarm(&SweepFinding::JointSlip {
            at: AT,
            slip: JointSlip {
                joint: 1,
                estimate_sweeps: 0,
                axis: Some(AxisReading {
                    entries: vec![1, 2, 3, 4, 5, 6, 7, 8],
                    up: 4,
                    change_pct: -3.0,
                    joint1_pct: -2.9,
                    wagon_pct: -0.6,
                    se_pct: 0.4,
                }),
                ..slip.clone()
            },
        });
        assert!(
            by_axis.message.starts_with("joint 1 looks offset by about +1.25° (± 0.25°, from the re-captured pair): two earlier poses re-captured back to back departed")
                && by_axis.message.contains("(CUSUM 9.5 > 6.0)")
                && !by_axis.message.contains("the pattern across the cameras"),
            "{}",
            by_axis.message
        );
        assert!(
            matches!(&by_axis.evidence, Evidence::JointSlip(e) if e.axis.as_ref().is_some_and(|r| r.up == 4))
        );
        // without probes the message says what would decide
        let no_probes = alarm(&SweepFinding::JointSlip {
            at: AT,
            slip: JointSlip {
                recapture: Recapture::NoProbes,
                ..slip.clone()
            },
        });
        assert!(
            no_probes.message.contains("(CUSUM 9.5 > 6.0); from the light sweeps alone, which cannot tell a slip from a stationary pattern")
                && no_probes.message.ends_with("earlier poses are re-captured to decide"),
            "{}",
            no_probes.message
        );
        assert_eq!(
            serde_json::to_value(&a).unwrap()["evidence"].to_string(),
            r#"{"estimate_sweeps":2,"joint":2,"offset_deg":1.25,"other_joints":[{"cusum":0.5,"joint":1,"offset_deg":0.5,"se_deg":0.25}],"run_mean_deg":1.5,"se_deg":0.25,"since_idx":3725,"statistic":9.5,"sweeps":3,"threshold":6.0}"#
        );
        // a level change the joint's pattern explains: the level and the attribution's test
        let a = alarm(&SweepFinding::JointSlip {
            at: AT,
            slip: JointSlip {
                attributed_level_pct: Some(-0.8),
                threshold: 3.0,
                ..slip
            },
        });
        assert!(
            a.message.contains("sit -0.80 % off") && a.message.contains("(threshold 3)"),
            "{}",
            a.message
        );
        assert!(
            matches!(&a.evidence, Evidence::JointSlip(e) if e.attributed_level_pct == Some(-0.8))
        );
    }

    #[test]
    fn a_wagon_offset_names_the_wagon_with_the_joint_it_could_be_and_retakes_from_its_start() {
        let x = WagonOffset {
            offset_deg: 1.0,
            se_deg: 0.1,
            entries: [650, 210],
            change_pct: 6.0,
            sensitivity_pct_per_deg: 6.0,
            joint_leak: [-1.5, 0.25],
            originals_lights: [8, 2],
            readings: 2,
            sweeps_z: Some(6.5),
            statistic: 4.5,
            threshold: 2.7,
            since_idx: 3564,
            approach: None,
            axis: None,
            told: true,
        };
        let a = alarm(&SweepFinding::WagonOffset {
            at: AT,
            offset: x.clone(),
        });
        assert_eq!(a.code, AlarmCode::WagonOffsetSuspected);
        assert_eq!(
            (a.kind, a.severity),
            (AlarmKind::Positioning, Severity::Warning)
        );
        assert_eq!(a.idx, Some(AT.last_idx));
        assert_eq!(
            a.affects,
            Some(Affects::Since {
                from_idx: 3564,
                handling: Handling::Retake
            })
        );
        assert!(
            a.message.contains("+1.00°") && a.message.contains("at 6.5 standard deviations"),
            "{}",
            a.message
        );
        assert!(
            matches!(&a.evidence, Evidence::WagonOffset(e) if e.source == Source::Recaptures && e.sweeps_z == Some(6.5))
        );
        // told from joint 1 by neither the sweeps nor re-captures: the camera's pose moved, by
        // the wagon or by the joint-1 slip that would read the same
        let a = alarm(&SweepFinding::WagonOffset {
            at: AT,
            offset: WagonOffset {
                sweeps_z: None,
                told: false,
                ..x.clone()
            },
        });
        assert_eq!(a.code, AlarmCode::CameraPoseMoved);
        assert!(
            a.message
                .starts_with("the camera's pose moved: the wagon by about +1.00°")
                && a.message.contains("or arm joint 1 by -0.67°")
                && a.message
                    .contains("no set of earlier poses could be re-captured"),
            "{}",
            a.message
        );
        assert!(
            a.action
                .as_deref()
                .is_some_and(|t| t.contains("arm joint 1")),
            "{:?}",
            a.action
        );
        assert!(matches!(&a.evidence, Evidence::WagonOffset(e) if e.sweeps_z.is_none()));
        // re-captures chosen to tell the two apart read the wagon's
        let axis = AxisReading {
            entries: vec![1, 2, 3, 4, 5, 6, 7, 8],
            up: 4,
            change_pct: 0.3,
            joint1_pct: 3.1,
            wagon_pct: 0.2,
            se_pct: 0.4,
        };
        let a = alarm(&SweepFinding::WagonOffset {
            at: AT,
            offset: WagonOffset {
                sweeps_z: None,
                axis: Some(axis.clone()),
                ..x.clone()
            },
        });
        assert_eq!(a.code, AlarmCode::WagonOffsetSuspected);
        assert!(
            a.message.contains("8 earlier poses re-captured back to back to tell the wagon from joint 1 moved +0.30 % against each other (± 0.40), where the wagon would have moved them +0.20 % and joint 1 +3.10 %: the wagon's"),
            "{}",
            a.message
        );
        assert!(
            matches!(&a.evidence, Evidence::WagonOffset(e) if e.axis.as_ref().is_some_and(|r| r.up == 4 && r.entries.len() == 8))
        );
        // a pose re-captured from both sides read no lag: the alarm says so
        let reading = ApproachReading {
            entries: [640, 650, 660, 650],
            change_pct: 0.1,
            sensitivity_pct_per_deg: 4.0,
            backlash_deg: -0.0125,
            se_deg: 0.07,
        };
        let a = alarm(&SweepFinding::WagonOffset {
            at: AT,
            offset: WagonOffset {
                approach: Some(reading.clone()),
                ..x
            },
        });
        assert!(
            a.message.ends_with("plan entry 650 re-captured from below and from above read +0.10 % apart (-0.01° ± 0.07° of lag): not play in the drive"),
            "{}",
            a.message
        );
        assert!(
            matches!(&a.evidence, Evidence::WagonOffset(e) if e.approach.as_ref().is_some_and(|r| r.entries == [640, 650, 660, 650]))
        );
    }

    #[test]
    fn a_level_the_layer_below_accounts_for_is_an_advisory_with_that_layers_departure() {
        let a = alarm(&SweepFinding::StepUnresolved {
            at: AT,
            up: false,
            run: run(),
            below: PatternBelow {
                below_deg: 45.0,
                departure: -0.0062,
                se: 0.0011,
                growth: 3.0,
            },
        });
        assert_eq!(
            (a.code, a.kind, a.severity),
            (AlarmCode::StepUnresolved, AlarmKind::Drift, Severity::Info)
        );
        // nothing is corrected or retaken
        assert_eq!(a.affects, None);
        assert!(
            a.message.starts_with("not raised: light sweep 47 (captures up to 3887) and the 2 before it sit -2.50 % off the earlier sweeps of θi = 60° (CUSUM 7.2 > 5.5), but at the same light azimuths the θi = 45° layer departed from its own pattern by -0.62 % ± 0.11 (5.6 standard errors), which grown towards grazing at the lamp footprint's law (×3.0) accounts for it")
                && a.message.contains("drift probes ([probes] every) would tell them apart at once"),
            "{}",
            a.message
        );
        assert_eq!(
            serde_json::to_value(&a).unwrap()["evidence"].to_string(),
            r#"{"below_deg":45.0,"below_pct":-0.62,"below_se_pct":0.11,"growth":3.0,"layer_deg":60.0,"level_pct":-2.5,"light":47,"since_idx":3725,"source":"light sweeps","statistic":7.25,"sweeps":3,"threshold":5.5,"threshold_z":3.0}"#
        );
        // the evidence reads back as its code's
        let back: Alarm = serde_json::from_value(serde_json::to_value(&a).unwrap()).unwrap();
        assert_eq!(back, a);
    }

    #[test]
    fn a_lag_read_from_both_sides_names_the_wagons_backlash_from_the_re_captures() {
        let x = WagonBacklash {
            backlash_deg: 0.95,
            se_deg: 0.07,
            estimate_sweeps: 0,
            run_mean_deg: -1.2,
            offset_deg: -1.2,
            sweeps: 0,
            since_idx: 3480,
            from_idx: 3402,
            statistic: 5.1,
            threshold: 2.7,
            approach: Some(ApproachReading {
                entries: [640, 650, 660, 650],
                change_pct: -7.6,
                sensitivity_pct_per_deg: 4.0,
                backlash_deg: 0.95,
                se_deg: 0.07,
            }),
        };
        let a = alarm(&SweepFinding::WagonBacklash {
            at: AT,
            backlash: x.clone(),
        });
        assert_eq!(a.code, AlarmCode::WagonBacklashSuspected);
        assert_eq!(
            a.affects,
            Some(Affects::Since {
                from_idx: 3402,
                handling: Handling::Retake
            })
        );
        assert!(
            a.message.starts_with("the wagon lags about 0.95° (± 0.07°)")
                && a.message.contains("moved -1.20° of wagon against each other (CUSUM 5.1 > 2.7), plan entry 650 re-captured once approached from below (after entry 640) and once from above (after entry 660) read -7.60 % apart at +4.00 %/° of wagon"),
            "{}",
            a.message
        );
        let Evidence::WagonBacklash(e) = &a.evidence else {
            panic!("typed evidence")
        };
        assert_eq!(e.source, Source::Recaptures);
        assert_eq!(e.approach.as_ref().map(|r| r.backlash_deg), Some(0.95));
        // the sweeps' own: no approach in the evidence at all
        let a = alarm(&SweepFinding::WagonBacklash {
            at: AT,
            backlash: WagonBacklash {
                approach: None,
                ..x
            },
        });
        let Evidence::WagonBacklash(e) = &a.evidence else {
            panic!("typed evidence")
        };
        assert_eq!(e.source, Source::LightSweeps);
        assert!(serde_json::to_value(&a).unwrap()["evidence"]
            .get("approach")
            .is_none());
    }
}
