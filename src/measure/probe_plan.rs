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
use super::stats::SplitMix64;
use serde::Serialize;

/// What the probes must achieve. The defaults are the daemon's design target: a 1 %/h decay
/// flagged before a quarter of the run, a −2 % step within 300 captures and a −20 K/h colour
/// drift before 15 % of the run, in 9 runs of 10 each, and at most one false alarm in 20
/// fault-free runs.
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
    /// The colour check on the probes; None: the plan has no colour target.
    pub colour: Option<ColourProbes>,
}

/// The colour check the probes feed (`[checks.colour_drift]`) and their chromaticity scatter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ColourProbes {
    /// The lamp's colour temperature at the start (K): the lamp model's reference.
    pub lamp_cct_k: f64,
    pub tolerance_k_per_h: f64,
    pub z: f64,
    /// The scatter of a probe's ln X/Y and of its ln Z/Y against its original (% SD each).
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
pub enum ProbePlan {
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
            let t = time_h(s, regular, probes);
            orig = Some((t, gain(regular, t) * (sigma * rng.gauss()).exp()));
        }
        regular += 1;
        if probe_due(s, every, regular) {
            let t = time_h(s, regular, probes);
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

/// The lamp's ln X/Y and ln Z/Y relative to the start, for a colour temperature moving by
/// `k_per_h`: at the probe pose's original capture and at each probe of the cadence `every`
/// (the lamp model is evaluated once per cadence, not once per simulated run).
struct LampChroma {
    anchor: [f64; 2],
    probes: Vec<[f64; 2]>,
}

fn lamp_chroma(
    s: &ProbeSession,
    (c, model): (&ColourProbes, &LampColour),
    every: u64,
    k_per_h: f64,
) -> LampChroma {
    let at = |t_h: f64| model.log_chromaticity(c.lamp_cct_k + k_per_h * t_h);
    let mut out = LampChroma {
        anchor: [0.0; 2],
        probes: Vec::new(),
    };
    let (mut regular, mut probes) = (0u64, 0u64);
    while regular < s.captures {
        if regular == s.anchor {
            out.anchor = at(time_h(s, regular, probes));
        }
        regular += 1;
        if probe_due(s, every, regular) {
            out.probes.push(at(time_h(s, regular, probes)));
            probes += 1;
        }
    }
    out
}

/// The run time (h) after `regular` captures and `probes` probes.
fn time_h(s: &ProbeSession, regular: u64, probes: u64) -> f64 {
    (regular as f64 * s.seconds_per_capture + probes as f64 * s.seconds_per_probe) / 3600.0
}

/// Whether a probe is taken once `regular` regular captures are in.
fn probe_due(s: &ProbeSession, every: u64, regular: u64) -> bool {
    regular.is_multiple_of(every) && regular < s.captures && regular >= s.probes_from
}

/// One simulated run of the colour check on the probes (the lamp's luminance kept: the check
/// reads chromaticity only): the regular capture count after which `colour-drift` was first
/// raised, if it was before `horizon` regular captures.
fn simulate_colour(
    s: &ProbeSession,
    spec: &ProbeSpec,
    (c, model): (&ColourProbes, &LampColour),
    every: u64,
    lamp: &LampChroma,
    horizon: u64,
    rng: &mut SplitMix64,
) -> Option<u64> {
    let sigma = c.scatter_pct / 100.0;
    let noisy = |m: [f64; 2], rng: &mut SplitMix64| {
        [m[0] + sigma * rng.gauss(), m[1] + sigma * rng.gauss()]
    };
    let fit = DriftDetector::new(colour_fit_spec(
        spec.min_probes,
        spec.design_scatter_pct / 100.0,
    ));
    let mut fits = [fit.clone(), fit];
    let mut orig: Option<(f64, [f64; 2])> = None;
    let (mut regular, mut probes, mut judged) = (0u64, 0u64, 0usize);
    while regular < s.captures.min(horizon) {
        if regular == s.anchor {
            orig = Some((time_h(s, regular, probes), noisy(lamp.anchor, rng)));
        }
        regular += 1;
        if !probe_due(s, every, regular) {
            continue;
        }
        let t = time_h(s, regular, probes);
        let m = lamp
            .probes
            .get(probes as usize)
            .copied()
            .unwrap_or([0.0; 2]);
        probes += 1;
        let Some((t0, c0)) = orig else {
            continue;
        };
        let now = noisy(m, rng);
        for (k, fit) in fits.iter_mut().enumerate() {
            fit.add(PairObservation {
                t_a_h: t0,
                t_b_h: t,
                d: now[k] - c0[k],
                bucket: (0, 0),
                sigma: 0.0,
                mount: [0.0; 4],
            });
        }
        let (Some(u), Some(v)) = (fits[0].estimate(), fits[1].estimate()) else {
            continue;
        };
        // judged at each refit, as the daemon does
        if u.pairs == judged {
            continue;
        }
        judged = u.pairs;
        let (u, v) = (
            (u.rate_pct_per_h / 100.0, u.se_pct_per_h / 100.0),
            (v.rate_pct_per_h / 100.0, v.se_pct_per_h / 100.0),
        );
        if model
            .cct_rate(u, v, t)
            .is_some_and(|r| r.exceeds(c.tolerance_k_per_h, c.z))
        {
            return Some(regular);
        }
    }
    None
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
pub fn design(
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
            colour: None,
        }
    }

    /// The UBO session whose probes also feed the colour check (a 3000 K lamp, the default
    /// tolerance and z), with `colour_pct` chromaticity scatter.
    fn ubo_colour(scatter_pct: f64, colour_pct: f64) -> ProbeSession {
        ProbeSession {
            colour: Some(ColourProbes {
                lamp_cct_k: 3000.0,
                tolerance_k_per_h: 5.0,
                z: 4.0,
                scatter_pct: colour_pct,
            }),
            ..ubo(scatter_pct)
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
    fn the_colour_target_asks_for_denser_probes_and_names_itself_when_missed() {
        let spec = ProbeSpec::default();
        let t = DetectionTarget::default();
        // a probe every 200 meets the luminance target (the design without colour recommends
        // it) ...
        let luminance = cadence_figures(&ubo(0.3), &spec, &t, 200);
        assert!(
            luminance.meets && luminance.colour_in_time.is_none(),
            "{luminance:?}"
        );
        // ... but −20 K/h before 15 % of the run is judged from the colour fits' 4th probe on,
        // at 12 % of the run at best: most runs miss it
        let sparse = cadence_figures(&ubo_colour(0.3, 0.3), &spec, &t, 200);
        assert!(!sparse.meets, "{sparse:?}");
        assert!(sparse.colour_in_time.unwrap() < 0.5, "{sparse:?}");
        assert_eq!(
            (sparse.decay_in_time, sparse.step_in_time),
            (luminance.decay_in_time, luminance.step_in_time)
        );
        let dense = cadence_figures(&ubo_colour(0.3, 0.3), &spec, &t, 75);
        assert!(dense.meets, "{dense:?}");
        assert!(dense.colour_in_time.unwrap() >= 0.9);
        assert!(dense.colour_median_fraction.unwrap() <= 0.15);
        // the colour fits' scale floor keeps fault-free runs quiet: the colour check adds no
        // false alarm to the luminance checks' at this cadence
        let quiet = cadence_figures(&ubo(0.3), &spec, &t, 75);
        assert_eq!(dense.false_alarms_per_run, quiet.false_alarms_per_run);
        // the reason names the colour target when it is the part that fails
        let why = unreachable_reason(&ubo_colour(0.3, 0.3), &spec, &t, &[sparse]);
        assert!(why.contains("-20 K/h colour drift"), "{why}");
        assert!(
            !why.contains("step is flagged") && !why.contains("decay"),
            "{why}"
        );
        // no colour target: the same as no colour check
        let none = DetectionTarget {
            colour_k_per_h: 0.0,
            ..t
        };
        assert_eq!(
            cadence_figures(&ubo_colour(0.3, 0.3), &spec, &none, 200),
            cadence_figures(&ubo(0.3), &spec, &none, 200)
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
        let bad = DetectionTarget {
            colour_k_per_h: f64::NAN,
            ..t
        };
        assert!(matches!(
            design(&ubo(0.3), &spec, &bad),
            Err(ProbePlanError::Invalid {
                field: "colour_k_per_h",
                ..
            })
        ));
        assert!(matches!(
            design(&ubo_colour(0.3, -1.0), &spec, &t),
            Err(ProbePlanError::Invalid {
                field: "colour.scatter_pct",
                ..
            })
        ));
    }
}
