//! Cross-validation against an uncalibrated reference (the paper's Section 6.2): the least-squares
//! 3×3 colour transform T with T·v ≈ w, and the Table 3 statistics of the colour differences.
//! Groundwork for issue 6 (the reference file format, the resampling at the session's directions
//! and the `compare` command are open).
//!
//! T is found row by row from the n×3 least-squares system V·tₖ = wₖ with an SVD of V (never the
//! normal equations' inverse): its condition number κ(V) is reported, and near-grey data (all
//! colours almost proportional to one another, so V is nearly rank 1) make κ large, which the
//! result flags. The paper shows channel weights aₖ leave T unchanged (each row is its own
//! problem); `fit_transform_weighted` exists to test exactly that.

use super::colour::{colour_difference, White, Xyz};
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
    #[error("the reference colours are (numerically) rank-deficient: no unique transform (condition number {0:.3e})")]
    Singular(f64),
    #[error("channel weights must be finite and positive, got {0:?}")]
    BadWeights([f64; 3]),
}

/// Above this condition number the fit is flagged as ill-conditioned (near-grey data).
pub const ILL_CONDITIONED: f64 = 1e3;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ColourTransform {
    /// Row-major T.
    pub t: [[f64; 3]; 3],
    /// Condition number of the reference colour matrix V (σ_max / σ_min).
    pub condition: f64,
    /// RMS of |T·v − w| over the pairs.
    pub rms_residual: f64,
    /// `condition > ILL_CONDITIONED`: the data are close to grey and T is poorly determined.
    pub ill_conditioned: bool,
}

impl ColourTransform {
    pub fn apply(&self, v: Xyz) -> Xyz {
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
pub fn fit_transform_weighted(
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
    let vm = DMatrix::from_fn(n, 3, |i, j| v[i][j]);
    let svd = vm.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    if !(condition < 1e12) {
        return Err(CrossValError::Singular(condition));
    }
    let mut t = [[0.0; 3]; 3];
    for k in 0..3 {
        // row k: minimise aₖ Σᵢ (vᵢ·tₖ − wᵢₖ)²; the weight scales both sides of one problem
        let sa = weights[k].sqrt();
        let rhs = DVector::from_fn(n, |i, _| w[i][k] * sa);
        let sol = svd
            .solve(&rhs, 0.0)
            .map_err(|_| CrossValError::Singular(condition))?
            / sa;
        for j in 0..3 {
            t[k][j] = sol[j];
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
        rms_residual: (ss / n as f64).sqrt(),
        ill_conditioned: condition > ILL_CONDITIONED,
    })
}

/// Max, average and median of a list (the paper's Table 3 columns).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Table3Row {
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
pub fn table3(
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

#[cfg(test)]
mod tests {
    use super::*;

    fn colours(n: usize, grey: f64, seed: u64) -> Vec<Xyz> {
        let mut s = seed;
        let mut u = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
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
        let mut s = 9u64;
        let noisy: Vec<Xyz> = w
            .iter()
            .map(|x| {
                x.map(|c| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    c + ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
                })
            })
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
        assert!(!chromatic.ill_conditioned, "{}", chromatic.condition);
        let v = colours(200, 0.002, 4);
        let w: Vec<Xyz> = v.iter().map(|x| apply(&T, *x)).collect();
        let grey = fit_transform(&v, &w).unwrap();
        assert!(
            grey.ill_conditioned && grey.condition > 1e3,
            "{}",
            grey.condition
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
}
