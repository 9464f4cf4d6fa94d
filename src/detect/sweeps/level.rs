//! The level test: a sweep's level against the earlier sweeps of its θi layer.

use super::*;

/// The in-control history a statistic is scaled by. A value seen while its CUSUM has a run
/// under way is held back, so the sweeps of a developing fault do not inflate the scale they are
/// judged by; the held values join the history when the run dies out, are dropped when it ends
/// in an alarm, and join anyway once `HELD_MAX` have piled up (a lasting new normal).
#[derive(Debug, Clone, Default)]
pub(super) struct ScaleHistory {
    pub(super) values: Vec<f64>,
    pub(super) held: Vec<f64>,
}

pub(super) const HELD_MAX: usize = 8;

/// A θi layer's level is judged by its own scale history from this many sweeps on, by the
/// layer below's before (`SweepMonitor::prior_level_scale`).
pub(super) const OWN_SCALE_SWEEPS: usize = 4;
/// Sweeps a lower layer needs before its scale is lent to the layer above.
pub(super) const PRIOR_MIN_SWEEPS: usize = 4;
/// The lent scale's margin over the growth towards grazing (the footprint's pattern is not
/// exactly tan², and one lower layer's growth is a rough measure of the next one's).
pub(super) const PRIOR_SAFETY: f64 = 2.0;
/// The largest growth power the lent scale takes: the lamp footprint's tan²θi.
pub(super) const PRIOR_MAX_POWER: f64 = 2.0;

impl ScaleHistory {
    pub(super) fn len(&self) -> usize {
        self.values.len()
    }

    pub(super) fn scale(&self) -> f64 {
        robust_scale_about_zero(&self.values)
    }

    /// Records `v` after its CUSUM was updated: `active` when the CUSUM is above zero after it,
    /// `alarmed` when it raised an alarm.
    pub(super) fn record(&mut self, v: f64, active: bool, alarmed: bool) {
        if alarmed {
            self.held.clear();
        } else if active && self.held.len() < HELD_MAX {
            self.held.push(v);
        } else {
            self.values.append(&mut self.held);
            self.values.push(v);
        }
    }
}

impl SweepMonitor {
    /// The level against the earlier sweeps of the same θi layer: its CUSUM, and a gain step
    /// (once per sign and layer) when it crosses with a large enough mean and no joint's
    /// pattern explains it. `level` is the sweep's level less the layer pattern's prediction
    /// (ln units), with the level's standard error and the prediction's SD (`None` while the
    /// layer has no pattern model: `level` is then the raw level); `raw` is the level itself.
    pub(super) fn test_level(
        &mut self,
        sweep: &Sweep,
        (level, raw, level_se, pattern_sd): (f64, f64, f64, Option<f64>),
        known: &Known,
        rec: &mut SweepRecord,
        findings: &mut Vec<SweepFinding>,
    ) -> LevelStep {
        let (k, clip, layer) = (self.spec.cusum_k, self.spec.clip, sweep.layer);
        let mut step = LevelStep::default();
        let prior = self.prior_level_scale(layer, pattern_sd.is_some());
        let pattern_sd = pattern_sd.unwrap_or(0.0);
        let hist = self.level_history.entry(layer).or_default();
        let own = hist.len();
        // a layer's own scale once it has `OWN_SCALE_SWEEPS` sweeps; before, the smaller of its
        // own and the layer below's grown to this θi (`prior_level_scale`), and the latter alone
        // before `min_layer_sweeps`: a step in a layer's first sweeps would otherwise set the
        // scale it is judged by
        let base = if own >= OWN_SCALE_SWEEPS.max(self.spec.min_layer_sweeps) {
            Some(hist.scale())
        } else if own >= self.spec.min_layer_sweeps {
            Some(prior.map_or(hist.scale(), |p| p.min(hist.scale())))
        } else {
            prior
        };
        let mut tested = false;
        if let Some(base) = base.filter(|_| level_se.is_finite()) {
            tested = true;
            let scale = base.max(2.0 * level_se).max(pattern_sd).max(1e-3);
            let z = (level / scale).clamp(-clip, clip);
            rec.level_z = Some(z);
            self.level_cusum.add(z, k, level, scale, sweep.last_idx);
            let cs = &self.level_cusum;
            for (sign, stat, run) in [(1i8, cs.up, cs.up_run), (-1i8, cs.down, cs.down_run)] {
                let mean = if run.n > 0 {
                    run.sum / run.n as f64
                } else {
                    0.0
                };
                if stat > self.h_level
                    && 100.0 * f64::from(sign) * mean >= self.spec.level_tolerance_pct
                    && self.latched.insert(Latch::Level { sign, layer })
                {
                    let from_idx = self.sweep_first_idx(run.start);
                    // a tilt changes cos θi and the footprint over whole sweeps: a level change
                    // that begins after a slip named in this layer is attributed to the slip
                    // and is no lamp step for the drift model
                    if let Some((_, joint, slip_idx)) = self
                        .slip
                        .filter(|&(l, _, first)| l == layer && from_idx >= first)
                    {
                        findings.push(SweepFinding::LevelAfterSlip {
                            at: sweep.at(),
                            run: LevelRun {
                                level_pct: 100.0 * mean,
                                sweeps: run.n,
                                since_idx: run.start,
                                statistic: stat,
                                threshold: self.h_level,
                            },
                            joint,
                            slip_from_idx: slip_idx,
                        });
                        self.level_cusum.reset();
                        step.alarmed = true;
                        break;
                    }
                    // a tilt changes cos θi and the footprint as a lamp step would: the level is
                    // the lamp's only when no joint's pattern explains it (a layer that has named
                    // its slip keeps to one positioning alarm)
                    if let Some(x) = self
                        .attribute_level(layer, mean, run.start)
                        .filter(|_| !self.latched.contains(&Latch::Joint { layer }))
                    {
                        // named only when the slip's own size clears the tolerance (as a
                        // crossing of the joints' CUSUMs); otherwise the level is the lamp's
                        let x = self.slip_estimate(x, known);
                        if x.mean.abs() >= self.spec.joint_tolerance_deg {
                            let recapture = self.unasked();
                            step.slip = Some(self.name_slip(
                                sweep.at(),
                                &x,
                                &rec.joints,
                                recapture,
                                findings,
                            ));
                            self.level_cusum.reset();
                            step.alarmed = true;
                            break;
                        }
                    }
                    findings.push(SweepFinding::GainStep {
                        at: sweep.at(),
                        up: sign > 0,
                        run: LevelRun {
                            level_pct: 100.0 * mean,
                            sweeps: run.n,
                            since_idx: run.start,
                            statistic: stat,
                            threshold: self.h_level,
                        },
                        since_t: self.sweep_start(run.start),
                        // the drift model takes the step from the start of that sweep
                        from_idx: self.sweep_first_idx(run.start),
                    });
                    step.at_s = self.sweep_start(run.start);
                    self.level_steps
                        .push((layer, sweep.last_idx, step.at_s, 100.0 * mean));
                    self.level_cusum.reset();
                    step.alarmed = true;
                    break;
                }
            }
            rec.level_cusum = self.level_cusum.max();
        }
        let active = tested && self.level_cusum.max() > 0.0;
        if let Some(hist) = self.level_history.get_mut(&layer) {
            hist.record(level, active, step.alarmed);
        }
        self.raw_level_history
            .entry(layer)
            .or_default()
            .record(raw, active, step.alarmed);
        step
    }

    /// The level scale a θi layer with fewer than `OWN_SCALE_SWEEPS` sweeps is judged by: the
    /// robust scale of the nearest lower layer (θi ≥ 5°) with `PRIOR_MIN_SWEEPS` sweeps, grown
    /// to this θi and times `PRIOR_SAFETY`. The growth is (tan θi / tan θ_below)^p: p is
    /// measured from the two nearest such layers (how the session's own light-side effects grow
    /// towards grazing), at most `PRIOR_MAX_POWER` (the lamp footprint's tan² law), and the law
    /// itself while only one lower layer has a scale. `None` without such a layer.
    ///
    /// Like is judged by like: a layer whose levels are taken about its pattern model
    /// (`modelled`) by the lower layers' levels about theirs; a layer without one yet, whose
    /// levels still carry the light-side pattern's whole swing, by the lower layers' raw levels,
    /// pattern and all. (A pattern the lower layer's model removes would otherwise be missing
    /// from the scale of a layer where it is not yet removed, and its swing read as a step.)
    pub(super) fn prior_level_scale(&self, layer: i64, modelled: bool) -> Option<f64> {
        let histories = if modelled {
            &self.level_history
        } else {
            &self.raw_level_history
        };
        let mut lower: Vec<(i64, f64)> = histories
            .iter()
            .filter(|(&l, h)| l < layer && l >= 5000 && h.len() >= PRIOR_MIN_SWEEPS)
            .map(|(&l, h)| (l, h.scale()))
            .collect();
        lower.sort_by_key(|&(l, _)| std::cmp::Reverse(l));
        let tan = |l: i64| (l as f64 / 1000.0).to_radians().tan();
        let &(below, scale) = lower.first()?;
        let power = match lower.get(1) {
            Some(&(second, s2)) if s2 > 0.0 && scale > 0.0 => {
                ((scale / s2).ln() / (tan(below) / tan(second)).ln()).clamp(0.0, PRIOR_MAX_POWER)
            }
            _ => PRIOR_MAX_POWER,
        };
        let s = scale * (tan(layer) / tan(below)).powf(power) * PRIOR_SAFETY;
        (s.is_finite() && s > 0.0).then_some(s)
    }
}
