//! Drift from probes: periodic re-captures of one reference pose (docs/protocol.md `PROBE`, off
//! unless the operator enables `[probes] every`). A probe and the original capture of its plan
//! entry share the geometry exactly, so ln(Y_probe / Y_original) is the gain change between the
//! two times with no geometric nuisance: the confounding that reciprocal pairs suffer (see
//! `measure::drift`) does not arise.
//!
//! Model: d(t) = a + r·(t − t₀) on the current segment (ordinary least squares; r in ln-gain per
//! hour). A rate alarm when |r| − z·SE(r) exceeds the tolerance (with hysteresis). A step alarm
//! when a new probe departs from the segment's prediction by more than `step_sigmas` residual
//! standard deviations and `step_pct`; the segment then restarts at that probe.

use super::drift::{DriftEstimate, DriftEvent};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSpec {
    /// Ask for a probe every this many checked captures; 0 = never (the default: probes move the
    /// rig, so the operator must enable them, and the rig may refuse).
    pub every: u64,
    /// The plan entry to re-capture (default: lamp at the pole, camera at 45°, azimuth 0: a
    /// diffuse geometry, far from the specular peak and from grazing).
    pub entry: Option<usize>,
    pub rate_tolerance_pct_per_h: f64,
    pub z: f64,
    /// Probes on a segment before its rate is judged.
    pub min_probes: usize,
    pub step_sigmas: f64,
    /// Smallest step reported (%).
    pub step_pct: f64,
}

impl Default for ProbeSpec {
    fn default() -> Self {
        ProbeSpec {
            every: 0,
            entry: None,
            rate_tolerance_pct_per_h: 0.25,
            z: 4.0,
            min_probes: 4,
            step_sigmas: 5.0,
            step_pct: 1.0,
        }
    }
}

#[derive(Debug, Clone)]
pub(crate) struct ProbeDrift {
    spec: ProbeSpec,
    /// (t in hours, ln ratio) of the current segment.
    segment: Vec<(f64, f64)>,
    rate_alarm: bool,
    estimate: Option<DriftEstimate>,
}

struct Fit {
    a: f64,
    r: f64,
    t0: f64,
    se: f64,
    sd: f64,
}

fn fit(points: &[(f64, f64)]) -> Option<Fit> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let t0 = points[0].0;
    let tm = points.iter().map(|p| p.0 - t0).sum::<f64>() / nf;
    let dm = points.iter().map(|p| p.1).sum::<f64>() / nf;
    let sxx: f64 = points.iter().map(|p| (p.0 - t0 - tm).powi(2)).sum();
    if !(sxx > 0.0) {
        return None;
    }
    let sxy: f64 = points.iter().map(|p| (p.0 - t0 - tm) * (p.1 - dm)).sum();
    let r = sxy / sxx;
    let a = dm - r * tm;
    let sse: f64 = points
        .iter()
        .map(|p| (p.1 - a - r * (p.0 - t0)).powi(2))
        .sum();
    let var = sse / (nf - 2.0);
    Some(Fit {
        a,
        r,
        t0,
        se: (var / sxx).sqrt(),
        sd: var.sqrt(),
    })
}

impl ProbeDrift {
    pub(crate) fn new(spec: ProbeSpec) -> Self {
        ProbeDrift {
            spec,
            segment: Vec::new(),
            rate_alarm: false,
            estimate: None,
        }
    }

    pub(crate) fn estimate(&self) -> Option<DriftEstimate> {
        self.estimate
    }

    /// The gain at `t_h` relative to the original capture of the probe pose, from the current
    /// segment's line (its level includes any step since the start), and its relative standard
    /// uncertainty (intercept and slope). None until the segment has three points.
    pub(crate) fn gain_at(&self, t_h: f64) -> Option<(f64, f64)> {
        let f = fit(&self.segment)?;
        let n = self.segment.len() as f64;
        let tm = self.segment.iter().map(|p| p.0).sum::<f64>() / n;
        let ln_g = f.a + f.r * (t_h - f.t0);
        let sigma = (f.sd * f.sd / n + (f.se * (t_h - tm)).powi(2)).sqrt();
        (ln_g.is_finite() && sigma.is_finite()).then(|| (ln_g.exp(), sigma))
    }

    /// One probe: its time and luminance, and the original capture's time and luminance.
    pub(crate) fn add(&mut self, t_orig_h: f64, y_orig: f64, t_h: f64, y: f64) -> Vec<DriftEvent> {
        let mut ev = Vec::new();
        if !(y_orig > 0.0 && y > 0.0 && t_h.is_finite() && t_orig_h.is_finite()) {
            return ev;
        }
        let d = (y / y_orig).ln();
        if self.segment.is_empty() {
            // the original capture anchors the first segment at ratio 1
            self.segment.push((t_orig_h, 0.0));
        }
        if self.segment.len() > self.spec.min_probes {
            if let Some(f) = fit(&self.segment) {
                let e = d - (f.a + f.r * (t_h - f.t0));
                let sd = f.sd.max(1e-4);
                if e.abs() > self.spec.step_sigmas * sd && e.abs() > self.spec.step_pct / 100.0 {
                    ev.push(DriftEvent::Step {
                        direction: if e > 0.0 { 1 } else { -1 },
                        statistic: e.abs() / sd,
                        threshold: self.spec.step_sigmas,
                        pairs_since_reset: self.segment.len(),
                    });
                    self.segment.clear();
                    self.rate_alarm = false;
                }
            }
        }
        self.segment.push((t_h, d));
        if let Some(f) = fit(&self.segment) {
            let est = DriftEstimate {
                pairs: self.segment.len() - 1,
                rate_pct_per_h: 100.0 * f.r,
                se_pct_per_h: 100.0 * f.se,
                residual_scale: f.sd,
            };
            self.estimate = Some(est);
            if self.segment.len() > self.spec.min_probes {
                let lower = est.rate_pct_per_h.abs() - self.spec.z * est.se_pct_per_h;
                let upper = est.rate_pct_per_h.abs() + self.spec.z * est.se_pct_per_h;
                if !self.rate_alarm && lower > self.spec.rate_tolerance_pct_per_h {
                    self.rate_alarm = true;
                    ev.push(DriftEvent::RateSignificant(est));
                } else if self.rate_alarm && upper < self.spec.rate_tolerance_pct_per_h {
                    self.rate_alarm = false;
                    ev.push(DriftEvent::RateCleared(est));
                }
            }
        }
        ev
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(
        rate_pct_h: f64,
        step: Option<(f64, f64)>,
        noise: f64,
        seed: u64,
    ) -> Vec<(f64, DriftEvent)> {
        let mut s = crate::fixtures::Lcg(seed);
        let mut g = move || (s.uniform() - 0.5) * 2.0 * noise;
        let gain = |t: f64| {
            let mut v = (1.0 - rate_pct_h / 100.0 * t).max(1e-6);
            if let Some((t0, f)) = step {
                if t >= t0 {
                    v *= 1.0 + f;
                }
            }
            v
        };
        let mut p = ProbeDrift::new(ProbeSpec {
            every: 100,
            ..ProbeSpec::default()
        });
        let y0 = 40.0 * gain(0.1) * (1.0 + g());
        let mut ev = Vec::new();
        // a probe every 100 captures of 7 s: every 0.194 h over 12.75 h
        let mut t = 0.3;
        while t < 12.75 {
            for e in p.add(0.1, y0, t, 40.0 * gain(t) * (1.0 + g())) {
                ev.push((t, e));
            }
            t += 100.0 * 7.0 / 3600.0;
        }
        ev
    }

    #[test]
    fn decay_of_1_percent_per_hour_is_found_early() {
        let ev = run(1.0, None, 0.002, 1);
        let (t, e) = ev
            .iter()
            .find(|(_, e)| matches!(e, DriftEvent::RateSignificant(_)))
            .unwrap();
        assert!(*t < 2.0, "alarm at {t} h");
        if let DriftEvent::RateSignificant(est) = e {
            assert!(est.rate_pct_per_h < -0.5, "{est:?}");
        }
    }

    #[test]
    fn no_alarm_without_drift() {
        for seed in 0..20 {
            assert!(run(0.0, None, 0.002, seed).is_empty(), "seed {seed}");
        }
    }

    #[test]
    fn a_three_percent_step_is_caught_at_the_next_probe() {
        let ev = run(0.0, Some((6.4, -0.03)), 0.002, 3);
        assert_eq!(ev.len(), 1, "{ev:?}");
        let (t, e) = &ev[0];
        assert!(*t >= 6.4 && *t < 6.4 + 0.2, "{t}");
        assert!(matches!(e, DriftEvent::Step { direction: -1, .. }));
    }
}
