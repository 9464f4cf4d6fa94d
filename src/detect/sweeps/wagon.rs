//! The wagon's backlash from the light sweeps.
//!
//! The wagon carries the camera along the arc; a lag `b` of its position against its last
//! direction of motion (play in the drive) moves each capture's camera by −b·dir. Within one
//! sweep the wagon moves both ways (the cameras of a light are not taken in one monotonic
//! pass), so the lag's pattern across the cameras, −dir·∂ln Y/∂w, is not that of any arm joint
//! nor that of a constant wagon offset, and the F + L + C reference, which averages both
//! directions, does not absorb it. The smooth model's fit of each sweep (joints, wagon offset
//! and lag together, `WagonFit`) gives the lag with its standard error; a one-sided CUSUM (a
//! lag, never a lead) of it, scaled by the robust scale of its θi layer's earlier lags (the
//! lower layer's, doubled, until the layer has `min_sweeps`), names the wagon once per run.
//!
//! The sweeps do not test a constant wagon offset: it moves ωo along the great circle through
//! both directions, as joint 1 moves both, and the reference absorbs most of it within a few
//! sweeps (benches/wagon_identifiability.py: the first three sweeps after a ±1° offset show it
//! at 2–5 standard errors, a joint-1 slip leaks into it by up to 1.5, and fault-free sweeps
//! scatter by 2.6), so the per-sweep `wagon` record carries its fit for the operator and the
//! lab. On a probe-taking rig a re-captured pair watches it (`wagon_watch`).

use super::level::PRIOR_SAFETY;
use super::model::SMOOTH_SE_MAX_DEG;
use super::*;

/// A θi layer's first sweeps, which the wagon test leaves out.
pub(super) const WAGON_LEARNING_SWEEPS: usize = 2;

impl SweepMonitor {
    /// Tests the wagon's lag in the sweep just completed, from its smooth-model fit `fit` (none
    /// when the model does not fit the sweep, or its lag's standard error is above
    /// `SMOOTH_SE_MAX_DEG`: a layer the model does not know yet). `hold` (the level test named
    /// a step or a joint in this sweep) feeds the CUSUM but names nothing: one alarm a sweep.
    /// Returns whether the wagon was named (the joints then name nothing in this sweep).
    pub(super) fn test_wagon(
        &mut self,
        sweep: &Sweep,
        fit: Option<WagonFit>,
        hold: bool,
        known: &Known,
        findings: &mut Vec<SweepFinding>,
    ) -> bool {
        let Some((b, se)) = fit
            .map(|f| (f.backlash_deg, f.backlash_se_deg))
            .filter(|(b, se)| b.is_finite() && *se > 0.0 && *se <= SMOOTH_SE_MAX_DEG)
        else {
            return false;
        };
        // a layer's first sweeps are the smooth model learning the layer (their lag is biased
        // either way by up to 2 standard errors on fault-free runs): neither judged nor history
        let in_layer = self
            .sweep_starts
            .iter()
            .filter(|s| s.layer == sweep.layer)
            .count();
        if in_layer <= WAGON_LEARNING_SWEEPS {
            return false;
        }
        let (k, clip) = (self.spec.cusum_k, self.spec.clip);
        let latched = self.latched.contains(&Latch::Wagon);
        let mut named = false;
        if let Some(nuisance) = self.wagon_scale(sweep.layer).filter(|_| !latched) {
            let scale = (se * se + nuisance * nuisance).sqrt();
            if scale > 0.0 {
                let z = (b / scale).clamp(-clip, clip);
                self.wagon_cusum.add(z, k, b, scale, sweep.last_idx);
                let run = self.wagon_cusum.up_run;
                let (mean, _) = run.mean_and_se();
                if !hold
                    && run.n > 0
                    && self.wagon_cusum.up > self.h_joint
                    && mean >= self.spec.joint_tolerance_deg
                {
                    let (size, size_se, estimate_sweeps) = self
                        .backlash_estimate(run.start, known)
                        .unwrap_or((mean, run.mean_and_se().1, run.n));
                    if size >= self.spec.joint_tolerance_deg {
                        self.latched.insert(Latch::Wagon);
                        let from_idx = self.slip_first_idx(run.start);
                        self.named_lag = Some(recapture::NamedLag {
                            backlash_deg: size,
                            from_idx,
                        });
                        findings.push(SweepFinding::WagonBacklash {
                            at: sweep.at(),
                            backlash: WagonBacklash {
                                backlash_deg: size,
                                se_deg: size_se,
                                estimate_sweeps,
                                run_mean_deg: mean,
                                offset_deg: fit.map_or(f64::NAN, |f| f.offset_deg),
                                sweeps: run.n,
                                since_idx: run.start,
                                from_idx,
                                statistic: self.wagon_cusum.up,
                                threshold: self.h_joint,
                                approach: None,
                            },
                        });
                        named = true;
                        self.wagon_cusum.reset();
                    }
                }
            }
        }
        let active = self.wagon_cusum.up > 0.0;
        self.wagon_history
            .entry(sweep.layer)
            .or_default()
            .record(b, active, named);
        named
    }

    /// The in-control scale of the lag in θi layer `layer`: its own history's once it has
    /// `min_sweeps` sweeps; before, the nearest lower layer's that has, times `PRIOR_SAFETY`
    /// (the lag's sweep-to-sweep scatter grows towards grazing: about 0.05° at θi = 30°, 0.07°
    /// at 45°, 0.12° at 60° and 0.23° at 75° on fault-free runs). `None` while neither has
    /// enough.
    fn wagon_scale(&self, layer: i64) -> Option<f64> {
        let enough = |h: &&ScaleHistory| h.len() >= self.spec.min_sweeps;
        if let Some(own) = self.wagon_history.get(&layer).filter(enough) {
            return Some(own.scale());
        }
        self.wagon_history
            .iter()
            .filter(|(l, h)| **l < layer && enough(h))
            .max_by_key(|(l, _)| **l)
            .map(|(_, h)| PRIOR_SAFETY * h.scale())
    }

    /// The lag's size: every sweep from the CUSUM run's first (`since`, its last capture) on,
    /// fitted again against the F + L + C reference of the captures taken before the sweep
    /// preceding it (the per-sweep fits are against a reference that already holds lagged
    /// captures, which takes part of the lag into its camera effects). The mean lag with its
    /// standard error and the sweeps behind it; `None` without a reference or a fit.
    fn backlash_estimate(&self, since: u64, known: &Known) -> Option<(f64, f64, usize)> {
        let cut = self.slip_first_idx(since);
        let in_reference =
            |c: &SweepCapture| c.idx < cut && self.completed.get(c.light).copied().unwrap_or(false);
        if !self.captures.iter().any(in_reference) {
            return None;
        }
        let reference = self.reference_before(cut, known);
        let fits: Vec<(f64, f64)> = self
            .sweep_starts
            .iter()
            .filter(|s| s.last_idx >= since)
            .filter_map(|s| {
                let current = self.captures_of_light(s.light);
                let (_, rows) = self.residuals(&current, &reference, known, Model::Smooth);
                let fit = self.pattern_fit(rows.iter().filter_map(Row::with_wagon).collect());
                let se = fit
                    .se(4)
                    .filter(|v| v.is_finite() && *v > 0.0 && *v <= SMOOTH_SE_MAX_DEG)?;
                fit.beta[4].is_finite().then_some((fit.beta[4], se))
            })
            .collect();
        if fits.is_empty() {
            return None;
        }
        let m = fits.len() as f64;
        let mean = fits.iter().map(|f| f.0).sum::<f64>() / m;
        let se = fits.iter().map(|f| f.1 * f.1).sum::<f64>().sqrt() / m;
        Some((mean, se, fits.len()))
    }
}
