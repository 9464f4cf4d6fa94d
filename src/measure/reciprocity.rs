//! Helmholtz reciprocity of one pair of captures (the paper's Section 6.1): both XYZ values are
//! divided by their own cos θᵢ and multiplied by the geometric mean √(cos θᵢ₁ · cos θᵢ₂), then
//! compared with |ΔX|, |ΔY|, |ΔZ|, ΔE*ab, ΔC*ab, ΔH*ab and CIEDE2000.
//!
//! Grazing incidence: the re-correction factor is √(cos θᵢ₂ / cos θᵢ₁), which is evaluated as a
//! ratio of square roots and never divides by zero. A pair whose cos θᵢ is below `min_cos`
//! (default 1e-3, i.e. θᵢ > 89.94°) carries no usable signal (the lamp barely lights the
//! sample) and is refused with [`PairError::Grazing`] instead of producing a huge or
//! infinite value.

use super::colour::{colour_difference, ColourDifference, White, Xyz};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Default lower bound on cos θᵢ for a comparable pair.
pub const DEFAULT_MIN_COS: f64 = 1e-3;

#[derive(Debug, Error, PartialEq)]
pub enum PairError {
    #[error("grazing incidence θᵢ = {theta_deg:.3}° (cos θᵢ = {cos:.2e} < {min_cos:.1e}): pair not comparable")]
    Grazing {
        theta_deg: f64,
        cos: f64,
        min_cos: f64,
    },
    #[error("non-finite colour value in pair: {0:?}")]
    NotFinite([f64; 6]),
}

/// The cosine re-corrected XYZ of both captures of a pair.
pub fn recorrect(
    xyz1: Xyz,
    theta_i1_deg: f64,
    xyz2: Xyz,
    theta_i2_deg: f64,
    min_cos: f64,
) -> Result<(Xyz, Xyz), PairError> {
    let all = [xyz1[0], xyz1[1], xyz1[2], xyz2[0], xyz2[1], xyz2[2]];
    if !all.iter().all(|v| v.is_finite()) {
        return Err(PairError::NotFinite(all));
    }
    let c1 = theta_i1_deg.to_radians().cos();
    let c2 = theta_i2_deg.to_radians().cos();
    for (t, c) in [(theta_i1_deg, c1), (theta_i2_deg, c2)] {
        if !(c >= min_cos) {
            return Err(PairError::Grazing {
                theta_deg: t,
                cos: c,
                min_cos,
            });
        }
    }
    let (s1, s2) = (c1.sqrt(), c2.sqrt());
    let f1 = s2 / s1; // X₁ / c₁ · √(c₁c₂)
    let f2 = s1 / s2;
    Ok((
        [xyz1[0] * f1, xyz1[1] * f1, xyz1[2] * f1],
        [xyz2[0] * f2, xyz2[1] * f2, xyz2[2] * f2],
    ))
}

/// The residual of one reciprocal pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairResidual {
    pub xyz1: Xyz,
    pub xyz2: Xyz,
    pub diff: ColourDifference,
}

/// Re-correct and compare one pair.
pub fn pair_residual(
    xyz1: Xyz,
    theta_i1_deg: f64,
    xyz2: Xyz,
    theta_i2_deg: f64,
    white: White,
    min_cos: f64,
) -> Result<PairResidual, PairError> {
    let (a, b) = recorrect(xyz1, theta_i1_deg, xyz2, theta_i2_deg, min_cos)?;
    Ok(PairResidual {
        xyz1: a,
        xyz2: b,
        diff: colour_difference(a, b, white),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambertian_pair_is_reciprocal_after_recorrection() {
        // a Lambertian surface: captured value ∝ albedo · cos θᵢ
        let albedo = [30.0, 40.0, 50.0];
        let (t1, t2) = (15.0f64, 75.0f64);
        let x1 = albedo.map(|a| a * t1.to_radians().cos());
        let x2 = albedo.map(|a| a * t2.to_radians().cos());
        let w = White::d65_scaled(100.0).unwrap();
        let r = pair_residual(x1, t1, x2, t2, w, DEFAULT_MIN_COS).unwrap();
        assert!(r.diff.de76 < 1e-12 && r.diff.de2000 < 1e-12);
        let g = (t1.to_radians().cos() * t2.to_radians().cos()).sqrt();
        for c in 0..3 {
            assert!((r.xyz1[c] - albedo[c] * g).abs() < 1e-12);
        }
    }
}
