//! The drift-probe cadence that meets a detection target (`goniowatch plan`).
//!
//! For each candidate cadence (a probe every N regular captures) the daemon's own probe detector
//! (`detect::probes`, with the session's `[probes]` settings) runs on simulated probe series: a
//! fault-free lamp, a linear decay and a step at a random onset, each over many runs with
//! log-normal probe scatter of the given size. The recommendation is the sparsest cadence whose
//! false-alarm rate, decay deadline and step delay all meet the target. The detector estimates
//! its scale from the segment's own few residuals and its step rule has a floor in %, so
//! closed-form ARL formulas do not describe it; its behaviour is measured, not approximated.
//!
//! The colour target runs the daemon's colour check on the same probes (`checks::drift`: rate
//! fits of ln X/Y and ln Z/Y against the probe pose's original, turned into a colour-temperature
//! rate by the lamp model): a lamp whose colour temperature moves linearly, through the same
//! Planck model, with the probes' chromaticity scatter.
//!
//! Deterministic: every run draws from a SplitMix64 seeded by (cadence, scenario, run), so the
//! same inputs print the same plan on every machine.

use super::drift::{DriftDetector, DriftEvent, PairObservation};
use super::lamp::LampColour;
use super::probes::{colour_fit_spec, ProbeDrift, ProbeSpec};
use crate::measure::stats::SplitMix64;
use serde::Serialize;

mod simulate;
#[cfg(test)]
mod tests;
use simulate::*;

/// What the probes must achieve. The defaults are the daemon's design target: a 1 %/h decay
/// flagged before a quarter of the run, a −2 % step within 300 captures and a −20 K/h colour
/// drift before 15 % of the run, in 9 runs of 10 each, and at most one false alarm in 20
/// fault-free runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub(crate) struct DetectionTarget {
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
    /// A linear drift of the lamp's colour temperature (K/h; 0: no colour target) ...
    pub colour_k_per_h: f64,
    /// ... flagged (`colour-drift`) before this fraction of the run.
    pub colour_by_fraction: f64,
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
            colour_k_per_h: -20.0,
            colour_by_fraction: 0.15,
        }
    }
}

/// The session the probes are planned for.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ProbeSession {
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
    /// The colour check on the probes; None: the plan has no colour target.
    pub colour: Option<ColourProbes>,
}

/// The colour check the probes feed (`[checks.colour_drift]`) and their chromaticity scatter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ColourProbes {
    /// The lamp's colour temperature at the start (K): the lamp model's reference.
    pub lamp_cct_k: f64,
    pub tolerance_k_per_h: f64,
    pub z: f64,
    /// The scatter of a probe's ln X/Y and of its ln Z/Y against its original (% SD each).
    pub scatter_pct: f64,
}

/// One cadence's measured figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct CadenceFigures {
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
    /// Share of colour-drift runs flagged before the deadline (None without a colour target),
    /// and the median time of the flag as a fraction of the run, over the runs flagged before
    /// twice the deadline (None when fewer than half were).
    pub colour_in_time: Option<f64>,
    pub colour_median_fraction: Option<f64>,
    pub meets: bool,
}

/// The outcome of the design.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub(crate) enum ProbePlan {
    /// The sparsest cadence that meets every part of the target; `tried` holds the cadences
    /// tried, sparsest first, up to it.
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
pub(crate) enum ProbePlanError {
    #[error("{field}: {message}")]
    Invalid {
        field: &'static str,
        message: String,
    },
}

/// Candidate cadences, sparsest first.
pub(crate) const CADENCES: [u64; 12] = [600, 450, 300, 250, 200, 150, 100, 75, 50, 35, 25, 15];

/// Monte Carlo runs per cadence and scenario: a share of 0.05 is then resolved to about ±0.015.
pub(crate) const RUNS: u64 = 200;

/// The figures of one cadence over `RUNS` runs per scenario.
pub(crate) fn cadence_figures(
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
    // the colour check, when the plan has a colour target and the lamp model can be built
    let colour_model = s
        .colour
        .as_ref()
        .filter(|_| target.colour_k_per_h != 0.0)
        .and_then(|c| Some((c, LampColour::new(c.lamp_cct_k).ok()?)));
    let colour = colour_model.as_ref().map(|(c, m)| (*c, m));
    let lamps = colour.map(|c| {
        (
            lamp_chroma(s, c, every, 0.0),
            lamp_chroma(s, c, every, target.colour_k_per_h),
        )
    });
    let mut colour_ok = 0u64;
    let mut colour_at = Vec::new();
    // a drifting run is followed to twice the deadline: enough for the median of a cadence
    // that nearly meets it, without refitting to the end of the run
    let horizon = (2.0 * target.colour_by_fraction * s.captures as f64).ceil() as u64;
    for run in 0..RUNS {
        let gain_false = !simulate(
            s,
            spec,
            target,
            every,
            Scenario::FaultFree,
            &mut seed(1, run),
        )
        .is_empty();
        // a fault-free run's colour check: the same lamp, its own scatter draws
        let colour_false = colour.zip(lamps.as_ref()).is_some_and(|(c, (steady, _))| {
            simulate_colour(s, spec, c, every, steady, s.captures, &mut seed(4, run)).is_some()
        });
        if gain_false || colour_false {
            false_runs += 1;
        }
        if let Some((c, (_, drifting))) = colour.zip(lamps.as_ref()) {
            let at = simulate_colour(s, spec, c, every, drifting, horizon, &mut seed(5, run));
            if let Some(at) = at {
                let fraction = at as f64 / s.captures as f64;
                colour_at.push(fraction);
                if fraction <= target.colour_by_fraction {
                    colour_ok += 1;
                }
            }
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
    let colour_in_time = colour.map(|_| colour_ok as f64 / n);
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
        colour_median_fraction: if half(&colour_at) {
            median(colour_at)
        } else {
            None
        },
        colour_in_time,
        meets: false_alarms_per_run <= target.false_alarms_per_run
            && decay_in_time >= target.power
            && step_in_time >= target.power
            && colour_in_time.is_none_or(|c| c >= target.power),
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
    if !(target.colour_k_per_h.is_finite() && target.colour_k_per_h.abs() < 10_000.0) {
        return bad("colour_k_per_h", "within ±10,000 (0: no colour target)");
    }
    if target.colour_k_per_h != 0.0
        && s.colour.is_some()
        && !(target.colour_by_fraction > 0.0 && target.colour_by_fraction <= 1.0)
    {
        return bad("colour_by_fraction", "in (0, 1]");
    }
    if let Some(c) = &s.colour {
        if !(c.scatter_pct > 0.0 && c.scatter_pct < 100.0) {
            return bad("colour.scatter_pct", "between 0 and 100 (exclusive)");
        }
        if !(c.z > 0.0 && c.z.is_finite()) {
            return bad("checks.colour_drift.z", "a positive number");
        }
        if !(c.tolerance_k_per_h >= 0.0 && c.tolerance_k_per_h.is_finite()) {
            return bad(
                "checks.colour_drift.tolerance_k_per_h",
                "zero or a positive number",
            );
        }
        if !(c.lamp_cct_k.is_finite() && (1000.0..=20_000.0).contains(&c.lamp_cct_k)) {
            return bad("checks.colour_drift.lamp_cct_k", "1000 to 20,000 K");
        }
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
    let colour_ok = |c: &CadenceFigures| c.colour_in_time.is_none_or(|x| x >= target.power);
    let score = |c: &CadenceFigures| {
        (c.false_alarms_per_run <= target.false_alarms_per_run) as u8
            + (c.decay_in_time >= target.power) as u8
            + (c.step_in_time >= target.power) as u8
            + colour_ok(c) as u8
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
    if let (Some(share), Some(c)) = (best.colour_in_time, &s.colour) {
        if share < target.power {
            why.push(format!(
                "a {:+} K/h colour drift is flagged before {:.0} % of the run in {:.0} % of runs (target {:.0} %): the colour-temperature rate must exceed the tolerance ({} K/h) by z ({}) standard errors, judged once the fits have {} probes, with {} % chromaticity scatter per probe and the fits' scale floored at [probes] design_scatter_pct ({} %); a later deadline, or design_scatter_pct set to the probes' measured scatter if it is lower",
                target.colour_k_per_h,
                100.0 * target.colour_by_fraction,
                100.0 * share,
                100.0 * target.power,
                c.tolerance_k_per_h,
                c.z,
                spec.min_probes.max(3),
                c.scatter_pct,
                spec.design_scatter_pct
            ));
        }
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
pub(crate) fn design(
    s: &ProbeSession,
    spec: &ProbeSpec,
    target: &DetectionTarget,
) -> Result<ProbePlan, ProbePlanError> {
    check(s, target)?;
    // sparsest first, up to the first that meets: a denser cadence costs more run time and
    // (with the colour check's fits refitted at every probe) more design time
    let mut tried = Vec::new();
    for &every in CADENCES.iter().filter(|&&every| every < s.captures) {
        let c = cadence_figures(s, spec, target, every);
        if c.meets {
            tried.push(c.clone());
            return Ok(ProbePlan::Recommended { cadence: c, tried });
        }
        tried.push(c);
    }
    Ok(ProbePlan::Unreachable {
        reason: unreachable_reason(s, spec, target, &tried),
        tried,
    })
}
