//! The drift an export divides out, and the photometry from a capture's XYZ to a BRDF.
//!
//! The drift model is the session's end-of-run estimate, not the one known at each capture's
//! check time: the lamp gain g(t) from the drift probes' measured curve when the session has
//! one (steps included), else the isotropy classes' rate with the steps the light sweeps found;
//! the lamp's colour as rates of ln(X/Y) and ln(Z/Y). A capture's corrected XYZ is
//! (X / (g·cx), Y / g, Z / (g·cz)).
//!
//! The BRDF of a corrected capture is (value / the white's value) × ρ_white / (π cos θi) per
//! channel, in linear RGB of the configured primaries (the white's RGB divides each channel, so
//! a white standard exports as ρ_white / π in every channel and a Lambertian sample of albedo ρ
//! as ρ / π).

use super::ExportError;
use crate::measure::colour::{RgbPrimaries, RgbToXyz, White, Xyz};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Where the gain model comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GainSource {
    /// The drift probes' measured gain curve (re-captures of one pose; steps included).
    ProbeCurve,
    /// The isotropy classes' drift rate, with the steps the light sweeps found.
    IsotropyClasses,
    /// The session has no gain estimate (or the export was asked not to correct).
    None,
}

/// A gain step at a known time: the gain is multiplied by exp(ln_size) after `t_h`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GainStep {
    pub t_h: f64,
    pub ln_size: f64,
}

/// The lamp's colour drift: rates of ln(X/Y) and ln(Z/Y) in %/h from the start of the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ColourRates {
    pub x_rate_pct_per_h: f64,
    pub z_rate_pct_per_h: f64,
    /// The colour-temperature rate they amount to (K/h) and its standard error.
    pub k_per_h: f64,
    pub se_k_per_h: f64,
}

/// The drift model an export divides out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriftCorrection {
    pub gain_source: GainSource,
    /// The gain's rate (%/h) and its standard error; with a probe curve, the probes' fitted
    /// rate (the curve itself is what is divided out).
    pub rate_pct_per_h: f64,
    pub se_pct_per_h: f64,
    /// The probes' curve: (t in hours, gain), in time order; interpolated linearly in ln g and
    /// held at the ends.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub curve: Vec<(f64, f64)>,
    /// Steps on top of the rate (isotropy classes only: a probe curve holds its steps).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub steps: Vec<GainStep>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<ColourRates>,
}

impl DriftCorrection {
    /// No correction.
    pub fn none() -> Self {
        DriftCorrection {
            gain_source: GainSource::None,
            rate_pct_per_h: 0.0,
            se_pct_per_h: 0.0,
            curve: Vec::new(),
            steps: Vec::new(),
            colour: None,
        }
    }

    /// The lamp's gain at controller time `t_s` relative to the start (or, with a probe curve,
    /// to the probe pose's first capture).
    pub fn gain(&self, t_s: f64) -> f64 {
        let t = t_s / 3600.0;
        match self.gain_source {
            GainSource::None => 1.0,
            GainSource::ProbeCurve if self.curve.len() >= 2 => {
                crate::measure::crossval::gain_curve_at(&self.curve, t).unwrap_or(1.0)
            }
            GainSource::ProbeCurve | GainSource::IsotropyClasses => {
                let steps: f64 = self
                    .steps
                    .iter()
                    .filter(|s| t > s.t_h)
                    .map(|s| s.ln_size)
                    .sum();
                let v = self.rate_pct_per_h / 100.0 * t + steps;
                if v.is_finite() {
                    v.exp()
                } else {
                    1.0
                }
            }
        }
    }

    /// The factors dividing X, Y and Z at `t_s`: g·cx, g, g·cz.
    pub fn xyz_factors(&self, t_s: f64) -> [f64; 3] {
        let g = self.gain(t_s);
        let t = t_s / 3600.0;
        let (cx, cz) = match &self.colour {
            Some(c) => (
                (c.x_rate_pct_per_h / 100.0 * t).exp(),
                (c.z_rate_pct_per_h / 100.0 * t).exp(),
            ),
            None => (1.0, 1.0),
        };
        let f = [g * cx, g, g * cz];
        if f.iter().all(|v| v.is_finite() && *v > 0.0) {
            f
        } else {
            [1.0; 3]
        }
    }

    /// `xyz` with the drift at `t_s` divided out.
    pub fn correct(&self, xyz: Xyz, t_s: f64) -> Xyz {
        let f = self.xyz_factors(t_s);
        [xyz[0] / f[0], xyz[1] / f[1], xyz[2] / f[2]]
    }
}

/// From a capture's XYZ on the white's scale to a BRDF, and back to the files' RGB.
#[derive(Debug, Clone, PartialEq)]
pub struct Photometry {
    /// XYZ → linear RGB of the configured primaries.
    xyz_to_rgb: Matrix3<f64>,
    white: Xyz,
    white_rgb: [f64; 3],
    reflectance: f64,
    rgb_scale: f64,
}

impl Photometry {
    /// `white`: the configured white (its XYZ on the captures' scale); `reflectance`: what
    /// reflectance that white stands for; `rgb_scale`: the factor from the files' RGB to the
    /// white's scale.
    pub fn new(
        primaries: RgbPrimaries,
        white: White,
        reflectance: f64,
        rgb_scale: f64,
    ) -> Result<Self, ExportError> {
        if !(reflectance > 0.0 && reflectance.is_finite()) {
            return Err(ExportError::BadReflectance(reflectance));
        }
        if !(rgb_scale > 0.0 && rgb_scale.is_finite()) {
            return Err(ExportError::BadScale(rgb_scale));
        }
        let m = Matrix3::from_row_slice(&RgbToXyz::new(primaries).matrix().concat());
        let xyz_to_rgb = m.try_inverse().ok_or(ExportError::SingularPrimaries)?;
        let w = white.xyz();
        let v = xyz_to_rgb * Vector3::new(w[0], w[1], w[2]);
        let white_rgb = [v[0], v[1], v[2]];
        if !white_rgb.iter().all(|c| *c > 0.0 && c.is_finite()) {
            return Err(ExportError::BadWhite(white_rgb));
        }
        Ok(Photometry {
            xyz_to_rgb,
            white: w,
            white_rgb,
            reflectance,
            rgb_scale,
        })
    }

    /// The white's XYZ and RGB (the divisors of `relative_rgb`).
    pub fn white(&self) -> (Xyz, [f64; 3]) {
        (self.white, self.white_rgb)
    }

    /// Linear RGB of the configured primaries, on the white's scale.
    pub fn rgb(&self, xyz: Xyz) -> [f64; 3] {
        let v = self.xyz_to_rgb * Vector3::new(xyz[0], xyz[1], xyz[2]);
        [v[0], v[1], v[2]]
    }

    /// Each channel relative to the white's (a white standard: (1, 1, 1) × its reflectance
    /// ÷ `reflectance`).
    pub fn relative_rgb(&self, xyz: Xyz) -> [f64; 3] {
        let v = self.rgb(xyz);
        [
            v[0] / self.white_rgb[0],
            v[1] / self.white_rgb[1],
            v[2] / self.white_rgb[2],
        ]
    }

    /// The BRDF (sr⁻¹) per RGB channel of a capture whose XYZ (cos θi included, drift divided
    /// out) is `xyz`, lit at cos θi = `cos_i`. None for light at or beyond grazing.
    pub fn brdf_rgb(&self, xyz: Xyz, cos_i: f64) -> Option<[f64; 3]> {
        if !(cos_i > 1e-6) || !xyz.iter().all(|v| v.is_finite()) {
            return None;
        }
        let k = self.reflectance / (std::f64::consts::PI * cos_i);
        let r = self.relative_rgb(xyz);
        Some([r[0] * k, r[1] * k, r[2] * k])
    }

    /// The BRDF of the luminance (sr⁻¹): Y / the white's Y × ρ / (π cos θi).
    pub fn brdf_y(&self, xyz: Xyz, cos_i: f64) -> Option<f64> {
        if !(cos_i > 1e-6) || !xyz[1].is_finite() {
            return None;
        }
        Some(xyz[1] / self.white[1] * self.reflectance / (std::f64::consts::PI * cos_i))
    }

    /// The factors that divide the drift out of a capture's image, per channel of the files'
    /// RGB: the file's mean RGB over the corrected XYZ brought back to the files' scale. Exact
    /// for the capture's mean colour; for a pure gain drift the three are g(t) and exact for
    /// every pixel. None when a channel is not positive.
    pub fn image_factors(&self, mean_rgb: [f64; 3], corrected_xyz: Xyz) -> Option<[f64; 3]> {
        let c = self.rgb(corrected_xyz);
        let mut out = [0.0; 3];
        for k in 0..3 {
            let corrected = c[k] / self.rgb_scale;
            let f = mean_rgb[k] / corrected;
            if !(corrected > 0.0 && mean_rgb[k] > 0.0 && f.is_finite()) {
                return None;
            }
            out[k] = f;
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn photometry(reflectance: f64) -> Photometry {
        Photometry::new(
            RgbPrimaries::SrgbIec,
            White::d65_scaled(100.0).unwrap(),
            reflectance,
            100.0,
        )
        .unwrap()
    }

    #[test]
    fn a_lambertian_sample_exports_as_its_albedo_over_pi_at_every_incidence() {
        let p = photometry(1.0);
        let conv = RgbToXyz::new(RgbPrimaries::SrgbIec);
        let albedo = [0.5, 0.4, 0.3];
        for theta in [0.0f64, 30.0, 60.0, 75.0] {
            let c = theta.to_radians().cos();
            // the files' RGB of a Lambertian sample under a lamp that makes a white read 1
            let file = [albedo[0] * c, albedo[1] * c, albedo[2] * c];
            let xyz = conv.convert_scaled(file, 100.0);
            let f = p.brdf_rgb(xyz, c).unwrap();
            for k in 0..3 {
                let want = albedo[k] / std::f64::consts::PI;
                // the IEC matrix's rounding leaves D65 at RGB 1 within 1e-4
                assert!((f[k] / want - 1.0).abs() < 2e-4, "{theta} {k}: {f:?}");
            }
            let y = p.brdf_y(xyz, c).unwrap();
            assert!((y - xyz[1] / 100.0 / std::f64::consts::PI / c).abs() < 1e-12);
        }
    }

    #[test]
    fn the_white_reflectance_scales_the_brdf() {
        let xyz = [40.0, 42.0, 45.0];
        let a = photometry(1.0).brdf_rgb(xyz, 0.8).unwrap();
        let b = photometry(0.5).brdf_rgb(xyz, 0.8).unwrap();
        for k in 0..3 {
            assert!((b[k] / a[k] - 0.5).abs() < 1e-12);
        }
    }

    #[test]
    fn grazing_light_and_bad_settings_give_no_brdf() {
        let p = photometry(1.0);
        assert_eq!(p.brdf_rgb([1.0; 3], 0.0), None);
        assert_eq!(p.brdf_rgb([1.0; 3], f64::NAN), None);
        assert_eq!(p.brdf_rgb([f64::NAN, 1.0, 1.0], 0.5), None);
        let w = White::d65_scaled(100.0).unwrap();
        assert_eq!(
            Photometry::new(RgbPrimaries::SrgbIec, w, 0.0, 1.0),
            Err(ExportError::BadReflectance(0.0))
        );
        assert_eq!(
            Photometry::new(RgbPrimaries::SrgbIec, w, 1.0, f64::INFINITY),
            Err(ExportError::BadScale(f64::INFINITY))
        );
        // a white outside the primaries' gamut has a negative channel
        let green = White::new([10.0, 100.0, 10.0]).unwrap();
        assert!(matches!(
            Photometry::new(RgbPrimaries::SrgbIec, green, 1.0, 1.0),
            Err(ExportError::BadWhite(_))
        ));
    }

    #[test]
    fn the_gain_follows_the_probe_curve_or_the_rate_with_its_steps() {
        let mut d = DriftCorrection::none();
        assert_eq!(d.gain(10_000.0), 1.0);
        d.gain_source = GainSource::IsotropyClasses;
        d.rate_pct_per_h = -1.0;
        d.steps = vec![GainStep {
            t_h: 2.0,
            ln_size: (0.97f64).ln(),
        }];
        assert!((d.gain(3600.0) - (-0.01f64).exp()).abs() < 1e-12);
        assert!((d.gain(3.0 * 3600.0) - (-0.03f64).exp() * 0.97).abs() < 1e-12);
        d.gain_source = GainSource::ProbeCurve;
        d.curve = vec![(0.0, 1.0), (1.0, 0.99), (2.0, 0.95)];
        assert!(
            (d.gain(1.5 * 3600.0) - (0.99f64.ln() * 0.5 + 0.95f64.ln() * 0.5).exp()).abs() < 1e-12
        );
        // held at the ends
        assert!((d.gain(5.0 * 3600.0) - 0.95).abs() < 1e-12);
        assert!((d.gain(-10.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn colour_rates_divide_x_and_z_and_the_image_factors_undo_them_on_the_mean() {
        let mut d = DriftCorrection::none();
        d.gain_source = GainSource::IsotropyClasses;
        d.rate_pct_per_h = -2.0;
        d.colour = Some(ColourRates {
            x_rate_pct_per_h: 0.5,
            z_rate_pct_per_h: -1.0,
            k_per_h: -20.0,
            se_k_per_h: 1.0,
        });
        let t = 2.0 * 3600.0;
        let f = d.xyz_factors(t);
        let g = (-0.04f64).exp();
        assert!((f[1] - g).abs() < 1e-12);
        assert!((f[0] - g * (0.01f64).exp()).abs() < 1e-12);
        assert!((f[2] - g * (-0.02f64).exp()).abs() < 1e-12);
        // the factors on the file's RGB give back the corrected colour
        let p = photometry(1.0);
        let conv = RgbToXyz::new(RgbPrimaries::SrgbIec);
        let file = [0.3, 0.25, 0.2];
        let xyz = conv.convert_scaled(file, 100.0);
        let corrected = d.correct(xyz, t);
        let k = p.image_factors(file, corrected).unwrap();
        let back = conv.convert_scaled([file[0] / k[0], file[1] / k[1], file[2] / k[2]], 100.0);
        for c in 0..3 {
            assert!((back[c] / corrected[c] - 1.0).abs() < 1e-9);
        }
        // a pure gain: every factor is g
        d.colour = None;
        let k = p.image_factors(file, d.correct(xyz, t)).unwrap();
        for c in k {
            assert!((c - g).abs() < 1e-9);
        }
        assert_eq!(p.image_factors([0.0, 0.2, 0.2], corrected), None);
    }
}
