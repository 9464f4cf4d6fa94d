//! The lamp's colour. A halogen lamp is close to a black body: as it ages, or as its supply
//! drifts, its colour temperature (CCT) moves and with it the chromaticity of every capture, while
//! the luminance may hardly change. A change from the reference temperature T₀ (the one the
//! camera was white-balanced on) to T multiplies the light by r(λ) = B(λ, T) / B(λ, T₀), Planck's
//! law, normalised so that a white keeps its luminance.
//!
//! goniowatch observes that change as the rates of two log-chromaticities of the same geometry
//! over time, u = ln(X/Y) and v = ln(Z/Y) (`checks::drift`), and turns them into a CCT rate by
//! the model's sensitivity ∂(u, v)/∂T at T₀: the least-squares K/h of the two rates, with its
//! standard error. The colour difference per hour is that of a white surface (ΔE00 between the
//! white at T₀ and the white one hour of drift later).

use crate::measure::colour::{
    bands, ciede2000, xyz_to_lab, ColourError, SpectralToXyz, White, Xyz,
};
use serde::{Deserialize, Serialize};

/// Planck's second radiation constant c₂ = h·c/k (m·K), CODATA 2018.
const PLANCK_C2_M_K: f64 = 1.438_776_877e-2;

/// Relative spectral radiance of a black body at `t_k` kelvin, wavelength in nm (the first
/// radiation constant is left out: only ratios are used).
pub(crate) fn planck_relative(wavelength_nm: f64, t_k: f64) -> f64 {
    let lam = wavelength_nm * 1e-9;
    1.0 / (lam.powi(5) * (PLANCK_C2_M_K / (lam * t_k)).exp_m1())
}

/// The lamp model at a reference colour temperature: the CIE 1931 2° observer and D65 (the
/// illuminant the session's XYZ assume) on 5 nm bands from 380 to 780 nm.
#[derive(Debug, Clone)]
pub(crate) struct LampColour {
    reference_k: f64,
    spectral: SpectralToXyz,
    wavelengths: Vec<f64>,
    /// ∂(ln X/Y, ln Z/Y)/∂T at the reference, per kelvin.
    sensitivity: [f64; 2],
}

/// A colour-temperature rate from the two log-chromaticity rates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(crate) struct CctRate {
    pub k_per_h: f64,
    pub se_k_per_h: f64,
}

impl CctRate {
    /// The colour-drift alarm's rule: the rate exceeds `tolerance_k_per_h` by `z` standard
    /// errors (the daemon's `colour-drift` and `goniowatch plan`'s simulation of it).
    pub(crate) fn exceeds(&self, tolerance_k_per_h: f64, z: f64) -> bool {
        self.k_per_h.abs() - z * self.se_k_per_h > tolerance_k_per_h
    }

    /// The clearing rule: the rate is within `tolerance_k_per_h` by `z` standard errors.
    pub(crate) fn within(&self, tolerance_k_per_h: f64, z: f64) -> bool {
        self.k_per_h.abs() + z * self.se_k_per_h < tolerance_k_per_h
    }
}

impl LampColour {
    /// The model for a lamp whose reference colour temperature is `reference_k` kelvin
    /// (1000–20,000 K).
    pub(crate) fn new(reference_k: f64) -> Result<Self, ColourError> {
        if !(reference_k.is_finite() && (1000.0..=20_000.0).contains(&reference_k)) {
            return Err(ColourError::BadTemperature {
                kelvin: reference_k,
            });
        }
        let wavelengths = bands(380.0, 5.0, 81);
        let spectral = SpectralToXyz::d65(&wavelengths)?;
        let mut m = LampColour {
            reference_k,
            spectral,
            wavelengths,
            sensitivity: [0.0; 2],
        };
        m.sensitivity = m.sensitivity_at(reference_k);
        Ok(m)
    }

    pub(crate) fn reference_k(&self) -> f64 {
        self.reference_k
    }

    /// ∂(ln X/Y, ln Z/Y)/∂T at the reference (per kelvin).
    #[cfg(test)]
    pub(crate) fn sensitivity(&self) -> [f64; 2] {
        self.sensitivity
    }

    /// XYZ of a perfect white (Y = 100) lit by the lamp at `t_k`, white-balanced at the
    /// reference.
    pub(crate) fn white_at(&self, t_k: f64) -> Xyz {
        // the model holds for lamps, not for any number an estimate can reach: a temperature
        // outside 500–50,000 K (a rate extrapolated from a short span) is taken at the bound
        let t_k = if t_k.is_nan() {
            self.reference_k
        } else {
            t_k.clamp(500.0, 50_000.0)
        };
        let r: Vec<f64> = self
            .wavelengths
            .iter()
            .map(|&w| planck_relative(w, t_k) / planck_relative(w, self.reference_k))
            .collect();
        // `convert` only fails on a length mismatch, which cannot happen here
        let xyz = self.spectral.convert(&r).unwrap_or(self.spectral.white());
        let k = if xyz[1] > 0.0 { 100.0 / xyz[1] } else { 1.0 };
        [xyz[0] * k, xyz[1] * k, xyz[2] * k]
    }

    /// (ln X/Y, ln Z/Y) of the white at `t_k` minus those at the reference.
    pub(crate) fn log_chromaticity(&self, t_k: f64) -> [f64; 2] {
        let (w, w0) = (self.white_at(t_k), self.spectral.white());
        [
            (w[0] / w[1]).ln() - (w0[0] / w0[1]).ln(),
            (w[2] / w[1]).ln() - (w0[2] / w0[1]).ln(),
        ]
    }

    /// ∂(ln X/Y, ln Z/Y)/∂T at `t_k` (per kelvin; central difference over ±1 K: the curve is
    /// smooth on that scale, and a 1 K step keeps the difference far above rounding).
    pub(crate) fn sensitivity_at(&self, t_k: f64) -> [f64; 2] {
        let (hi, lo) = (
            self.log_chromaticity(t_k + 1.0),
            self.log_chromaticity(t_k - 1.0),
        );
        [(hi[0] - lo[0]) / 2.0, (hi[1] - lo[1]) / 2.0]
    }

    /// The colour temperature whose white has the log-chromaticity change `c` (ln X/Y, ln Z/Y
    /// against the reference) nearest in the weights `w`: Gauss–Newton from the linear guess,
    /// a fixed number of steps (the curve is nearly straight over hundreds of kelvin).
    fn cct_of(&self, c: [f64; 2], w: [f64; 2]) -> f64 {
        let mut t = self.reference_k;
        for _ in 0..6 {
            let (f, s) = (self.log_chromaticity(t), self.sensitivity_at(t));
            let den = w[0] * s[0] * s[0] + w[1] * s[1] * s[1];
            let step = (w[0] * s[0] * (c[0] - f[0]) + w[1] * s[1] * (c[1] - f[1])) / den;
            if !step.is_finite() {
                break;
            }
            t = (t + step).clamp(500.0, 50_000.0);
        }
        t
    }

    /// The colour-temperature rate that best explains the rates of ln X/Y and ln Z/Y (per
    /// hour, each with its standard error) observed over `span_h` hours from the start: the
    /// temperature whose chromaticity the fitted rates reach at the end of the span (weighted
    /// least squares on the model, so the curvature of the chromaticity in T does not bias
    /// the rate), over the span; the standard error propagated through the sensitivity at the
    /// middle of the span. `None` without finite inputs.
    pub(crate) fn cct_rate(&self, u: (f64, f64), v: (f64, f64), span_h: f64) -> Option<CctRate> {
        if !(span_h > 0.0
            && span_h.is_finite()
            && u.0.is_finite()
            && v.0.is_finite()
            && u.1 >= 0.0
            && v.1 >= 0.0)
        {
            return None;
        }
        // weights 1/se² (a floor keeps a perfect channel from dividing by zero)
        let w = [1.0 / u.1.max(1e-12).powi(2), 1.0 / v.1.max(1e-12).powi(2)];
        let t_end = self.cct_of([u.0 * span_h, v.0 * span_h], w);
        let k = (t_end - self.reference_k) / span_h;
        let s = self.sensitivity_at(0.5 * (self.reference_k + t_end));
        let se = (1.0 / (w[0] * s[0] * s[0] + w[1] * s[1] * s[1])).sqrt();
        (k.is_finite() && se.is_finite()).then_some(CctRate {
            k_per_h: k,
            se_k_per_h: se,
        })
    }

    /// ΔE00 of a white surface over one hour of a `k_per_h` drift from the reference. L\*a\*b\*
    /// is relative to `white`, so any white gives the same figure for a white surface.
    pub(crate) fn delta_e00_per_h(&self, k_per_h: f64, white: White) -> f64 {
        let w = white.xyz();
        let d = self.log_chromaticity(self.reference_k + k_per_h);
        let moved = [w[0] * d[0].exp(), w[1], w[2] * d[1].exp()];
        ciede2000(xyz_to_lab(w, white), xyz_to_lab(moved, white))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planck_peaks_where_wiens_law_says() {
        // Wien's displacement constant b = 2.897771955e-3 m·K (CODATA 2018)
        for t in [3000.0, 5000.0] {
            let peak = (2000..40000)
                .map(|i| i as f64 * 0.1)
                .max_by(|&a, &b| planck_relative(a, t).total_cmp(&planck_relative(b, t)))
                .unwrap();
            assert!(
                (peak - 2.897771955e-3 / t * 1e9).abs() < 0.2,
                "{t} K: {peak} nm"
            );
        }
    }

    #[test]
    fn the_reference_is_the_white_and_a_cooler_lamp_is_redder() {
        let m = LampColour::new(3000.0).unwrap();
        let at_ref = m.log_chromaticity(3000.0);
        assert!(
            at_ref[0].abs() < 1e-14 && at_ref[1].abs() < 1e-14,
            "{at_ref:?}"
        );
        let w = m.white_at(3000.0);
        let d65 = SpectralToXyz::d65(&bands(380.0, 5.0, 81)).unwrap().white();
        for c in 0..3 {
            assert!((w[c] - d65[c]).abs() < 1e-9);
        }
        let [du, dv] = m.log_chromaticity(2800.0);
        assert!(du > 0.0 && dv < 0.0, "{du} {dv}");
        let [su, sv] = m.sensitivity();
        assert!(su < 0.0 && sv > 0.0);
        // the sensitivity predicts a 10 K change: ln Z/Y to within 1 %; ln X/Y, which hardly
        // moves near 3000 K and turns over near 3500 K, to within 5 %
        let [u10, v10] = m.log_chromaticity(2990.0);
        assert!((u10 / (-10.0 * su) - 1.0).abs() < 0.05, "{u10} {su}");
        assert!((v10 / (-10.0 * sv) - 1.0).abs() < 0.01, "{v10} {sv}");
    }

    #[test]
    fn the_cct_rate_is_recovered_from_its_own_log_chromaticity_rates() {
        let m = LampColour::new(3000.0).unwrap();
        // the chromaticity of a lamp 20 K/h cooler after 13 h, as two rates over that span
        for (k_per_h, span) in [(-20.0, 13.0), (-20.0, 2.0), (30.0, 6.0), (-100.0, 13.0)] {
            let [u, v] = m.log_chromaticity(3000.0 + k_per_h * span);
            let r = m
                .cct_rate((u / span, 1e-4), (v / span, 1e-4), span)
                .unwrap();
            assert!(
                (r.k_per_h - k_per_h).abs() < 1e-3 * k_per_h.abs(),
                "{k_per_h} {span}: {r:?}"
            );
            assert!(r.se_k_per_h > 0.0);
        }
        // one channel far noisier: the estimate follows the other
        let [u, v] = m.log_chromaticity(2800.0);
        let r = m
            .cct_rate((u / 10.0 + 0.01, 1.0), (v / 10.0, 1e-4), 10.0)
            .unwrap();
        assert!((r.k_per_h + 20.0).abs() < 0.05, "{r:?}");
        assert!(m.cct_rate((f64::NAN, 1.0), (0.0, 1.0), 1.0).is_none());
        assert!(m.cct_rate((0.0, f64::NAN), (0.0, 1.0), 1.0).is_none());
        // an absurd rate over a short span stays finite: the model is taken at its bounds
        let r = m.cct_rate((5.0, 1e-3), (-50.0, 1e-3), 0.1).unwrap();
        let white = White::d65_scaled(100.0).unwrap();
        assert!(m.delta_e00_per_h(r.k_per_h, white).is_finite(), "{r:?}");
        assert!(m.log_chromaticity(-400.0).iter().all(|v| v.is_finite()));
        assert!(m.cct_rate((0.0, 1.0), (0.0, 1.0), 0.0).is_none());
    }

    #[test]
    fn a_white_moves_by_a_fraction_of_a_de00_per_hour_at_20_k_per_h() {
        let m = LampColour::new(3000.0).unwrap();
        let white = White::d65_scaled(100.0).unwrap();
        let de = m.delta_e00_per_h(-20.0, white);
        assert!(de > 0.05 && de < 2.0, "{de}");
        assert_eq!(m.delta_e00_per_h(0.0, white), 0.0);
        assert!(m.delta_e00_per_h(-40.0, white) > de);
    }

    #[test]
    fn colour_temperatures_outside_the_range_are_refused() {
        for t in [0.0, -5.0, f64::NAN, f64::INFINITY, 999.0, 25_000.0] {
            assert!(LampColour::new(t).is_err(), "{t}");
        }
    }
}
