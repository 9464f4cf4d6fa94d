//! The drift-probe cadence that meets a detection target (`goniowatch plan`).
//!
//! For each candidate cadence (a probe every N regular captures) the daemon's own probe detector
//! (`measure::probes`, with the session's `[probes]` settings) runs on simulated probe series: a
//! fault-free lamp, a linear decay and a step at a random onset, each over many runs with
//! log-normal probe scatter of the given size. The recommendation is the sparsest cadence whose
//! false-alarm rate, decay deadline and step delay all meet the target. The detector estimates
//! its scale from the segment's own few residuals and its step rule has a floor in %, so
//! closed-form ARL formulas do not describe it; its behaviour is measured, not approximated.
//!
//! Deterministic: every run draws from a SplitMix64 seeded by (cadence, scenario, run), so the
//! same inputs print the same plan on every machine.

use super::drift::DriftEvent;
use super::probes::{ProbeDrift, ProbeSpec};
use super::stats::SplitMix64;
use serde::Serialize;

/// What the probes must achieve. The defaults are the daemon's design target: a 1 %/h decay
/// flagged before a quarter of the run, a −2 % step within 300 captures, in 9 runs of 10 each,
/// and at most one false alarm in 20 fault-free runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DetectionTarget {
    /// A linear decay of the gain (%/h; its sign does not matter to the detector).
    pub decay_pct_per_h: f64,
    /// ... flagged before this fraction of the run.
    pub decay_by_fraction: f64,
    /// A step of the gain (%; negative: darker) ...
    pub step_pct: f64,
    /// ... flagged (a step alarm of its sign) within this many regular captures of its onset.
    pub step_within_captures: u64,
    /// Runs with any probe alarm on a fault-free lamp, at most (0.05: one in 20).
    pub false_alarms_per_run: f64,
    /// The share of runs that must meet each detection target.
    pub power: f64,
}

impl Default for DetectionTarget {
    fn default() -> Self {
        DetectionTarget {
            decay_pct_per_h: 1.0,
            decay_by_fraction: 0.25,
            step_pct: -2.0,
            step_within_captures: 300,
            false_alarms_per_run: 0.05,
            power: 0.9,
        }
    }
}

/// The session the probes are planned for.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbeSession {
    /// Regular captures in the plan.
    pub captures: u64,
    pub seconds_per_capture: f64,
    /// What one probe adds to the run (the move out, the capture and the move back).
    pub seconds_per_probe: f64,
    /// The plan index of the probe entry's own capture: probes before it have nothing to be
    /// compared with (they cost time and are ignored).
    pub anchor: u64,
    /// Probes are asked for from this many regular captures on (a pose the daemon chooses is
    /// chosen after a light sweep's worth of captures).
    pub probes_from: u64,
    /// The scatter of one probe's luminance against its original (% SD of the ratio): camera
    /// noise, lamp flicker and the rig's repeatability at the probe pose together.
    pub scatter_pct: f64,
}

/// One cadence's measured figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CadenceFigures {
    /// A probe every this many regular captures.
    pub every: u64,
    pub probes_per_run: u64,
    /// Run time the probes add (hours, and % of the run without them).
    pub overhead_h: f64,
    pub overhead_pct: f64,
    /// Fault-free runs with at least one probe alarm, as a share of the runs.
    pub false_alarms_per_run: f64,
    /// Share of decay runs flagged before the deadline, and the median time of the flag as a
    /// fraction of the run (None when fewer than half were flagged at all).
    pub decay_in_time: f64,
    pub decay_median_fraction: Option<f64>,
    /// Share of step runs flagged within the window, and the median delay in regular captures
    /// (None when fewer than half were flagged at all).
    pub step_in_time: f64,
    pub step_median_delay: Option<f64>,
    pub meets: bool,
}

/// The outcome of the design.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum ProbePlan {
    /// The sparsest cadence that meets every part of the target.
    Recommended {
        cadence: CadenceFigures,
        tried: Vec<CadenceFigures>,
    },
    /// No candidate cadence meets the target; `reason` says which part fails at the best one
    /// and what would help.
    Unreachable {
        reason: String,
        tried: Vec<CadenceFigures>,
    },
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProbePlanError {
    #[error("{field}: {message}")]
    Invalid {
        field: &'static str,
        message: String,
    },
}

/// Candidate cadences, sparsest first.
pub const CADENCES: [u64; 12] = [600, 450, 300, 250, 200, 150, 100, 75, 50, 35, 25, 15];

/// Monte Carlo runs per cadence and scenario: a share of 0.05 is then resolved to about ±0.015.
pub const RUNS: u64 = 200;

#[derive(Debug, Clone, Copy)]
enum Scenario {
    FaultFree,
    Decay,
    /// Onset in regular captures.
    Step(u64),
}

/// One simulated run: the probe alarms, each with the regular capture count it came after.
fn simulate(
    s: &ProbeSession,
    spec: &ProbeSpec,
    target: &DetectionTarget,
    every: u64,
    scenario: Scenario,
    rng: &mut SplitMix64,
) -> Vec<(u64, DriftEvent)> {
    let sigma = s.scatter_pct / 100.0;
    // time (h) after `regular` captures and `probes` probes
    let time_h = |regular: u64, probes: u64| {
        (regular as f64 * s.seconds_per_capture + probes as f64 * s.seconds_per_probe) / 3600.0
    };
    let gain = |regular: u64, t_h: f64| -> f64 {
        match scenario {
            Scenario::FaultFree => 1.0,
            Scenario::Decay => (1.0 - target.decay_pct_per_h / 100.0 * t_h).max(1e-6),
            Scenario::Step(onset) => {
                if regular > onset {
                    1.0 + target.step_pct / 100.0
                } else {
                    1.0
                }
            }
        }
    };
    let mut det = ProbeDrift::new(ProbeSpec {
        every,
        ..spec.clone()
    });
    let mut out = Vec::new();
    let mut probes = 0u64;
    let mut orig: Option<(f64, f64)> = None;
    let mut regular = 0u64;
    while regular < s.captures {
        // the regular capture `regular` is taken
        if regular == s.anchor {
            let t = time_h(regular, probes);
            orig = Some((t, gain(regular, t) * (sigma * rng.gauss()).exp()));
        }
        regular += 1;
        if regular.is_multiple_of(every) && regular < s.captures && regular >= s.probes_from {
            let t = time_h(regular, probes);
            probes += 1;
            if let Some((t0, y0)) = orig {
                let y = gain(regular, t) * (sigma * rng.gauss()).exp();
                // the plan designs the drift alarms; lamp-unstable judges its scatter assumption
                for ev in det.add(regular, t0, y0, t, y) {
                    if !matches!(
                        ev,
                        DriftEvent::Unstable { .. } | DriftEvent::UnstableCleared { .. }
                    ) {
                        out.push((regular, ev));
                    }
                }
                let stop = match scenario {
                    Scenario::FaultFree => false,
                    Scenario::Decay => out
                        .iter()
                        .any(|(_, e)| matches!(e, DriftEvent::RateSignificant(_))),
                    Scenario::Step(onset) => {
                        regular > onset + target.step_within_captures
                            || step_after(&out, onset, target).is_some()
                    }
                };
                if stop {
                    break;
                }
            }
        }
    }
    out
}

/// The first step alarm of the target's sign after `onset`: its delay in regular captures.
fn step_after(events: &[(u64, DriftEvent)], onset: u64, target: &DetectionTarget) -> Option<u64> {
    let sign: i8 = if target.step_pct < 0.0 { -1 } else { 1 };
    events.iter().find_map(|(at, e)| match e {
        DriftEvent::Step { direction, .. } if *direction == sign && *at > onset => Some(at - onset),
        _ => None,
    })
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| super::stats::median_sorted(&v))
}

/// The figures of one cadence over `RUNS` runs per scenario.
pub fn cadence_figures(
    s: &ProbeSession,
    spec: &ProbeSpec,
    target: &DetectionTarget,
    every: u64,
) -> CadenceFigures {
    let run_h = s.captures as f64 * s.seconds_per_capture / 3600.0;
    // requests at every multiple of `every` from `probes_from` up to the last capture
    let asked = |upto: u64| upto.saturating_sub(1) / every;
    let probes_per_run = asked(s.captures) - asked(s.probes_from).min(asked(s.captures));
    let overhead_h = probes_per_run as f64 * s.seconds_per_probe / 3600.0;
    // every cadence draws the same numbers (common random numbers): cadences differ by their
    // cadence, not by their luck, so "the sparsest that meets" is not picked by chance
    let seed = |scenario: u64, run: u64| SplitMix64((scenario << 40) ^ run);

    let mut false_runs = 0u64;
    let mut decay_ok = 0u64;
    let mut decay_at = Vec::new();
    let mut step_ok = 0u64;
    let mut step_delay = Vec::new();
    for run in 0..RUNS {
        if !simulate(
            s,
            spec,
            target,
            every,
            Scenario::FaultFree,
            &mut seed(1, run),
        )
        .is_empty()
        {
            false_runs += 1;
        }
        let decay = simulate(s, spec, target, every, Scenario::Decay, &mut seed(2, run));
        if let Some((at, _)) = decay
            .iter()
            .find(|(_, e)| matches!(e, DriftEvent::RateSignificant(_)))
        {
            let fraction = *at as f64 / s.captures as f64;
            decay_at.push(fraction);
            if fraction <= target.decay_by_fraction {
                decay_ok += 1;
            }
        }
        // onsets spread over the run after the anchor, from 10 % to 90 %
        let mut r = seed(3, run);
        let lo = (s.captures as f64 * 0.1).max(s.anchor as f64 + 1.0);
        let hi = (s.captures as f64 * 0.9).max(lo + 1.0);
        let onset = r.range(lo, hi) as u64;
        let step = simulate(s, spec, target, every, Scenario::Step(onset), &mut r);
        if let Some(d) = step_after(&step, onset, target) {
            step_delay.push(d as f64);
            if d <= target.step_within_captures {
                step_ok += 1;
            }
        }
    }
    let n = RUNS as f64;
    let false_alarms_per_run = false_runs as f64 / n;
    let decay_in_time = decay_ok as f64 / n;
    let step_in_time = step_ok as f64 / n;
    let half = |v: &Vec<f64>| v.len() as f64 >= n / 2.0;
    CadenceFigures {
        every,
        probes_per_run,
        overhead_h,
        overhead_pct: 100.0 * overhead_h / run_h,
        false_alarms_per_run,
        decay_in_time,
        decay_median_fraction: if half(&decay_at) {
            median(decay_at)
        } else {
            None
        },
        step_in_time,
        step_median_delay: if half(&step_delay) {
            median(step_delay)
        } else {
            None
        },
        meets: false_alarms_per_run <= target.false_alarms_per_run
            && decay_in_time >= target.power
            && step_in_time >= target.power,
    }
}

fn check(s: &ProbeSession, target: &DetectionTarget) -> Result<(), ProbePlanError> {
    let bad = |field: &'static str, message: &str| {
        Err(ProbePlanError::Invalid {
            field,
            message: message.into(),
        })
    };
    if s.captures < 2 {
        return bad("captures", "a plan of at least 2 captures");
    }
    if s.anchor >= s.captures {
        return bad("probes.entry", "the probe entry is not in the plan");
    }
    if !(s.seconds_per_capture > 0.0 && s.seconds_per_capture.is_finite()) {
        return bad("seconds_per_capture", "a positive number");
    }
    if !(s.seconds_per_probe >= 0.0 && s.seconds_per_probe.is_finite()) {
        return bad("seconds_per_probe", "zero or a positive number");
    }
    if !(s.scatter_pct > 0.0 && s.scatter_pct < 100.0) {
        return bad("scatter_pct", "between 0 and 100 (exclusive)");
    }
    if !(target.decay_pct_per_h.abs() > 0.0 && target.decay_pct_per_h.abs() < 100.0) {
        return bad("decay_pct_per_h", "non-zero, within ±100");
    }
    if !(target.decay_by_fraction > 0.0 && target.decay_by_fraction <= 1.0) {
        return bad("decay_by_fraction", "in (0, 1]");
    }
    if !(target.step_pct.abs() > 0.0 && target.step_pct > -100.0 && target.step_pct < 1000.0) {
        return bad("step_pct", "non-zero, above −100");
    }
    if target.step_within_captures == 0 {
        return bad("step_within_captures", "at least 1");
    }
    if !(0.0..=1.0).contains(&target.false_alarms_per_run) {
        return bad("false_alarms_per_run", "in [0, 1]");
    }
    if !(target.power > 0.0 && target.power <= 1.0) {
        return bad("power", "in (0, 1]");
    }
    Ok(())
}

/// Why the best cadence (the one that meets most of the target, the densest on a tie) fails.
fn unreachable_reason(
    s: &ProbeSession,
    spec: &ProbeSpec,
    target: &DetectionTarget,
    tried: &[CadenceFigures],
) -> String {
    let score = |c: &CadenceFigures| {
        (c.false_alarms_per_run <= target.false_alarms_per_run) as u8
            + (c.decay_in_time >= target.power) as u8
            + (c.step_in_time >= target.power) as u8
    };
    // max_by_key keeps the last of equals: the densest
    let Some(best) = tried.iter().max_by_key(|c| score(c)) else {
        return "no cadence was tried".into();
    };
    let mut why = Vec::new();
    if best.step_in_time < target.power {
        let floor = (spec.step_sigmas * s.scatter_pct).max(spec.step_pct);
        why.push(format!(
            "a {:+} % step is flagged within {} captures in {:.0} % of runs (target {:.0} %): a step alarm needs a probe off its line by {} × the probe scatter ({} %) and at least {} %, so about {:.1} %; a probe pose with less scatter (brighter, far from grazing, away from the specular peak) or a larger step target",
            target.step_pct,
            target.step_within_captures,
            100.0 * best.step_in_time,
            100.0 * target.power,
            spec.step_sigmas,
            s.scatter_pct,
            spec.step_pct,
            floor
        ));
    }
    if best.decay_in_time < target.power {
        why.push(format!(
            "a {} %/h decay is flagged before {:.0} % of the run in {:.0} % of runs (target {:.0} %): the rate must exceed the tolerance ({} %/h) by z ({}) standard errors; a later deadline, or probes with less scatter",
            target.decay_pct_per_h,
            100.0 * target.decay_by_fraction,
            100.0 * best.decay_in_time,
            100.0 * target.power,
            spec.rate_tolerance_pct_per_h,
            spec.z
        ));
    }
    if best.false_alarms_per_run > target.false_alarms_per_run {
        why.push(format!(
            "{:.1} % of fault-free runs raise a probe alarm (target at most {:.1} %): raise [probes] step_sigmas or z",
            100.0 * best.false_alarms_per_run,
            100.0 * target.false_alarms_per_run
        ));
    }
    format!(
        "no cadence from every {} to every {} captures meets the target; at every {}: {}",
        CADENCES[0],
        CADENCES[CADENCES.len() - 1],
        best.every,
        why.join("; ")
    )
}

/// The probe plan for a session: every candidate cadence's figures and the recommendation.
pub fn design(
    s: &ProbeSession,
    spec: &ProbeSpec,
    target: &DetectionTarget,
) -> Result<ProbePlan, ProbePlanError> {
    check(s, target)?;
    let tried: Vec<CadenceFigures> = CADENCES
        .iter()
        .filter(|&&every| every < s.captures)
        .map(|&every| cadence_figures(s, spec, target, every))
        .collect();
    match tried.iter().find(|c| c.meets) {
        Some(c) => Ok(ProbePlan::Recommended {
            cadence: c.clone(),
            tried,
        }),
        None => Ok(ProbePlan::Unreachable {
            reason: unreachable_reason(s, spec, target, &tried),
            tried,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ubo(scatter_pct: f64) -> ProbeSession {
        ProbeSession {
            captures: 6561,
            seconds_per_capture: 7.0,
            seconds_per_probe: 7.0,
            anchor: 11,
            probes_from: 0,
            scatter_pct,
        }
    }

    /// The design for the UBO session at this scatter, with the default settings and target.
    fn default_design(scatter_pct: f64) -> ProbePlan {
        design(
            &ubo(scatter_pct),
            &ProbeSpec::default(),
            &DetectionTarget::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_quiet_probe_pose_gets_a_sparse_cadence_that_meets_the_default_target() {
        let plan = default_design(0.3);
        let ProbePlan::Recommended { cadence, tried } = plan else {
            panic!("{plan:?}");
        };
        // a step must be seen within 300 captures, so a probe at least every 300
        assert!(cadence.every <= 300, "{cadence:?}");
        assert!(cadence.false_alarms_per_run <= 0.05);
        assert!(cadence.decay_in_time >= 0.9 && cadence.step_in_time >= 0.9);
        // the sparsest that meets: every sparser candidate fails
        assert!(tried
            .iter()
            .take_while(|c| c.every > cadence.every)
            .all(|c| !c.meets));
        // what it costs: a probe per `every` captures of the same length
        assert!(
            (cadence.overhead_pct - 100.0 / cadence.every as f64).abs() < 0.1,
            "{cadence:?}"
        );
    }

    #[test]
    fn a_noisy_probe_pose_cannot_meet_the_target_and_says_why() {
        let plan = default_design(2.0);
        let ProbePlan::Unreachable { reason, tried } = plan else {
            panic!("{plan:?}");
        };
        assert_eq!(tried.len(), CADENCES.len());
        assert!(reason.contains("no cadence"), "{reason}");
        assert!(reason.contains("step"), "{reason}");
        assert!(reason.contains("scatter (2 %)"), "{reason}");
    }

    #[test]
    fn the_design_is_deterministic() {
        let a = cadence_figures(
            &ubo(0.3),
            &ProbeSpec::default(),
            &DetectionTarget::default(),
            100,
        );
        let b = cadence_figures(
            &ubo(0.3),
            &ProbeSpec::default(),
            &DetectionTarget::default(),
            100,
        );
        assert_eq!(a, b);
    }

    #[test]
    fn denser_probes_flag_a_decay_earlier() {
        let t = DetectionTarget::default();
        let sparse = cadence_figures(&ubo(0.3), &ProbeSpec::default(), &t, 300);
        let dense = cadence_figures(&ubo(0.3), &ProbeSpec::default(), &t, 50);
        assert!(
            dense.decay_median_fraction.unwrap() < sparse.decay_median_fraction.unwrap(),
            "{dense:?} {sparse:?}"
        );
    }

    #[test]
    fn bad_inputs_are_refused_with_the_field() {
        let t = DetectionTarget::default();
        let spec = ProbeSpec::default();
        let mut s = ubo(0.0);
        assert!(matches!(
            design(&s, &spec, &t),
            Err(ProbePlanError::Invalid {
                field: "scatter_pct",
                ..
            })
        ));
        s.scatter_pct = f64::NAN;
        assert!(design(&s, &spec, &t).is_err());
        s = ubo(0.3);
        s.anchor = 7000;
        assert!(matches!(
            design(&s, &spec, &t),
            Err(ProbePlanError::Invalid {
                field: "probes.entry",
                ..
            })
        ));
        let bad = DetectionTarget { power: 0.0, ..t };
        assert!(matches!(
            design(&ubo(0.3), &spec, &bad),
            Err(ProbePlanError::Invalid { field: "power", .. })
        ));
    }
}
