//! The Monte Carlo runs a cadence is judged by: probe sessions with a fault-free lamp, a
//! decay and a step, and the lamp's colour.

use super::*;

#[derive(Debug, Clone, Copy)]
pub(super) enum Scenario {
    FaultFree,
    Decay,
    /// Onset in regular captures.
    Step(u64),
}

/// One simulated run: the probe alarms, each with the regular capture count it came after.
pub(super) fn simulate(
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
        every: crate::detect::probes::ProbeEvery::Captures(every),
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
pub(super) struct LampChroma {
    anchor: [f64; 2],
    probes: Vec<[f64; 2]>,
}

pub(super) fn lamp_chroma(
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
pub(super) fn time_h(s: &ProbeSession, regular: u64, probes: u64) -> f64 {
    (regular as f64 * s.seconds_per_capture + probes as f64 * s.seconds_per_probe) / 3600.0
}

/// Whether a probe is taken once `regular` regular captures are in.
pub(super) fn probe_due(s: &ProbeSession, every: u64, regular: u64) -> bool {
    regular.is_multiple_of(every) && regular < s.captures && regular >= s.probes_from
}

/// One simulated run of the colour check on the probes (the lamp's luminance kept: the check
/// reads chromaticity only): the regular capture count after which `colour-drift` was first
/// raised, if it was before `horizon` regular captures.
pub(super) fn simulate_colour(
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
                light_az: [0.0; 2],
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
pub(super) fn step_after(
    events: &[(u64, DriftEvent)],
    onset: u64,
    target: &DetectionTarget,
) -> Option<u64> {
    let sign: i8 = if target.step_pct < 0.0 { -1 } else { 1 };
    events.iter().find_map(|(at, e)| match e {
        DriftEvent::Step { direction, .. } if *direction == sign && *at > onset => Some(at - onset),
        _ => None,
    })
}

pub(super) fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| crate::measure::stats::median_sorted(&v))
}
