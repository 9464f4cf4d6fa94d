//! The level test: a sweep's level against the earlier sweeps of its θi layer.

use super::model::{pattern_fit, pattern_row, PatternColumns, PATTERN_SAMPLES_PER_PERIOD};
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

/// A level crossing is the light-side pattern's, not yet a step, when the θi layer below departs
/// from its own azimuthal pattern at the run's light azimuths in the run's direction by this
/// many standard errors, and by enough that growing at the lamp footprint's tan² law
/// (`PRIOR_MAX_POWER`) it reaches the run's mean level.
pub(crate) const PATTERN_BELOW_Z: f64 = 3.0;

impl PatternBelow {
    /// Whether the layer below accounts for a run of mean level `mean` (ln units) that moved
    /// `up` or down.
    pub(super) fn explains(&self, up: bool, mean: f64) -> bool {
        let sign = if up { 1.0 } else { -1.0 };
        let departure = sign * self.departure;
        departure >= PATTERN_BELOW_Z * self.se && departure * self.growth >= sign * mean
    }
}

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
        reference: &Reference,
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
                    && !self.latched.contains(&Latch::Level { sign, layer })
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
                    // a level the layer below's departure from its own pattern at the same light
                    // azimuths accounts for is as much a stationary light-side pattern grown
                    // towards grazing (a holder's shadow, a bowed sample) as a lamp step: no
                    // alarm, and the CUSUM runs on, so the step is raised once the run reaches
                    // azimuths where the layer below does not account for it
                    let run_level = LevelRun {
                        level_pct: 100.0 * mean,
                        sweeps: run.n,
                        since_idx: run.start,
                        statistic: stat,
                        threshold: self.h_level,
                    };
                    if let Some(below) = self
                        .pattern_below(sweep, reference, run.start)
                        .filter(|b| b.explains(sign > 0, mean))
                    {
                        if self.latched.insert(Latch::LevelUnresolved { sign, layer }) {
                            findings.push(SweepFinding::StepUnresolved {
                                at: sweep.at(),
                                up: sign > 0,
                                run: run_level,
                                below,
                            });
                        }
                        continue;
                    }
                    self.latched.insert(Latch::Level { sign, layer });
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

    /// The θi layer right below the sweep's, put through the test this layer's level CUSUM run
    /// went through (the run began with the sweep ending at `run_start`): for each of the run's
    /// sweeps, the layer below's light effects (the same back-fit as the level) interpolated
    /// linearly round the turn to that sweep's light azimuth, less the layer pattern that
    /// sweep's level was taken about (the same columns) fitted to the layer below's effects
    /// interpolated to this layer's lights before it; averaged over the run. With its standard
    /// error from the layer below's level standard errors and the growth to this θi at the
    /// lamp footprint's law. A stationary light-side pattern of the sample frame (any smooth
    /// function of the light's direction) that the pattern misses leaves the same departure
    /// there first, smaller; a lamp step leaves none. `None` without a lower layer of four
    /// lights with a level, or where a run sweep's pattern cannot be fitted to it.
    pub(super) fn pattern_below(
        &self,
        sweep: &Sweep,
        r: &Reference,
        run_start: u64,
    ) -> Option<PatternBelow> {
        let below = sweep
            .past
            .iter()
            .map(|&k| self.captures[k].layer)
            .filter(|&l| l < sweep.layer && l >= 5000)
            .max()?;
        let phi = |l: usize| {
            self.light_phi
                .get(l)
                .map_or(f64::NAN, |p| p.rem_euclid(TAU))
        };
        let span_of = |l: usize| self.sweep_starts.iter().rev().find(|s| s.light == l);
        // the layer below's lights with a level: azimuth, effect, level standard error
        let (lights, step) = self.layer_lights(sweep, below, r);
        let mut points: Vec<(f64, f64, f64)> = lights
            .iter()
            .filter_map(|&l| {
                let (a, v) = (phi(l), r.light[l]);
                let se = span_of(l).map_or(f64::NAN, |s| s.level_se);
                (a.is_finite() && v.is_finite() && se.is_finite()).then_some((a, v, se))
            })
            .collect();
        points.sort_by(|x, y| x.0.total_cmp(&y.0));
        let n = points.len();
        if n < 4 {
            return None;
        }
        // each light's own noise: its level's standard error, or the layer's light-to-light
        // scatter that is no smooth pattern if larger (a per-light nuisance such as the lamp's
        // footprint moving between sweeps): half the mean square difference of neighbours'
        // departures from the layer's whole pattern, round the turn (Rice's difference
        // estimator; a smooth pattern differs little between neighbours)
        let harmonics: Vec<f64> = [4.0, 2.0]
            .into_iter()
            .filter(|h| TAU / h >= PATTERN_SAMPLES_PER_PERIOD * step)
            .collect();
        let whole = PatternColumns::new(&harmonics, None);
        if n > whole.count() + 1 {
            let azimuths: Vec<f64> = points.iter().map(|p| p.0).collect();
            let values: Vec<f64> = points.iter().map(|p| p.1).collect();
            if let Some(fit) = pattern_fit(&azimuths, &values, whole.harmonics(), None, 0.0) {
                let d: Vec<f64> = points
                    .iter()
                    .map(|p| {
                        let x = pattern_row(p.0, whole.harmonics(), None);
                        p.1 - x
                            .iter()
                            .zip(fit.coef.iter())
                            .map(|(x, b)| x * b)
                            .sum::<f64>()
                    })
                    .collect();
                let rice =
                    (0..n).map(|i| (d[(i + 1) % n] - d[i]).powi(2)).sum::<f64>() / (2 * n) as f64;
                if rice.is_finite() {
                    for p in points.iter_mut() {
                        p.2 = p.2.max(rice.sqrt());
                    }
                }
            }
        }
        // the weights of the layer below's lights in its value at azimuth `a`
        let interpolate = |a: f64| -> DVector<f64> {
            let mut w = DVector::zeros(n);
            let j = points.iter().rposition(|p| p.0 <= a).unwrap_or(n - 1);
            let k = (j + 1) % n;
            let gap = (points[k].0 - points[j].0).rem_euclid(TAU);
            let t = if gap > 1e-9 {
                ((a - points[j].0).rem_euclid(TAU) / gap).clamp(0.0, 1.0)
            } else {
                0.0
            };
            w[j] += 1.0 - t;
            w[k] += t;
            w
        };
        // this layer's sweeps in completion order: light azimuth, last capture, pattern
        let layer: Vec<(f64, u64, Option<PatternColumns>)> = self
            .sweep_starts
            .iter()
            .filter(|s| s.layer == sweep.layer && phi(s.light).is_finite())
            .map(|s| (phi(s.light), s.last_idx, s.pattern))
            .collect();
        let run: Vec<usize> = (0..layer.len())
            .filter(|&i| layer[i].1 >= run_start)
            .collect();
        if run.is_empty() {
            return None;
        }
        let share = 1.0 / run.len() as f64;
        let mut weight = DVector::<f64>::zeros(n);
        for &i in &run {
            let (a, _, columns) = layer[i];
            let columns = columns.unwrap_or_default();
            let before: Vec<f64> = layer[..i].iter().map(|x| x.0).collect();
            let cols = columns.count();
            if before.len() < cols {
                return None;
            }
            // the pattern's prediction at `a` from the values at `before`: x₀ᵀ(XᵀX)⁺Xᵀ
            let x = DMatrix::from_fn(before.len(), cols, |row, col| {
                pattern_row(before[row], columns.harmonics(), columns.borrowed)[col]
            });
            let x0 = DVector::from_vec(pattern_row(a, columns.harmonics(), columns.borrowed));
            let hat = (x.transpose() * &x).pseudo_inverse(1e-12).ok()? * x.transpose();
            let predict = hat.transpose() * x0;
            weight += interpolate(a) * share;
            for (b, p) in before.iter().zip(predict.iter()) {
                weight -= interpolate(*b) * (p * share);
            }
        }
        let departure: f64 = weight.iter().zip(&points).map(|(w, p)| w * p.1).sum();
        let se = weight
            .iter()
            .zip(&points)
            .map(|(w, p)| (w * p.2).powi(2))
            .sum::<f64>()
            .sqrt();
        let tan = |l: i64| (l as f64 / 1000.0).to_radians().tan();
        let growth = (tan(sweep.layer) / tan(below)).powf(PRIOR_MAX_POWER);
        (departure.is_finite() && se.is_finite() && growth.is_finite()).then_some(PatternBelow {
            below_deg: below as f64 / 1000.0,
            departure,
            se,
            growth,
        })
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
