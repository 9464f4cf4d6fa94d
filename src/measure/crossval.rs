//! Cross-validation against an uncalibrated reference (the paper's Section 6.2): the least-squares
//! 3×3 colour transform T with T·v ≈ w, and the Table 3 statistics of the colour differences.
//! `cross_validate` resamples the reference at the session's capture directions (the layered
//! resampler of `measure::resample`), fits T, and gives Table 3 with and without the gain
//! correction of a drift estimate.
//!
//! T is found row by row from the n×3 least-squares system V·tₖ = wₖ with an SVD (never the
//! normal equations' inverse) of V with its columns scaled to unit norm: a channel that reads on
//! another scale changes T's column by the inverse factor but not how well T is determined, so
//! the scaled matrix's condition number decides. Near-grey data (all colours almost proportional
//! to one another, so V is nearly rank 1) make it large, which the result flags; both it and the
//! raw κ(V) are reported. The paper shows channel weights aₖ leave T unchanged (each row is its
//! own problem); `fit_transform_weighted` exists to test exactly that.

use super::colour::{colour_difference, White, Xyz};
use super::geometry::{Spherical, Vec3};
use super::resample::LayeredResampler;
use nalgebra::{DMatrix, DVector, Matrix3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum CrossValError {
    #[error("need at least 3 colour pairs, got {0}")]
    TooFewPairs(usize),
    #[error("the two colour lists differ in length ({0} vs {1})")]
    LengthMismatch(usize, usize),
    #[error("colour pair {0} is not finite")]
    NotFinite(usize),
    /// Carries the condition number of the column-scaled V (infinite for a zero column).
    #[error("the reference colours are (numerically) rank-deficient: no unique transform (condition number {0:.3e} with the channels scaled to unit norm)")]
    Singular(f64),
    #[error("channel weights must be finite and positive, got {0:?}")]
    BadWeights([f64; 3]),
}

/// Above this condition number of the column-scaled V the fit is flagged as ill-conditioned
/// (near-grey data).
pub(crate) const ILL_CONDITIONED: f64 = 1e3;
/// At or above this condition number of the column-scaled V the fit is refused as singular.
pub(crate) const SINGULAR: f64 = 1e12;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(from = "ColourTransformFields")]
pub struct ColourTransform {
    /// Row-major T.
    pub t: [[f64; 3]; 3],
    /// Condition number of the reference colour matrix V (σ_max / σ_min) as the data come, the
    /// channels' scales included; `f64::MAX` when it exceeds the double range (JSON has no
    /// infinity).
    pub condition: f64,
    /// Condition number of V with each column divided by its norm: how well T is determined,
    /// whatever scale each channel reads on. This one decides `ill_conditioned` and the refusal.
    pub condition_scaled: f64,
    /// RMS of |T·v − w| over the pairs.
    pub rms_residual: f64,
    /// `condition_scaled > ILL_CONDITIONED`: the data are close to grey and T is poorly
    /// determined.
    pub ill_conditioned: bool,
}

/// The serialised form as read: files written before `condition_scaled` existed lack it, and
/// their `ill_conditioned` was decided on the raw condition number, so that stands in for it.
#[derive(Deserialize)]
struct ColourTransformFields {
    t: [[f64; 3]; 3],
    condition: f64,
    #[serde(default)]
    condition_scaled: Option<f64>,
    rms_residual: f64,
    ill_conditioned: bool,
}

impl From<ColourTransformFields> for ColourTransform {
    fn from(f: ColourTransformFields) -> Self {
        ColourTransform {
            t: f.t,
            condition: f.condition,
            condition_scaled: f.condition_scaled.unwrap_or(f.condition),
            rms_residual: f.rms_residual,
            ill_conditioned: f.ill_conditioned,
        }
    }
}

/// σ_max / σ_min, infinite when σ_min is 0 (or the values are not finite).
fn condition_of(singular_values: &DVector<f64>) -> f64 {
    let smax = singular_values.max();
    let smin = singular_values.min();
    let k = smax / smin;
    if smin > 0.0 && k.is_finite() {
        k
    } else {
        f64::INFINITY
    }
}

/// The Euclidean norm of column `j`, scaled by its largest entry first so that squaring
/// neither overflows nor underflows.
fn column_norm(v: &[Xyz], j: usize) -> f64 {
    let m = v.iter().map(|x| x[j].abs()).fold(0.0, f64::max);
    if m == 0.0 {
        return 0.0;
    }
    m * v.iter().map(|x| (x[j] / m).powi(2)).sum::<f64>().sqrt()
}

impl ColourTransform {
    pub(crate) fn apply(&self, v: Xyz) -> Xyz {
        let t = &self.t;
        [
            t[0][0] * v[0] + t[0][1] * v[1] + t[0][2] * v[2],
            t[1][0] * v[0] + t[1][1] * v[1] + t[1][2] * v[2],
            t[2][0] * v[0] + t[2][1] * v[1] + t[2][2] * v[2],
        ]
    }
}

/// Fit T minimising Σ |T·vᵢ − wᵢ|².
pub fn fit_transform(v: &[Xyz], w: &[Xyz]) -> Result<ColourTransform, CrossValError> {
    fit_transform_weighted(v, w, [1.0; 3])
}

/// Fit T minimising Σᵢ Σₖ aₖ ((T·vᵢ)ₖ − wᵢₖ)²; the paper shows the result does not depend on aₖ.
pub(crate) fn fit_transform_weighted(
    v: &[Xyz],
    w: &[Xyz],
    weights: [f64; 3],
) -> Result<ColourTransform, CrossValError> {
    if v.len() != w.len() {
        return Err(CrossValError::LengthMismatch(v.len(), w.len()));
    }
    let n = v.len();
    if n < 3 {
        return Err(CrossValError::TooFewPairs(n));
    }
    if !weights.iter().all(|a| a.is_finite() && *a > 0.0) {
        return Err(CrossValError::BadWeights(weights));
    }
    for i in 0..n {
        if !(v[i].iter().chain(&w[i]).all(|x| x.is_finite())) {
            return Err(CrossValError::NotFinite(i));
        }
    }
    let raw = DMatrix::from_fn(n, 3, |i, j| v[i][j]).singular_values();
    let condition = condition_of(&raw).min(f64::MAX);
    // equilibrate: V = Vₛ·diag(s) with unit-norm columns; Vₛ·uₖ = wₖ gives tₖⱼ = uₖⱼ / sⱼ
    let scale = [0, 1, 2].map(|j| column_norm(v, j));
    if !scale.iter().all(|s| *s > 0.0 && s.is_finite()) {
        return Err(CrossValError::Singular(f64::INFINITY));
    }
    let svd = DMatrix::from_fn(n, 3, |i, j| v[i][j] / scale[j]).svd(true, true);
    let condition_scaled = condition_of(&svd.singular_values);
    if !(condition_scaled < SINGULAR) {
        return Err(CrossValError::Singular(condition_scaled));
    }
    let mut t = [[0.0; 3]; 3];
    for k in 0..3 {
        // row k: minimise aₖ Σᵢ (vᵢ·tₖ − wᵢₖ)²; the weight scales both sides of one problem
        let sa = weights[k].sqrt();
        let rhs = DVector::from_fn(n, |i, _| w[i][k] * sa);
        let sol = svd
            .solve(&rhs, 0.0)
            .map_err(|_| CrossValError::Singular(condition_scaled))?
            / sa;
        for j in 0..3 {
            t[k][j] = sol[j] / scale[j];
        }
    }
    let tm = Matrix3::from_row_slice(&t.concat());
    let mut ss = 0.0;
    for i in 0..n {
        let p = tm * nalgebra::Vector3::new(v[i][0], v[i][1], v[i][2]);
        ss += (p[0] - w[i][0]).powi(2) + (p[1] - w[i][1]).powi(2) + (p[2] - w[i][2]).powi(2);
    }
    Ok(ColourTransform {
        t,
        condition,
        condition_scaled,
        rms_residual: (ss / n as f64).sqrt(),
        ill_conditioned: condition_scaled > ILL_CONDITIONED,
    })
}

/// Max, average and median of a list (the paper's Table 3 columns).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct Table3Row {
    pub max: f64,
    pub avg: f64,
    pub median: f64,
}

fn stats(mut v: Vec<f64>) -> Table3Row {
    if v.is_empty() {
        return Table3Row::default();
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Table3Row {
        max: v[n - 1],
        avg: v.iter().sum::<f64>() / n as f64,
        median,
    }
}

/// Table 3: ΔE*ab and CIEDE2000 between T·vᵢ and wᵢ; also the indices of the largest ΔE00.
pub(crate) fn table3(
    tr: &ColourTransform,
    v: &[Xyz],
    w: &[Xyz],
    white: White,
    worst: usize,
) -> (Table3Row, Table3Row, Vec<(usize, f64)>) {
    let d: Vec<_> = v
        .iter()
        .zip(w)
        .map(|(a, b)| colour_difference(tr.apply(*a), *b, white))
        .collect();
    let mut ranked: Vec<(usize, f64)> = d.iter().enumerate().map(|(i, x)| (i, x.de2000)).collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    ranked.truncate(worst);
    (
        stats(d.iter().map(|x| x.de76).collect()),
        stats(d.iter().map(|x| x.de2000).collect()),
        ranked,
    )
}

/// One session capture for the cross-validation: the measured directions, the XYZ as captured
/// (it carries cos θi and the session's gain), and the controller time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SessionValue {
    pub idx: u64,
    pub entry: usize,
    pub t_s: f64,
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub xyz: Xyz,
}

/// A gain model to divide out: a measured gain curve when there is one (`points`, e.g. the
/// drift probes: steps included), else g(t) = exp(r·t), r = rate_pct_per_h / 100 per hour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct GainCorrection {
    pub rate_pct_per_h: f64,
    pub se_pct_per_h: f64,
    /// Where the model comes from (`probes`, `command line`, ...).
    pub source: String,
    /// (t in hours, gain) in time order: interpolated linearly in ln g, held at the ends.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<(f64, f64)>,
}

/// A gain curve's value at `t_h` (hours): (t in hours, gain) points in time order, interpolated
/// linearly in ln g and held at the ends. None with fewer than two points or a gain that is not
/// positive.
pub(crate) fn gain_curve_at(points: &[(f64, f64)], t_h: f64) -> Option<f64> {
    let p = points;
    if p.len() < 2 {
        return None;
    }
    let k = p.partition_point(|q| q.0 <= t_h);
    let ln = |i: usize| p[i].1.ln();
    let v = if k == 0 {
        ln(0)
    } else if k == p.len() {
        ln(p.len() - 1)
    } else {
        let (a, b) = (p[k - 1], p[k]);
        let u = if b.0 > a.0 {
            (t_h - a.0) / (b.0 - a.0)
        } else {
            1.0
        };
        ln(k - 1) + u * (ln(k) - ln(k - 1))
    };
    v.is_finite().then(|| v.exp())
}

impl GainCorrection {
    pub(crate) fn gain(&self, t_s: f64) -> f64 {
        let t = t_s / 3600.0;
        gain_curve_at(&self.points, t).unwrap_or_else(|| (self.rate_pct_per_h / 100.0 * t).exp())
    }
}

/// One of the directions with the largest deviation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Deviation {
    pub idx: u64,
    pub entry: usize,
    /// θi, φi, θo, φo of the capture (degrees).
    pub angles_deg: [f64; 4],
    pub t_h: f64,
    pub de76: f64,
    pub de2000: f64,
    /// The resampled reference's relative uncertainty (nodal spread over value, worst channel).
    pub reference_rel_spread: f64,
}

/// Table 3 for one set of session values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Table3 {
    pub transform: ColourTransform,
    pub de76: Table3Row,
    pub de2000: Table3Row,
    pub worst: Vec<Deviation>,
}

/// The result of `cross_validate`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct CrossValidation {
    pub reference_layers_deg: Vec<f64>,
    pub captures_compared: usize,
    /// Captures the reference does not reach (θi beyond its layers, outgoing directions outside
    /// every radius of influence).
    pub captures_not_covered: usize,
    /// Captures left out as grazing (cos θi below the limit).
    pub captures_grazing: usize,
    /// Captures left out because the resampled reference is too uncertain there (its relative
    /// nodal spread in any channel exceeds `max_reference_spread`): gaps in the reference's grid.
    pub captures_reference_uncertain: usize,
    pub max_reference_spread: f64,
    /// Median relative uncertainty of the resampled reference (worst channel).
    pub reference_rel_spread_median: f64,
    pub table3: Table3,
    pub gain_corrected: Option<(GainCorrection, Table3)>,
}

fn table3_of(
    values: &[Xyz],
    reference: &[Xyz],
    used: &[(SessionValue, f64)],
    white: White,
    worst: usize,
) -> Result<Table3, CrossValError> {
    let transform = fit_transform(values, reference)?;
    let (de76, de2000, ranked) = table3(&transform, values, reference, white, worst);
    let worst = ranked
        .into_iter()
        .map(|(k, de00)| {
            let (s, spread) = used[k];
            let si = Spherical::from_vector(&s.omega_i);
            let so = Spherical::from_vector(&s.omega_o);
            Deviation {
                idx: s.idx,
                entry: s.entry,
                angles_deg: [si.theta_deg(), si.phi_deg(), so.theta_deg(), so.phi_deg()],
                t_h: s.t_s / 3600.0,
                de76: colour_difference(transform.apply(values[k]), reference[k], white).de76,
                de2000: de00,
                reference_rel_spread: spread,
            }
        })
        .collect();
    Ok(Table3 {
        transform,
        de76,
        de2000,
        worst,
    })
}

/// Resample the reference at every session capture, fit T (session → reference) and give
/// Table 3; with a gain model, the same again on the gain-corrected session values. Session
/// values are divided by cos θi first (the reference holds reflectance factors, BRDF·π).
pub(crate) fn cross_validate(
    session: &[SessionValue],
    reference: &LayeredResampler,
    white: White,
    min_cos: f64,
    max_reference_spread: f64,
    gain: Option<GainCorrection>,
    worst: usize,
) -> Result<CrossValidation, CrossValError> {
    let mut used: Vec<(SessionValue, f64)> = Vec::new();
    let mut values = Vec::new();
    let mut refs = Vec::new();
    let (mut not_covered, mut grazing, mut uncertain) = (0, 0, 0);
    for s in session {
        let ci = s.omega_i.normalize().z;
        if !(ci >= min_cos) || !s.xyz.iter().all(|v| v.is_finite()) {
            grazing += 1;
            continue;
        }
        match reference.at(&s.omega_i, &s.omega_o) {
            Ok(r) if r.value.iter().all(|v| v.is_finite()) => {
                // the worst channel: a chroma error shows in X or Z before Y
                let spread = (0..3)
                    .map(|c| r.spread[c] / r.value[c].abs().max(1e-300))
                    .fold(0.0, f64::max);
                if !(spread <= max_reference_spread) {
                    uncertain += 1;
                    continue;
                }
                used.push((*s, spread));
                values.push(s.xyz.map(|v| v / ci));
                refs.push(r.value);
            }
            _ => not_covered += 1,
        }
    }
    let table3 = table3_of(&values, &refs, &used, white, worst)?;
    let mut spreads: Vec<f64> = used.iter().map(|u| u.1).collect();
    spreads.sort_by(f64::total_cmp);
    let gain_corrected = match gain {
        None => None,
        Some(g) => {
            let corrected: Vec<Xyz> = values
                .iter()
                .zip(&used)
                .map(|(v, (s, _))| {
                    let k = g.gain(s.t_s);
                    v.map(|c| c / k)
                })
                .collect();
            let t = table3_of(&corrected, &refs, &used, white, worst)?;
            Some((g, t))
        }
    };
    Ok(CrossValidation {
        reference_layers_deg: reference.layer_thetas(),
        captures_compared: used.len(),
        captures_not_covered: not_covered,
        captures_grazing: grazing,
        captures_reference_uncertain: uncertain,
        max_reference_spread,
        reference_rel_spread_median: spreads.get(spreads.len() / 2).copied().unwrap_or(0.0),
        table3,
        gain_corrected,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colours(n: usize, grey: f64, seed: u64) -> Vec<Xyz> {
        let mut s = crate::fixtures::Lcg(seed);
        let mut u = || s.uniform();
        (0..n)
            .map(|_| {
                let l = 5.0 + 90.0 * u();
                // near-grey: every colour close to the same chromaticity
                [
                    l * (0.95 + grey * (u() - 0.5)),
                    l * (1.0 + grey * (u() - 0.5)),
                    l * (1.09 + grey * (u() - 0.5)),
                ]
            })
            .collect()
    }

    const T: [[f64; 3]; 3] = [
        [3.207, -1.406, -1.144],
        [3.404, -1.486, -1.218],
        [3.461, -1.578, -1.196],
    ];

    fn apply(t: &[[f64; 3]; 3], v: Xyz) -> Xyz {
        [0, 1, 2].map(|k| t[k][0] * v[0] + t[k][1] * v[1] + t[k][2] * v[2])
    }

    #[test]
    fn recovers_a_known_transform_and_ignores_channel_weights() {
        // the paper's T for the ceiling sample
        let v = colours(500, 0.5, 1);
        let w: Vec<Xyz> = v.iter().map(|x| apply(&T, *x)).collect();
        let fit = fit_transform(&v, &w).unwrap();
        for k in 0..3 {
            for j in 0..3 {
                assert!((fit.t[k][j] - T[k][j]).abs() < 1e-9, "{fit:?}");
            }
        }
        assert!(fit.rms_residual < 1e-9);
        // with noise, channel weights still give the same T (the paper's eq. 8-9)
        let mut s = crate::fixtures::Lcg(9);
        let noisy: Vec<Xyz> = w
            .iter()
            .map(|x| x.map(|c| c + (s.uniform() - 0.5)))
            .collect();
        let a = fit_transform(&v, &noisy).unwrap();
        let b = fit_transform_weighted(&v, &noisy, [0.2, 5.0, 1.0]).unwrap();
        for k in 0..3 {
            for j in 0..3 {
                assert!((a.t[k][j] - b.t[k][j]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn near_grey_data_are_flagged_and_degenerate_data_refused() {
        let chromatic = fit_transform(&colours(200, 0.5, 2), &colours(200, 0.5, 3)).unwrap();
        assert!(!chromatic.ill_conditioned, "{chromatic:?}");
        let v = colours(200, 0.002, 4);
        let w: Vec<Xyz> = v.iter().map(|x| apply(&T, *x)).collect();
        let grey = fit_transform(&v, &w).unwrap();
        assert!(
            grey.ill_conditioned && grey.condition_scaled > 1e3 && grey.condition > 1e3,
            "{grey:?}"
        );
        // exactly proportional colours: rank 1, no transform
        let flat: Vec<Xyz> = (1..50)
            .map(|i| [i as f64, i as f64 * 1.05, i as f64 * 1.1])
            .collect();
        assert!(matches!(
            fit_transform(&flat, &flat),
            Err(CrossValError::Singular(_))
        ));
        assert_eq!(
            fit_transform(&v[..2], &w[..2]).unwrap_err(),
            CrossValError::TooFewPairs(2)
        );
        assert_eq!(
            fit_transform(&v[..5], &w[..4]).unwrap_err(),
            CrossValError::LengthMismatch(5, 4)
        );
        let mut bad = v.clone();
        bad[3][1] = f64::NAN;
        assert_eq!(
            fit_transform(&bad, &w).unwrap_err(),
            CrossValError::NotFinite(3)
        );
        assert!(matches!(
            fit_transform_weighted(&v, &w, [1.0, 0.0, 1.0]),
            Err(CrossValError::BadWeights(_))
        ));
    }

    #[test]
    fn table3_statistics() {
        let v = colours(101, 0.5, 5);
        let w: Vec<Xyz> = v.iter().map(|x| apply(&T, *x)).collect();
        let fit = fit_transform(&v, &w).unwrap();
        let white = White::d65_scaled(100.0).unwrap();
        let (de, de00, worst) = table3(&fit, &v, &w, white, 3);
        assert!(de.max < 1e-6 && de00.max < 1e-6);
        // one disagreeing direction stands out as the worst
        let mut w2 = w.clone();
        w2[17] = w2[17].map(|c| c * 1.3);
        let (de, _, worst2) = table3(&fit, &v, &w2, white, 3);
        assert_eq!(worst2[0].0, 17);
        assert!(
            de.max > 1.0 && de.median < 1e-6 && de.avg < de.max,
            "{de:?}"
        );
        assert_eq!(worst.len(), 3);
    }

    #[test]
    fn cross_validation_recovers_the_transform_and_the_gain_correction_helps() {
        use crate::measure::plan::SamplingPlan;
        use crate::measure::resample::{LayeredResampler, ResampleSpec, Sample};
        // a chromatic, smooth "reference" BRDF (reflectance factors, Y≈100 scale)
        let f = |wi: &Vec3, wo: &Vec3| -> Xyz {
            let m = Vec3::new(-wi.x, -wi.y, wi.z);
            let lobe = 25.0 * m.dot(wo).max(0.0).powi(8);
            [
                30.0 + lobe + 10.0 * wo.z,
                40.0 + lobe,
                20.0 + lobe + 15.0 * wi.z,
            ]
        };
        let mut samples = Vec::new();
        for ti in [0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0] {
            let wi = Spherical::from_deg(ti, 0.0).to_vector();
            for to in (0..=80).step_by(5) {
                for po in (0..360).step_by(15) {
                    if to == 0 && po > 0 {
                        continue;
                    }
                    let wo = Spherical::from_deg(to as f64, po as f64).to_vector();
                    samples.push(Sample {
                        omega_i: wi,
                        omega_o: wo,
                        value: f(&wi, &wo),
                    });
                }
            }
        }
        let reference = LayeredResampler::new(&samples, &ResampleSpec::default()).unwrap();
        // the session: an uncalibrated camera (T⁻¹), cos θi, and a −2 %/h exponential drift
        let t_true = [[1.10, 0.05, -0.02], [0.03, 0.95, 0.01], [-0.04, 0.02, 1.20]];
        let t_inv = nalgebra::Matrix3::from_fn(|r, c| t_true[r][c])
            .try_inverse()
            .unwrap();
        let plan = SamplingPlan::ubo();
        let dirs = plan.directions();
        let session: Vec<SessionValue> = (0..plan.capture_count())
            .step_by(3)
            .map(|idx| {
                let e = plan.entry(idx).unwrap();
                let (wi, wo) = (
                    dirs[e.light].spherical().to_vector(),
                    dirs[e.camera].spherical().to_vector(),
                );
                let t_s = idx as f64 * 7.0;
                let g = (-0.02 * t_s / 3600.0).exp();
                let w = f(&wi, &wo);
                let v = t_inv * nalgebra::Vector3::new(w[0], w[1], w[2]) * wi.z * g;
                SessionValue {
                    idx: idx as u64,
                    entry: idx,
                    t_s,
                    omega_i: wi,
                    omega_o: wo,
                    xyz: [v.x, v.y, v.z],
                }
            })
            .collect();
        let white = White::d65_scaled(100.0).unwrap();
        let gain = GainCorrection {
            rate_pct_per_h: -2.0,
            se_pct_per_h: 0.0,
            source: "test".into(),
            points: vec![],
        };
        let x = cross_validate(&session, &reference, white, 1e-3, 0.05, Some(gain), 5).unwrap();
        assert!(x.captures_compared > 2000, "{}", x.captures_compared);
        assert_eq!(x.reference_layers_deg.len(), 7);
        let (g, corrected) = x.gain_corrected.as_ref().unwrap();
        assert_eq!(g.source, "test");
        // with the drift divided out, T is the instrument's and the residual is interpolation only
        for r in 0..3 {
            for c in 0..3 {
                assert!(
                    (corrected.transform.t[r][c] - t_true[r][c]).abs() < 0.02,
                    "{:?}",
                    corrected.transform.t
                );
            }
        }
        assert!(corrected.de2000.median < 0.1, "{:?}", corrected.de2000);
        assert!(
            x.table3.de2000.median > 3.0 * corrected.de2000.median,
            "{:?} vs {:?}",
            x.table3.de2000,
            corrected.de2000
        );
        assert_eq!(corrected.worst.len(), 5);
        assert!(corrected
            .worst
            .windows(2)
            .all(|w| w[0].de2000 >= w[1].de2000));
    }

    #[test]
    fn a_measured_gain_curve_is_interpolated_in_ln_g_and_held_at_the_ends() {
        let g = GainCorrection {
            rate_pct_per_h: 0.0,
            se_pct_per_h: 0.0,
            source: "probes".into(),
            points: vec![(1.0, 1.0), (2.0, 0.9), (2.0, 0.8), (4.0, 0.8)],
        };
        assert_eq!(g.gain(0.0), 1.0);
        assert!((g.gain(1.5 * 3600.0) - 0.9f64.sqrt()).abs() < 1e-12);
        // a step: after the repeated time the new level holds
        assert!((g.gain(3.0 * 3600.0) - 0.8).abs() < 1e-12);
        assert!((g.gain(10.0 * 3600.0) - 0.8).abs() < 1e-12);
        let rate = GainCorrection {
            points: vec![],
            rate_pct_per_h: -1.0,
            ..g
        };
        assert!((rate.gain(3600.0) - (-0.01f64).exp()).abs() < 1e-15);
    }
}
