//! What reciprocal pairs alone can tell about the lamp's drift under an acquisition order: the
//! question for an anisotropic sample without probes, which has nothing else.
//!
//! A reciprocal pair, its earlier capture a = (light ℓ, camera c) at t_a and its mirror b at
//! t_b, gives d = ln Y′_b − ln Y′_a = ln g(t_b) − ln g(t_a) + v(c) − v(ℓ) + ε after the cosine
//! re-correction: a lamp footprint that depends on the light direction and what the camera
//! sees beside the sample make a per-direction non-reciprocity v (`detect::drift`). The drift
//! is identifiable from the pairs only as far as its columns are not in the span of the
//! direction effects. This module measures that: a linear rate's standard error, and a step's at
//! a given point of the run, with the 80 free direction effects fitted (one is fixed by the
//! others), per 1 % of pair noise. In light-outer order t_b − t_a = 80·(c − ℓ)·T is itself a
//! difference of per-direction terms, so the rate is not identifiable at all; a step is, from
//! the pairs that straddle it, as far as the direction effects leave it.

use crate::measure::plan::SamplingPlan;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// How well the pairs of one acquisition order identify the drift.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct PairIdentifiability {
    /// Standard error of a linear drift rate (%/h) from all the pairs of a run, per 1 % of pair
    /// noise; `None` when the order makes it indistinguishable from the direction effects.
    pub rate_se_pct_per_h: Option<f64>,
    /// Per step point (fraction of the run): the standard error of a step's size (%) per 1 % of
    /// pair noise, with the rate and the direction effects fitted; `None` where unidentifiable.
    pub step_se_pct: Vec<(f64, Option<f64>)>,
}

/// The design of a drift question over the pairs: the direction-effect columns of each pair
/// (+1 at the earlier capture's camera, −1 at its light; direction 0 fixed), kept sparse, and
/// any dense extra columns.
struct Design<'a> {
    /// Per pair: (camera column, light column), `None` for the fixed direction 0.
    dirs: &'a [(Option<usize>, Option<usize>)],
    n_dirs: usize,
    extra: Vec<&'a DVector<f64>>,
}

impl Design<'_> {
    /// Xᵀv for the design X.
    fn xt(&self, v: &DVector<f64>) -> DVector<f64> {
        let p = self.n_dirs + self.extra.len();
        let mut out = DVector::zeros(p);
        for (r, &(c, l)) in self.dirs.iter().enumerate() {
            if let Some(c) = c {
                out[c] += v[r];
            }
            if let Some(l) = l {
                out[l] -= v[r];
            }
        }
        for (k, e) in self.extra.iter().enumerate() {
            out[self.n_dirs + k] = e.dot(v);
        }
        out
    }

    /// XᵀX, built from the sparse rows in one pass.
    fn gram(&self) -> DMatrix<f64> {
        let p = self.n_dirs + self.extra.len();
        let mut g = DMatrix::zeros(p, p);
        for &(c, l) in self.dirs {
            if let Some(c) = c {
                g[(c, c)] += 1.0;
            }
            if let Some(l) = l {
                g[(l, l)] += 1.0;
            }
            if let (Some(c), Some(l)) = (c, l) {
                g[(c, l)] -= 1.0;
                g[(l, c)] -= 1.0;
            }
        }
        for (k, e) in self.extra.iter().enumerate() {
            let col = self.xt(e);
            for j in 0..p {
                g[(self.n_dirs + k, j)] = col[j];
                g[(j, self.n_dirs + k)] = col[j];
            }
        }
        g
    }

    /// For each column: the norm of its part the design cannot explain (least squares through
    /// the pseudo-inverse of XᵀX: the design may be rank-deficient, and in light-outer order it
    /// is, by construction), and the column's norm.
    fn residual_norms(&self, cols: &[DVector<f64>]) -> Vec<(f64, f64)> {
        let svd = self.gram().svd(true, true);
        let eps = 1e-9 * svd.singular_values.max();
        cols.iter()
            .map(|col| {
                let b = self.xt(col);
                let explained = svd.solve(&b, eps).map(|beta| beta.dot(&b)).unwrap_or(0.0);
                let total = col.dot(col);
                ((total - explained).max(0.0).sqrt(), total.sqrt())
            })
            .collect()
    }
}

/// Identifiability of the drift from the reciprocal pairs of `plan`, each capture at
/// `hours_of(index)` hours (its place in the acquisition order times the capture interval), a
/// step tested at each of `step_fractions` of the run.
pub(crate) fn pair_identifiability(
    plan: &SamplingPlan,
    hours_of: impl Fn(usize) -> f64,
    step_fractions: &[f64],
) -> PairIdentifiability {
    let n = plan.direction_count();
    let pairs: Vec<(f64, f64, usize, usize)> = plan
        .reciprocal_pairs()
        .into_iter()
        .filter_map(|(i, j)| {
            let (ti, tj) = (hours_of(i), hours_of(j));
            let (a, tb, ta) = if ti <= tj { (i, tj, ti) } else { (j, ti, tj) };
            let e = plan.entry(a).ok()?;
            Some((ta, tb, e.light, e.camera))
        })
        .collect();
    let m = pairs.len();
    let end = (0..plan.capture_count())
        .map(&hours_of)
        .fold(0.0_f64, f64::max);
    // direction effects: +1 at the earlier capture's camera, −1 at its light; direction 0 fixed
    let dirs: Vec<(Option<usize>, Option<usize>)> = pairs
        .iter()
        .map(|&(_, _, l, c)| (c.checked_sub(1), l.checked_sub(1)))
        .collect();
    let dt = DVector::from_iterator(m, pairs.iter().map(|p| p.1 - p.0));
    // a column is identifiable when more than 1e-4 of its norm is left after the projection
    // (through the Gram matrix a column in the span keeps only rounding, about 1e-8 of it)
    let identifiable = |(res, norm): (f64, f64)| (norm > 0.0 && res > 1e-4 * norm).then_some(res);
    let directions = Design {
        dirs: &dirs,
        n_dirs: n.saturating_sub(1),
        extra: Vec::new(),
    };
    // per 1 % of noise (0.01 in ln) a rate in ln/h has SE 0.01/‖r‖, i.e. 1/‖r‖ in %/h
    let rate_se_pct_per_h = directions
        .residual_norms(std::slice::from_ref(&dt))
        .first()
        .and_then(|r| identifiable(*r))
        .map(|r| 1.0 / r);
    let steps: Vec<DVector<f64>> = step_fractions
        .iter()
        .map(|&f| {
            let tau = f * end;
            DVector::from_iterator(
                m,
                pairs
                    .iter()
                    .map(|p| if p.0 < tau && tau <= p.1 { 1.0 } else { 0.0 }),
            )
        })
        .collect();
    let with_rate = Design {
        dirs: &dirs,
        n_dirs: n.saturating_sub(1),
        extra: vec![&dt],
    };
    let step_se_pct = step_fractions
        .iter()
        .zip(with_rate.residual_norms(&steps))
        .map(|(&f, r)| (f, identifiable(r).map(|r| 1.0 / r)))
        .collect();
    PairIdentifiability {
        rate_se_pct_per_h,
        step_se_pct,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::plan::{AcquisitionOrder, PlanSpec};

    fn plan(order: AcquisitionOrder) -> SamplingPlan {
        SamplingPlan::new(&PlanSpec {
            order,
            ..PlanSpec::default()
        })
        .unwrap()
    }

    const T_H: f64 = 7.0 / 3600.0;

    #[test]
    fn light_outer_and_camera_outer_cannot_see_a_rate_from_pairs_but_see_steps() {
        for order in [AcquisitionOrder::LightOuter, AcquisitionOrder::CameraOuter] {
            let p = plan(order);
            let id = pair_identifiability(&p, |i| i as f64 * T_H, &[0.25, 0.5, 0.75]);
            assert_eq!(id.rate_se_pct_per_h, None, "{order:?}");
            for (f, se) in &id.step_se_pct {
                let se = se.unwrap_or_else(|| panic!("{order:?}: a step at {f} unidentifiable"));
                // hundreds of pairs straddle a step, but the direction effects take most of
                // it (the gain in light-outer order is mostly a function of the light): the
                // step is not 1/√(pairs straddling it) = 0.025 at mid-run, but about 0.22
                assert!(se > 0.15 && se < 0.5, "{order:?} {f}: {se}");
            }
            let mid = id.step_se_pct[1].1.unwrap();
            assert!((mid - 0.225).abs() < 0.01, "{order:?}: {mid}");
        }
    }

    #[test]
    fn an_order_whose_pair_times_are_not_per_direction_identifies_the_rate() {
        // the serpentine order reverses every other camera sweep
        let p = plan(AcquisitionOrder::LightOuterSerpentine);
        let id = pair_identifiability(&p, |i| i as f64 * T_H, &[0.5]);
        let se = id.rate_se_pct_per_h.expect("identifiable");
        assert!(se > 0.0 && se.is_finite(), "{se}");
        // a light-outer order whose camera sweep starts at the light's own direction
        let lo = plan(AcquisitionOrder::LightOuter);
        let n = lo.direction_count();
        let rotated = |i: usize| {
            let e = lo.entry(i).unwrap();
            (e.light * n + (e.camera + n - e.light) % n) as f64 * T_H
        };
        let id = pair_identifiability(&lo, rotated, &[0.5]);
        assert!(id.rate_se_pct_per_h.is_some());
    }

    #[test]
    fn a_rate_is_recovered_when_the_time_is_not_a_direction_difference() {
        // a check of the projection itself: with times drawn from a hash the rate is easy
        let p = plan(AcquisitionOrder::LightOuter);
        let id = pair_identifiability(
            &p,
            |i| ((i as u64).wrapping_mul(2654435761) % 6561) as f64 * T_H,
            &[],
        );
        let se = id.rate_se_pct_per_h.unwrap();
        // 3,240 pairs with time differences of hours: far below 1 %/h per 1 % of noise
        assert!(se < 0.05, "{se}");
        assert!(id.step_se_pct.is_empty());
    }
}
