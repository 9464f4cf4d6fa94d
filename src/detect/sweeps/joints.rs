//! The joint tests: the sweeps' patterns across their cameras against each joint's
//! sensitivity, the naming of a slip, its size and where it began.

use super::model::{ATTRIBUTION_Z, SMOOTH_SE_MAX_DEG};
use super::recapture::{Hold, RECAPTURE_EXPECTED_Z};
use super::*;

/// The start of the most likely last segment of a mean shift of sign `sign` in equally scaled
/// `values`: the k that maximises sign · Σ_{i≥k} vᵢ / √(n − k) (the likelihood-ratio change
/// point). `None` for no values.
pub(super) fn change_point(values: &[f64], sign: f64) -> Option<usize> {
    (0..values.len())
        .map(|k| {
            let tail = &values[k..];
            (
                k,
                sign * tail.iter().sum::<f64>() / (tail.len() as f64).sqrt(),
            )
        })
        .filter(|(_, t)| t.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// Where an attributed slip is placed: a CUSUM run often begins a sweep or more before the
/// slip, so at the change point of the run's offsets (`(offset, se, sensitivity, last_idx)`,
/// less the in-control `centre`) in the direction of the departure `offset`; the run's start
/// without one. Placement only: the decision does not look at it.
pub(super) fn slip_start(run: &[(f64, f64, f64, u64)], centre: f64, offset: f64) -> u64 {
    let centred: Vec<f64> = run.iter().map(|v| v.0 - centre).collect();
    let k = change_point(&centred, offset.signum()).unwrap_or(0);
    run.get(k).or(run.first()).map_or(0, |v| v.3)
}

/// Without re-captures, a joint's pattern is a slip only when its CUSUM run departs from the
/// earlier sweeps of its own θi layer by this many standard errors (one-sided normal tail
/// 0.13 %, as `ATTRIBUTION_Z`): a pattern present since the layer began is as much the new
/// θi's geometry (a beam or holder that follows the pose) as a slip at its start.
pub(crate) const LAYER_CHANGE_Z: f64 = 3.0;

/// The inverse-variance weighted mean of (value, variance) pairs and its variance; None for
/// none.
fn weighted_mean(v: &[(f64, f64)]) -> Option<(f64, f64)> {
    let w: f64 = v.iter().map(|s| 1.0 / s.1).sum();
    let m = v.iter().map(|s| s.0 / s.1).sum::<f64>() / w;
    (w > 0.0 && m.is_finite()).then(|| (m, 1.0 / w))
}

impl LayerChange {
    /// Whether the run departs from the layer's earlier sweeps in the direction of `offset`.
    pub(super) fn shown(&self, offset: f64) -> bool {
        self.change_z
            .is_some_and(|z| z * offset.signum() >= LAYER_CHANGE_Z)
    }
}

impl SweepMonitor {
    /// Joint `x.joint`'s offsets (detection's fit) in the θi layer `layer`: the mean of the
    /// sweeps of the crossing's run (from `x.since`) against that of the layer's sweeps
    /// tested before it, each sweep weighted by the variance its CUSUM is scaled by (its
    /// standard error and the joint's sweep-to-sweep scale).
    pub(super) fn layer_change(&self, x: &JointCrossing, layer: i64) -> LayerChange {
        let j = x.joint;
        let nuisance = self.joint_history[j].scale();
        let (mut before, mut run) = (Vec::new(), Vec::new());
        for s in self.sweep_starts.iter().filter(|s| s.layer == layer) {
            let (b, se) = (s.offsets[j], s.offset_se[j]);
            if !(b.is_finite() && se.is_finite() && se > 0.0) {
                continue;
            }
            let v = (b, se * se + nuisance * nuisance);
            if s.last_idx < x.since {
                before.push(v);
            } else {
                run.push(v);
            }
        }
        let b = weighted_mean(&before);
        let change_z = b.zip(weighted_mean(&run)).and_then(|(b, r)| {
            let z = (r.0 - b.0) / (r.1 + b.1).sqrt();
            z.is_finite().then_some(z)
        });
        LayerChange {
            sweeps_before: before.len(),
            before: b.map(|(m, v)| (m, v.sqrt())),
            change_z,
        }
    }

    /// Joint `j`'s offset and its standard error in the captures of light `light` against
    /// `reference`: from the smooth model's sensitivities, the wagon's among them; where that
    /// fit is too loose (a θi layer with too few lights for the model to know its slope in θi),
    /// the interpolant's.
    fn refit(
        &self,
        light: usize,
        reference: &Reference,
        known: &Known,
        j: usize,
    ) -> Option<(f64, f64)> {
        let current = self.captures_of_light(light);
        let (_, rows) = self.residuals(&current, reference, known, Model::Smooth);
        let fit = self.pattern_fit(rows.iter().filter_map(Row::with_wagon).collect());
        let smooth = fit
            .se(j + 1)
            .filter(|v| v.is_finite() && *v > 0.0 && *v <= SMOOTH_SE_MAX_DEG)
            .map(|se| (fit.beta[j + 1], se));
        smooth.or_else(|| {
            let (_, rows) = self.residuals(&current, reference, known, Model::Interpolant);
            let fit = self.pattern_fit(rows.iter().map(Row::joints).collect());
            let se = fit.se(j + 1).filter(|v| v.is_finite() && *v > 0.0)?;
            Some((fit.beta[j + 1], se))
        })
    }

    /// What a slip named without re-captures says of them: the rig takes none, or none was
    /// asked.
    pub(super) fn unasked(&self) -> Recapture {
        if self.recapture.is_some() {
            Recapture::NotAsked
        } else {
            Recapture::NoProbes
        }
    }

    /// Joint `j`'s (0-based) fit in the sweep's pattern, untested (`z` none, no CUSUM), noted in
    /// the sweep's span; None where the fit gives no standard error.
    fn joint_fit(&mut self, pattern: &PatternFit, j: usize) -> Option<JointFit> {
        let b = pattern.beta[j + 1];
        let bse = pattern.se(j + 1).filter(|v| v.is_finite() && *v > 0.0)?;
        if let Some(span) = self.sweep_starts.last_mut() {
            span.offsets[j] = b;
            span.offset_se[j] = bse;
        }
        Some(JointFit {
            joint: j + 1,
            offset_deg: b,
            se_deg: bse,
            z: None,
            cusum: 0.0,
        })
    }

    /// The sweep's joint fits, recorded untested: the lamp is unstable.
    pub(super) fn record_joint_fits(&mut self, pattern: &PatternFit, rec: &mut SweepRecord) {
        for j in 0..2 {
            rec.joints.extend(self.joint_fit(pattern, j));
        }
    }

    /// The joints: both CUSUMs are updated first; when one or both cross, the alarm names the
    /// joint with the larger statistic (one positioning alarm per θi layer). A sweep whose level
    /// stepped (`level_alarmed`: a lamp step part-way through it looks like a pattern across its
    /// cameras) raises no positioning alarm; the CUSUMs carry on, so a real offset is named at
    /// the next sweep. When it names a joint: the time the slip is placed at (seconds), and
    /// the earlier gain steps of its layer raised after the slip's first capture, which the
    /// slip explains (each withdrawn with an info alarm; their step terms, in seconds).
    pub(super) fn test_joints(
        &mut self,
        sweep: &Sweep,
        pattern: &PatternFit,
        level_alarmed: bool,
        known: &Known,
        rec: &mut SweepRecord,
        findings: &mut Vec<SweepFinding>,
    ) -> Option<NamedSlip> {
        let (k, clip) = (self.spec.cusum_k, self.spec.clip);
        let mut crossing: Option<JointCrossing> = None;
        for j in 0..2 {
            let Some(mut fit) = self.joint_fit(pattern, j) else {
                continue;
            };
            let (b, bse) = (fit.offset_deg, fit.se_deg);
            let hist = &self.joint_history[j];
            if hist.len() >= self.spec.min_sweeps {
                let nuisance = hist.scale();
                let scale = (bse * bse + nuisance * nuisance).sqrt();
                if scale > 0.0 {
                    let z = (b / scale).clamp(-clip, clip);
                    fit.z = Some(z);
                    self.joint_cusum[j].add(z, k, b, scale, sweep.last_idx);
                    let cs = &self.joint_cusum[j];
                    for (sign, stat, run) in [(1.0, cs.up, cs.up_run), (-1.0, cs.down, cs.down_run)]
                    {
                        if run.n == 0 {
                            continue;
                        }
                        let (mean, mean_se) = run.mean_and_se();
                        if stat > self.h_joint
                            && sign * mean >= self.spec.joint_tolerance_deg
                            && crossing.is_none_or(|c| stat > c.statistic)
                        {
                            crossing = Some(JointCrossing {
                                joint: j,
                                statistic: stat,
                                mean,
                                mean_se,
                                sweeps: run.n,
                                since: run.start,
                                estimate_sweeps: run.n,
                                run_mean: mean,
                                attributed_level: None,
                            });
                        }
                    }
                    fit.cusum = cs.max();
                }
            }
            rec.joints.push(fit);
        }
        // the crossing names a slip only when the slip's own size, fitted against a reference
        // that holds none of its sweeps, clears the tolerance too: a pattern the detection
        // interpolant leaves across the cameras (a light pattern that follows the whole pose)
        // can drive the CUSUM while the refit finds no tilt; the CUSUMs carry on meanwhile
        let crossing = if level_alarmed {
            None
        } else {
            crossing
                .map(|x| self.slip_estimate(x, known))
                .filter(|x| x.mean.abs() >= self.spec.joint_tolerance_deg)
        };
        // a crossing in a layer that already has its positioning alarm restarts the CUSUMs
        // without a second alarm (the operator has it; the next layer may raise one again)
        // on a probe-taking rig the slip waits for a re-capture of earlier poses (`recapture`);
        // while one waits, no other is asked about
        // a pattern too small for the re-captures to check is not named: the sweeps alone
        // cannot tell it from the geometry's (`recapture`)
        let mut named = None;
        if let Some(x) = &crossing {
            if !self.latched.contains(&Latch::Joint { layer: sweep.layer })
                && !self.recapture_pending()
            {
                match self.hold_for_recapture(sweep.at(), x, &rec.joints) {
                    Hold::Held => {}
                    // without re-captures, the evidence of a slip is a change within its layer
                    Hold::NotAsked if self.recapture.is_none() => {
                        let change = self.layer_change(x, sweep.layer);
                        if change.shown(x.mean) {
                            named = Some(self.name_slip(
                                sweep.at(),
                                x,
                                &rec.joints,
                                Recapture::NoProbes,
                                findings,
                            ));
                        } else if self.unresolved.insert(sweep.layer) {
                            findings.push(SweepFinding::SlipUnresolved {
                                at: sweep.at(),
                                joint: x.joint + 1,
                                offset_deg: x.mean,
                                change,
                            });
                        }
                    }
                    Hold::NotAsked => {
                        let recapture = self.unasked();
                        named =
                            Some(self.name_slip(sweep.at(), x, &rec.joints, recapture, findings));
                    }
                    Hold::Unverifiable { z_per_deg } => {
                        if self.unverifiable.insert(sweep.layer) {
                            findings.push(SweepFinding::SlipUnverifiable {
                                at: sweep.at(),
                                joint: x.joint + 1,
                                offset_deg: x.mean,
                                checkable_deg: RECAPTURE_EXPECTED_Z / z_per_deg,
                            });
                        }
                    }
                }
            }
            for c in self.joint_cusum.iter_mut() {
                c.reset();
            }
            for f in rec.joints.iter_mut() {
                f.cusum = 0.0;
            }
        }
        for f in &rec.joints {
            let j = f.joint - 1;
            let active = f.z.is_some() && self.joint_cusum[j].max() > 0.0;
            self.joint_history[j].record(f.offset_deg, active, crossing.is_some());
        }
        named
    }

    /// Names the slip `x` found at the sweep `at` (its layer's one positioning alarm), with the
    /// sweep's joint fits `fits` and what re-captures said of it: the alarm, the slip's place
    /// for the drift model, and the withdrawal of the gain steps of its layer raised after the
    /// slip's first capture, which the slip explains (each with an info alarm).
    pub(super) fn name_slip(
        &mut self,
        at: SweepAt,
        x: &JointCrossing,
        fits: &[JointFit],
        recapture: Recapture,
        findings: &mut Vec<SweepFinding>,
    ) -> NamedSlip {
        let layer = at.layer_mdeg;
        self.latched.insert(Latch::Joint { layer });
        findings.push(SweepFinding::JointSlip {
            at,
            slip: self.joint_slip(x, fits, recapture),
        });
        let at_s = self.slip_first_t(x.since);
        let slip_idx = self.slip_first_idx(x.since);
        self.slip = Some((layer, x.joint + 1, slip_idx));
        // a level change raised after the slip began, in its layer, was the tilt's
        let (explained, kept): (Vec<_>, Vec<_>) = self
            .level_steps
            .iter()
            .partition(|&&(l, idx, _, _)| l == layer && idx >= slip_idx);
        self.level_steps = kept;
        let mut withdrawn_steps_s = Vec::new();
        for (_, idx, step_at_s, level) in explained {
            findings.push(SweepFinding::GainStepWithdrawn {
                at,
                joint: x.joint + 1,
                step_idx: idx,
                level_pct: level,
                slip_from_idx: slip_idx,
            });
            withdrawn_steps_s.extend(step_at_s);
        }
        for c in self.joint_cusum.iter_mut() {
            c.reset();
        }
        self.wagon_watch.restart();
        NamedSlip {
            at_s,
            withdrawn_steps_s,
        }
    }

    /// The smooth model's fit of the sweep just completed (the last span): each joint's offset
    /// with its standard error, and the mean sensitivity. Kept for `attribute_level`. Returns
    /// the wagon's fit of the same sweep (the joints, the wagon and its backlash together).
    pub(super) fn smooth_offsets(
        &mut self,
        sweep: &Sweep,
        reference: &Reference,
        known: &Known,
    ) -> Option<WagonFit> {
        let (_, rows) = self.residuals(&sweep.current, reference, known, Model::Smooth);
        if rows.len() < self.spec.min_captures {
            return None;
        }
        let n = rows.len() as f64;
        let fit = self.pattern_fit(rows.iter().map(Row::joints).collect());
        let mut smooth = [(f64::NAN, f64::NAN); 2];
        let mut smooth_s = [f64::NAN; 2];
        for j in 0..2 {
            if let Some(se) = fit.se(j + 1).filter(|v| v.is_finite() && *v > 0.0) {
                smooth[j] = (fit.beta[j + 1], se);
            }
            smooth_s[j] = rows.iter().map(|r| r.s[j]).sum::<f64>() / n;
        }
        if let Some(span) = self.sweep_starts.last_mut() {
            span.smooth = smooth;
            span.smooth_s = smooth_s;
        }
        let fit = self.pattern_fit(rows.iter().filter_map(Row::with_wagon).collect());
        let inv = fit.inv.as_ref()?;
        let (w, b) = (fit.se(3)?, fit.se(4)?);
        if let Some(span) = self.sweep_starts.last_mut() {
            span.wagon_offset = (fit.beta[3], w);
        }
        let corr = inv[(1, 3)] / (inv[(1, 1)] * inv[(3, 3)]).sqrt();
        [fit.beta[3], w, fit.beta[4], b, corr]
            .iter()
            .all(|v| v.is_finite())
            .then_some(WagonFit {
                offset_deg: fit.beta[3],
                offset_se_deg: w,
                backlash_deg: fit.beta[4],
                backlash_se_deg: b,
                corr_joint1: corr,
            })
    }

    /// Whether the level change of mean `level` (ln units) in θi layer `layer`, over the sweeps
    /// from capture `since` on, is a joint's tilt. Each joint's smooth-model offset over those
    /// sweeps but the first is compared with the layer's earlier sweeps (or every earlier sweep while the
    /// layer has fewer than `min_sweeps`): its median is the in-control offset and its robust
    /// scale the nuisance. The tilt that would make the level is the level over the sweeps'
    /// mean sensitivity. A joint whose departure points the same way, by `ATTRIBUTION_Z` and
    /// the joint tolerance, takes the level (the larger departure of the two). Only sweeps
    /// whose smooth fit is within `SMOOTH_SE_MAX_DEG` count, so a layer the model does not know
    /// yet attributes nothing. A lamp step leaves the joints' offsets where they were.
    pub(super) fn attribute_level(
        &self,
        layer: i64,
        level: f64,
        since: u64,
    ) -> Option<JointCrossing> {
        let usable = |v: (f64, f64)| v.0.is_finite() && v.1 > 0.0 && v.1 <= SMOOTH_SE_MAX_DEG;
        let mut best: Option<JointCrossing> = None;
        for j in 0..2 {
            // the crossing's first sweep is left out: a lamp step part-way through a sweep
            // splits its cameras into two levels, a pattern across them that a joint's
            // sensitivity can follow (so a crossing of a single sweep stays the lamp's)
            let run: Vec<(f64, f64, f64, u64)> = self
                .sweep_starts
                .iter()
                .filter(|s| s.last_idx >= since && usable(s.smooth[j]))
                .map(|s| (s.smooth[j].0, s.smooth[j].1, s.smooth_s[j], s.last_idx))
                .skip(1)
                .collect();
            if run.is_empty() {
                continue;
            }
            let earlier = |same_layer: bool| -> Vec<f64> {
                let mut v: Vec<f64> = self
                    .sweep_starts
                    .iter()
                    .filter(|s| s.last_idx < since && usable(s.smooth[j]))
                    .filter(|s| !same_layer || s.layer == layer)
                    .map(|s| s.smooth[j].0)
                    .collect();
                v.sort_by(f64::total_cmp);
                v
            };
            let mut before = earlier(true);
            if before.len() < self.spec.min_sweeps {
                before = earlier(false);
            }
            if before.len() < self.spec.min_sweeps {
                continue;
            }
            let centre = median_sorted(&before);
            let centred: Vec<f64> = before.iter().map(|v| v - centre).collect();
            let nuisance = robust_scale_about_zero(&centred);
            // the decision rests on every sweep of the crossing, as the level's did: judged from
            // a change point picked for its departure, a lone nuisance sweep would pass
            let n = run.len() as f64;
            let offset = run.iter().map(|v| v.0).sum::<f64>() / n - centre;
            let se = run.iter().map(|v| v.1 * v.1).sum::<f64>().sqrt() / n;
            let sensitivity = run.iter().map(|v| v.2).sum::<f64>() / n;
            let implied = level / sensitivity;
            let z = offset.abs() / (se * se + nuisance * nuisance).sqrt();
            if implied.is_finite()
                && implied * offset > 0.0
                && z >= ATTRIBUTION_Z
                && offset.abs() >= self.spec.joint_tolerance_deg
                && best.is_none_or(|b| z > b.statistic)
            {
                best = Some(JointCrossing {
                    joint: j,
                    statistic: z,
                    mean: offset,
                    mean_se: se,
                    sweeps: run.len(),
                    since: slip_start(&run, centre, offset),
                    estimate_sweeps: run.len(),
                    run_mean: offset,
                    attributed_level: Some(level),
                });
            }
        }
        best
    }

    /// The slip's size from the sweeps that show it, each against a reference that holds none
    /// of them. The CUSUM run's own mean underestimates it twice over: a run starts at the first
    /// positive excursion, often a sweep or two before the slip, and each of its later sweeps is
    /// compared with class effects F that already average in the slipped captures before it
    /// (a class's first members after the slip hide it completely). So the run is cut at its
    /// change point (`change_point` on the sweeps' offsets), and every sweep from there on is
    /// fitted again against the F + L + C reference of the captures taken before the sweep
    /// preceding the change point (`slip_first_idx`); the estimate is the mean of those fits
    /// from their own change point. Where no refit is possible (too few captures with a class
    /// member before the cut) it is the mean of the run's own offsets from their change point.
    /// Detection is unchanged: only the alarm's size and its standard error come from here.
    pub(super) fn slip_estimate(&self, mut x: JointCrossing, known: &Known) -> JointCrossing {
        let j = x.joint;
        let sign = if x.mean < 0.0 { -1.0 } else { 1.0 };
        // the offsets the crossing was found in: detection's, or for an attributed level the
        // smooth model's
        let offset = |s: &SweepSpan| match x.attributed_level {
            Some(_) if s.smooth[j].1 <= SMOOTH_SE_MAX_DEG => s.smooth[j].0,
            Some(_) => f64::NAN,
            None => s.offsets[j],
        };
        let run: Vec<SweepSpan> = self
            .sweep_starts
            .iter()
            .filter(|s| s.last_idx >= x.since && offset(s).is_finite())
            .copied()
            .collect();
        let values: Vec<f64> = run.iter().map(offset).collect();
        let Some(k) = change_point(&values, sign) else {
            return x;
        };
        let mean_of = |v: &[(f64, f64)]| {
            let m = v.len() as f64;
            (
                v.iter().map(|r| r.0).sum::<f64>() / m,
                v.iter().map(|r| r.1 * r.1).sum::<f64>().sqrt() / m,
            )
        };
        // the sweep taken before the change point may hold the slip's start without showing it
        // (`slip_first_idx`), so the reference stops before it too
        let reference = self.reference_before(self.slip_first_idx(run[k].last_idx), known);
        let refits: Vec<(f64, f64)> = run[k..]
            .iter()
            .filter_map(|s| self.refit(s.light, &reference, known, j))
            .collect();
        let refitted: Vec<f64> = refits.iter().map(|r| r.0).collect();
        let (used, se_fallback) = match change_point(&refitted, sign) {
            Some(k2) => (refits[k2..].to_vec(), None),
            None => (
                values[k..].iter().map(|&v| (v, 0.0)).collect(),
                Some(x.mean_se),
            ),
        };
        let (mean, se) = mean_of(&used);
        if mean.is_finite() && sign * mean > 0.0 {
            x.mean = mean;
            x.mean_se = se_fallback.unwrap_or(se);
            x.estimate_sweeps = used.len();
        }
        x
    }

    /// The slip `x` names, with the other joints' fits of the sweep (from `fits`).
    pub(super) fn joint_slip(
        &self,
        x: &JointCrossing,
        fits: &[JointFit],
        recapture: Recapture,
    ) -> JointSlip {
        JointSlip {
            joint: x.joint + 1,
            offset_deg: x.mean,
            se_deg: x.mean_se,
            estimate_sweeps: x.estimate_sweeps,
            run_mean_deg: x.run_mean,
            sweeps: x.sweeps,
            since_idx: x.since,
            from_idx: self.slip_first_idx(x.since),
            statistic: x.statistic,
            threshold: if x.attributed_level.is_some() {
                ATTRIBUTION_Z
            } else {
                self.h_joint
            },
            attributed_level_pct: x.attributed_level.map(|level| 100.0 * level),
            other_joints: fits
                .iter()
                .filter(|f| f.joint != x.joint + 1)
                .cloned()
                .collect(),
            recapture,
            axis: None,
        }
    }
}
