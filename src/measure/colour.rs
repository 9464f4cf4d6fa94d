//! Colour: linear RGB → CIE XYZ, spectral → XYZ, XYZ → CIE 1976 L*a*b*, and colour differences
//! (ΔE*ab, ΔC*ab, ΔH*ab, CIEDE2000). f64 throughout, no allocation on the per-capture path.
//!
//! Conventions:
//! - XYZ is on the scale of the white it is compared with; with the default white Y_n = 100
//!   (the paper's "usual magnitude [0..100]").
//! - Hue angles are in degrees, in `[0, 360)`.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// CIE XYZ tristimulus values.
pub type Xyz = [f64; 3];
/// Linear RGB (scene-referred, no transfer function).
pub(crate) type Rgb = [f64; 3];

/// CIE 1976 L*a*b*.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lab {
    pub l: f64,
    pub a: f64,
    pub b: f64,
}

impl Lab {
    pub const fn new(l: f64, a: f64, b: f64) -> Self {
        Lab { l, a, b }
    }
    /// Chroma C*ab.
    pub fn chroma(&self) -> f64 {
        self.a.hypot(self.b)
    }
    /// Hue angle h_ab in degrees, `[0, 360)`; 0 for a neutral colour.
    pub fn hue_deg(&self) -> f64 {
        hue_deg(self.a, self.b)
    }
}

fn hue_deg(a: f64, b: f64) -> f64 {
    if a == 0.0 && b == 0.0 {
        return 0.0;
    }
    let h = b.atan2(a).to_degrees();
    if h < 0.0 {
        h + 360.0
    } else {
        h
    }
}

#[derive(Debug, Error, PartialEq)]
pub enum ColourError {
    #[error("white point must have finite, positive X, Y and Z, got {0:?}")]
    BadWhite(Xyz),
    #[error("spectral band set is empty")]
    NoBands,
    #[error("band wavelengths must be strictly increasing (band {index}: {wavelength} nm)")]
    BandsNotIncreasing { index: usize, wavelength: f64 },
    #[error("band {wavelength} nm lies outside the observer table {min}–{max} nm")]
    BandOutOfRange { wavelength: f64, min: f64, max: f64 },
    #[error("expected {expected} spectral values, got {got}")]
    SpectrumLength { expected: usize, got: usize },
    #[error("RGB→XYZ matrix is singular or not finite")]
    SingularMatrix,
    #[error("chromaticity must satisfy 0 < y and x + y ≤ 1, got ({x}, {y})")]
    BadChromaticity { x: f64, y: f64 },
    #[error("a lamp colour temperature of {kelvin} K is outside 1000–20,000 K")]
    BadTemperature { kelvin: f64 },
}

// ---------------------------------------------------------------------------------------------
// RGB → XYZ
// ---------------------------------------------------------------------------------------------

/// Which linear-RGB → XYZ matrix to use.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RgbPrimaries {
    /// The rounded matrix of IEC 61966-2-1 (sRGB), the paper's Eq. 5 with its 0.4142 slip
    /// corrected to 0.4124. This is the default, so results match the paper's convention.
    #[default]
    SrgbIec,
    /// Derived from the BT.709 primaries and the D65 white chromaticity (x, y) = (0.3127, 0.3290)
    /// at full double precision.
    SrgbDerived,
}

/// The IEC 61966-2-1 matrix (the paper's Eq. 5, first entry corrected to 0.4124).
pub(crate) const SRGB_IEC: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// BT.709 primaries and D65 white as CIE xy chromaticities.
pub(crate) const BT709_XY: [[f64; 2]; 3] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]];
pub(crate) const D65_XY: [f64; 2] = [0.3127, 0.3290];

/// Derive the RGB → XYZ matrix from primaries and a white chromaticity (white maps to Y = 1).
pub(crate) fn rgb_to_xyz_matrix_from_primaries(
    primaries: [[f64; 2]; 3],
    white: [f64; 2],
) -> Result<Matrix3<f64>, ColourError> {
    let xyz_of = |xy: [f64; 2]| -> Result<Vector3<f64>, ColourError> {
        let (x, y) = (xy[0], xy[1]);
        if !(y > 0.0 && x >= 0.0 && x + y <= 1.0) {
            return Err(ColourError::BadChromaticity { x, y });
        }
        Ok(Vector3::new(x / y, 1.0, (1.0 - x - y) / y))
    };
    let p = Matrix3::from_columns(&[
        xyz_of(primaries[0])?,
        xyz_of(primaries[1])?,
        xyz_of(primaries[2])?,
    ]);
    let w = xyz_of(white)?;
    let s = p.lu().solve(&w).ok_or(ColourError::SingularMatrix)?;
    Ok(p * Matrix3::from_diagonal(&s))
}

/// A linear RGB → XYZ conversion (3×3 matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RgbToXyz {
    m: Matrix3<f64>,
}

impl RgbToXyz {
    pub fn new(primaries: RgbPrimaries) -> Self {
        match primaries {
            RgbPrimaries::SrgbIec => RgbToXyz {
                m: Matrix3::from_row_slice(&SRGB_IEC.concat()),
            },
            RgbPrimaries::SrgbDerived => RgbToXyz {
                // The BT.709/D65 chromaticities are valid constants; the fallback never triggers
                // but keeps this constructor infallible without an unwrap.
                m: rgb_to_xyz_matrix_from_primaries(BT709_XY, D65_XY)
                    .unwrap_or_else(|_| Matrix3::from_row_slice(&SRGB_IEC.concat())),
            },
        }
    }
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        let m = &self.m;
        [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ]
    }
    #[inline]
    pub fn convert(&self, rgb: Rgb) -> Xyz {
        let v = self.m * Vector3::new(rgb[0], rgb[1], rgb[2]);
        [v[0], v[1], v[2]]
    }

    /// `rgb` scaled by `scale` (the files' values onto the white's scale), then converted.
    pub(crate) fn convert_scaled(&self, rgb: Rgb, scale: f64) -> Xyz {
        self.convert([rgb[0] * scale, rgb[1] * scale, rgb[2] * scale])
    }
}

// ---------------------------------------------------------------------------------------------
// Spectral → XYZ
// ---------------------------------------------------------------------------------------------

/// The CIE 1931 2° observer and D65 at 5 nm, 380–780 nm (colour-science snapshot of the CIE
/// tables), embedded so the core needs no file.
const CMF_D65_5NM: &str = include_str!("data/cmf1931_d65_5nm_380_780.csv");

/// One row of an observer/illuminant table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObserverRow {
    pub wavelength: f64,
    pub xbar: f64,
    pub ybar: f64,
    pub zbar: f64,
    pub illuminant: f64,
}

/// Parse an observer table in the reference CSV format
/// (`wavelength_nm,xbar,ybar,zbar,ILLUMINANT`, `#` comments).
pub fn parse_observer_table(text: &str) -> Result<Vec<ObserverRow>, String> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("wavelength") {
            continue;
        }
        let f: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", n + 1))?;
        if f.len() != 5 {
            return Err(format!(
                "line {}: expected 5 columns, got {}",
                n + 1,
                f.len()
            ));
        }
        rows.push(ObserverRow {
            wavelength: f[0],
            xbar: f[1],
            ybar: f[2],
            zbar: f[3],
            illuminant: f[4],
        });
    }
    Ok(rows)
}

/// The embedded CIE 1931 2° / D65 table at 5 nm.
pub(crate) fn cie1931_d65_5nm() -> Vec<ObserverRow> {
    // The embedded table is part of the build and is tested; an empty table can only follow
    // from a broken build, and then every spectral conversion reports `NoBands`.
    parse_observer_table(CMF_D65_5NM).unwrap_or_default()
}

fn interpolate_row(table: &[ObserverRow], wl: f64) -> Option<ObserverRow> {
    let first = table.first()?;
    let last = table.last()?;
    if wl < first.wavelength - 1e-9 || wl > last.wavelength + 1e-9 {
        return None;
    }
    let k = table.partition_point(|r| r.wavelength < wl);
    if k < table.len() && (table[k].wavelength - wl).abs() < 1e-9 {
        return Some(table[k]);
    }
    if k == 0 {
        return Some(*first);
    }
    let (a, b) = (table[k - 1], table[k.min(table.len() - 1)]);
    let t = (wl - a.wavelength) / (b.wavelength - a.wavelength);
    let lerp = |x: f64, y: f64| x + t * (y - x);
    Some(ObserverRow {
        wavelength: wl,
        xbar: lerp(a.xbar, b.xbar),
        ybar: lerp(a.ybar, b.ybar),
        zbar: lerp(a.zbar, b.zbar),
        illuminant: lerp(a.illuminant, b.illuminant),
    })
}

/// Precomputed weights that turn a reflectance spectrum on a given band set into XYZ under an
/// illuminant, normalised so that a perfect reflector (all ones) has Y = 100.
///
/// The observer and illuminant are linearly interpolated at the band centres; each band is
/// weighted by its width (half the distance to each neighbour; an end band mirrors its inner
/// half-width). This is the rectangle rule on the band set, exact for the 5 nm and 10 nm CIE
/// tables evaluated at their own wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralToXyz {
    wavelengths: Vec<f64>,
    weights: Vec<[f64; 3]>,
    white: Xyz,
}

impl SpectralToXyz {
    /// Band set `wavelengths` (nm, strictly increasing) with the embedded CIE 1931 2°/D65 table.
    pub fn d65(wavelengths: &[f64]) -> Result<Self, ColourError> {
        Self::with_table(wavelengths, &cie1931_d65_5nm())
    }

    /// Band set with an explicit observer/illuminant table.
    pub fn with_table(wavelengths: &[f64], table: &[ObserverRow]) -> Result<Self, ColourError> {
        if wavelengths.is_empty() || table.is_empty() {
            return Err(ColourError::NoBands);
        }
        for (i, w) in wavelengths.windows(2).enumerate() {
            if !(w[1] > w[0]) {
                return Err(ColourError::BandsNotIncreasing {
                    index: i + 1,
                    wavelength: w[1],
                });
            }
        }
        let n = wavelengths.len();
        let widths: Vec<f64> = (0..n)
            .map(|i| {
                if n == 1 {
                    return 1.0;
                }
                let left = if i > 0 {
                    (wavelengths[i] - wavelengths[i - 1]) / 2.0
                } else {
                    (wavelengths[1] - wavelengths[0]) / 2.0
                };
                let right = if i + 1 < n {
                    (wavelengths[i + 1] - wavelengths[i]) / 2.0
                } else {
                    (wavelengths[n - 1] - wavelengths[n - 2]) / 2.0
                };
                left + right
            })
            .collect();
        let mut raw = Vec::with_capacity(n);
        for (&wl, &dw) in wavelengths.iter().zip(&widths) {
            let r = interpolate_row(table, wl).ok_or(ColourError::BandOutOfRange {
                wavelength: wl,
                min: table[0].wavelength,
                max: table[table.len() - 1].wavelength,
            })?;
            raw.push([
                r.illuminant * r.xbar * dw,
                r.illuminant * r.ybar * dw,
                r.illuminant * r.zbar * dw,
            ]);
        }
        let ysum: f64 = raw.iter().map(|w| w[1]).sum();
        if ysum <= 0.0 {
            return Err(ColourError::NoBands);
        }
        let k = 100.0 / ysum;
        let weights: Vec<[f64; 3]> = raw.iter().map(|w| [w[0] * k, w[1] * k, w[2] * k]).collect();
        let mut white = [0.0; 3];
        for w in &weights {
            for c in 0..3 {
                white[c] += w[c];
            }
        }
        Ok(SpectralToXyz {
            wavelengths: wavelengths.to_vec(),
            weights,
            white,
        })
    }

    /// XYZ of the perfect reflector under the same bands (Y = 100): the white for L*a*b*.
    pub fn white(&self) -> Xyz {
        self.white
    }

    /// XYZ of a reflectance spectrum sampled at the band set.
    pub fn convert(&self, reflectance: &[f64]) -> Result<Xyz, ColourError> {
        if reflectance.len() != self.weights.len() {
            return Err(ColourError::SpectrumLength {
                expected: self.weights.len(),
                got: reflectance.len(),
            });
        }
        let mut xyz = [0.0; 3];
        for (r, w) in reflectance.iter().zip(&self.weights) {
            for c in 0..3 {
                xyz[c] += r * w[c];
            }
        }
        Ok(xyz)
    }
}

/// Evenly spaced bands, e.g. `bands(400.0, 10.0, 30)` = 400, 410, …, 690 nm.
pub fn bands(start: f64, step: f64, count: usize) -> Vec<f64> {
    (0..count).map(|i| start + step * i as f64).collect()
}

// ---------------------------------------------------------------------------------------------
// XYZ → L*a*b*
// ---------------------------------------------------------------------------------------------

/// The reference white for L*a*b*: finite and positive in all three components.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct White(Xyz);

impl White {
    pub fn new(xyz: Xyz) -> Result<Self, ColourError> {
        if xyz.iter().all(|v| v.is_finite() && *v > 0.0) {
            Ok(White(xyz))
        } else {
            Err(ColourError::BadWhite(xyz))
        }
    }
    /// D65 chromaticity (x, y) = (0.3127, 0.3290) scaled to luminance `y`.
    pub fn d65_scaled(y: f64) -> Result<Self, ColourError> {
        let [x, yy] = D65_XY;
        Self::new([x / yy * y, y, (1.0 - x - yy) / yy * y])
    }
    pub fn xyz(&self) -> Xyz {
        self.0
    }
}

const DELTA: f64 = 6.0 / 29.0;

#[inline]
fn lab_f(t: f64) -> f64 {
    if t > DELTA * DELTA * DELTA {
        t.cbrt()
    } else {
        t / (3.0 * DELTA * DELTA) + 4.0 / 29.0
    }
}

#[cfg(test)]
fn lab_f_inv(f: f64) -> f64 {
    if f > DELTA {
        f * f * f
    } else {
        3.0 * DELTA * DELTA * (f - 4.0 / 29.0)
    }
}

/// XYZ → CIE 1976 L*a*b* relative to `white`. Negative and near-zero XYZ use the linear
/// segment below (6/29)³, so L* is continuous and finite down to and below black.
pub fn xyz_to_lab(xyz: Xyz, white: White) -> Lab {
    let w = white.0;
    let fx = lab_f(xyz[0] / w[0]);
    let fy = lab_f(xyz[1] / w[1]);
    let fz = lab_f(xyz[2] / w[2]);
    Lab {
        l: 116.0 * fy - 16.0,
        a: 500.0 * (fx - fy),
        b: 200.0 * (fy - fz),
    }
}

/// CIE 1976 L*a*b* → XYZ relative to `white` (the exact inverse of [`xyz_to_lab`]; the tests'
/// round trip).
#[cfg(test)]
fn lab_to_xyz(lab: Lab, white: White) -> Xyz {
    let w = white.0;
    let fy = (lab.l + 16.0) / 116.0;
    let fx = fy + lab.a / 500.0;
    let fz = fy - lab.b / 200.0;
    [
        w[0] * lab_f_inv(fx),
        w[1] * lab_f_inv(fy),
        w[2] * lab_f_inv(fz),
    ]
}

// ---------------------------------------------------------------------------------------------
// Colour differences
// ---------------------------------------------------------------------------------------------

/// CIE 1976 total colour difference ΔE*ab.
pub fn delta_e76(a: Lab, b: Lab) -> f64 {
    let (dl, da, db) = (b.l - a.l, b.a - a.a, b.b - a.b);
    (dl * dl + da * da + db * db).sqrt()
}

/// Chroma difference ΔC*ab = C*₂ − C*₁ (signed).
pub fn delta_c76(a: Lab, b: Lab) -> f64 {
    b.chroma() - a.chroma()
}

/// Hue difference ΔH*ab, signed by the hue rotation from `a` to `b`: negative when the
/// rotation is clockwise (a₁b₂ − b₁a₂ < 0), positive otherwise, including for opposite hues.
/// NaN when any coordinate is NaN: a difference that cannot be computed never reads as a match.
///
/// ΔH = 2·√(C₁C₂)·sin(|Δh|/2) with the hue angle difference Δh = atan2(a₁b₂ − b₁a₂,
/// a₁a₂ + b₁b₂) taken from the two (a, b) vectors directly. The cross product is a compensated
/// difference of products (one fused multiply-add recovers the rounding error of the other
/// product), so it is accurate to a few ulps even for nearly equal hues: ΔH is exactly 0 for
/// identical colours, |ΔH| ≤ ΔE*ab to rounding, and hue differences far below √ε·C are
/// resolved. The textbook ΔH² = 2(C₁C₂ − a₁a₂ − b₁b₂) and ΔE² − ΔL² − ΔC² both lose every
/// difference below about √ε·C to cancellation.
pub fn delta_h76(a: Lab, b: Lab) -> f64 {
    if [a.l, a.a, a.b, b.l, b.a, b.b].iter().any(|v| v.is_nan()) {
        return f64::NAN;
    }
    let cross = cross2(a.a, a.b, b.a, b.b);
    let dot = a.a.mul_add(b.a, a.b * b.b);
    let dh = cross.atan2(dot).abs();
    let mag = 2.0 * a.chroma().sqrt() * b.chroma().sqrt() * (dh / 2.0).sin();
    if cross < 0.0 {
        -mag
    } else {
        mag
    }
}

/// a₁b₂ − b₁a₂, accurate to a few ulps of the result even where the two products nearly cancel
/// (Kahan's compensated 2×2 determinant): `e` is exactly the rounding error of the product b₁a₂.
fn cross2(a1: f64, b1: f64, a2: f64, b2: f64) -> f64 {
    let w = b1 * a2;
    let e = (-b1).mul_add(a2, w);
    let f = a1.mul_add(b2, -w);
    f + e
}

/// √(C⁷ / (C⁷ + 25⁷)), the chroma weight in CIEDE2000's G and R_C, without overflow. Where C⁷
/// is finite the textbook quotient is kept, so every ordinary result is bit for bit the
/// textbook one; where it overflows (C above about 1e44), with r = 25/C the same value is
/// 1/√(1 + r⁷). 0 at C = 0, tends to 1 as C grows, NaN for NaN.
fn chroma_weight(c: f64) -> f64 {
    const POW25_7: f64 = 6_103_515_625.0; // 25^7
    let c7 = c.powi(7);
    if c7.is_finite() {
        (c7 / (c7 + POW25_7)).sqrt()
    } else {
        (1.0 / (1.0 + (25.0 / c).powi(7))).sqrt()
    }
}

/// CIEDE2000 colour difference (kL = kC = kH = 1), following Sharma, Wu & Dalal (2005),
/// including the C′₁C′₂ = 0 branches and their Eq. 14 for the mean hue.
///
/// NaN when any input is NaN (a difference that cannot be computed never reads as a match).
/// Finite for chromas up to about 1e300: the C̄⁷ terms and √(C′₁C′₂) switch to forms that do not
/// overflow where the textbook ones would.
pub fn ciede2000(lab1: Lab, lab2: Lab) -> f64 {
    ciede2000_weighted(lab1, lab2, 1.0, 1.0, 1.0)
}

/// CIEDE2000 with parametric factors kL, kC, kH.
pub fn ciede2000_weighted(lab1: Lab, lab2: Lab, kl: f64, kc: f64, kh: f64) -> f64 {
    if [lab1.l, lab1.a, lab1.b, lab2.l, lab2.a, lab2.b, kl, kc, kh]
        .iter()
        .any(|v| v.is_nan())
    {
        return f64::NAN;
    }
    let c1 = lab1.chroma();
    let c2 = lab2.chroma();
    let cbar = (c1 + c2) / 2.0;
    let g = 0.5 * (1.0 - chroma_weight(cbar));
    let a1p = (1.0 + g) * lab1.a;
    let a2p = (1.0 + g) * lab2.a;
    let c1p = a1p.hypot(lab1.b);
    let c2p = a2p.hypot(lab2.b);
    let h1p = hue_deg(a1p, lab1.b);
    let h2p = hue_deg(a2p, lab2.b);

    let dlp = lab2.l - lab1.l;
    let dcp = c2p - c1p;
    // C′₁C′₂ = 0 decides Sharma's neutral branches; testing the factors keeps the product's
    // underflow out of that decision
    let neutral = c1p == 0.0 || c2p == 0.0;
    let dhp = if neutral {
        0.0
    } else {
        let d = h2p - h1p;
        if d > 180.0 {
            d - 360.0
        } else if d < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    // √(C′₁C′₂), as √C′₁·√C′₂ only where the product overflows (chromas above about 1e154)
    let cprod = c1p * c2p;
    let root = if cprod.is_finite() {
        cprod.sqrt()
    } else {
        c1p.sqrt() * c2p.sqrt()
    };
    let dhp_big = 2.0 * root * (dhp.to_radians() / 2.0).sin();

    let lbarp = (lab1.l + lab2.l) / 2.0;
    let cbarp = (c1p + c2p) / 2.0;
    let hbarp = if neutral {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        (h1p + h2p) / 2.0
    } else if h1p + h2p < 360.0 {
        (h1p + h2p + 360.0) / 2.0
    } else {
        (h1p + h2p - 360.0) / 2.0
    };

    let t = 1.0 - 0.17 * (hbarp - 30.0).to_radians().cos()
        + 0.24 * (2.0 * hbarp).to_radians().cos()
        + 0.32 * (3.0 * hbarp + 6.0).to_radians().cos()
        - 0.20 * (4.0 * hbarp - 63.0).to_radians().cos();
    let dtheta = 30.0 * (-((hbarp - 275.0) / 25.0).powi(2)).exp();
    let rc = 2.0 * chroma_weight(cbarp);
    let l50 = (lbarp - 50.0).powi(2);
    let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let sc = 1.0 + 0.045 * cbarp;
    let sh = 1.0 + 0.015 * cbarp * t;
    let rt = -(2.0 * dtheta).to_radians().sin() * rc;

    let tl = dlp / (kl * sl);
    let tc = dcp / (kc * sc);
    let th = dhp_big / (kh * sh);
    // the form is positive semi-definite (|R_T| < 2); a rounding-negative sum is 0, while a NaN
    // (from infinite inputs) stays NaN instead of reading as a perfect match
    let s = tl * tl + tc * tc + th * th + rt * tc * th;
    if s < 0.0 {
        0.0
    } else {
        s.sqrt()
    }
}

/// All the differences the paper's Table 2 reports for one pair, on already re-corrected XYZ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ColourDifference {
    /// |X₂ − X₁|, |Y₂ − Y₁|, |Z₂ − Z₁|
    pub abs_dxyz: [f64; 3],
    pub de76: f64,
    /// |ΔC*ab|
    pub dc: f64,
    /// |ΔH*ab|
    pub dh: f64,
    pub de2000: f64,
}

/// Compare two XYZ values under one white.
pub fn colour_difference(xyz1: Xyz, xyz2: Xyz, white: White) -> ColourDifference {
    let l1 = xyz_to_lab(xyz1, white);
    let l2 = xyz_to_lab(xyz2, white);
    ColourDifference {
        abs_dxyz: [
            (xyz2[0] - xyz1[0]).abs(),
            (xyz2[1] - xyz1[1]).abs(),
            (xyz2[2] - xyz1[2]).abs(),
        ],
        de76: delta_e76(l1, l2),
        dc: delta_c76(l1, l2).abs(),
        dh: delta_h76(l1, l2).abs(),
        de2000: ciede2000(l1, l2),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_matrix_matches_iec_rounding() {
        let d = RgbToXyz::new(RgbPrimaries::SrgbDerived).matrix();
        for r in 0..3 {
            for c in 0..3 {
                assert!(
                    (d[r][c] - SRGB_IEC[r][c]).abs() <= 0.00006,
                    "{r},{c}: {}",
                    d[r][c]
                );
            }
        }
        // the white (1,1,1) maps to the D65 white with Y = 1
        let w = RgbToXyz::new(RgbPrimaries::SrgbDerived).convert([1.0, 1.0, 1.0]);
        let d65 = White::d65_scaled(1.0).unwrap().xyz();
        for c in 0..3 {
            assert!((w[c] - d65[c]).abs() < 1e-12);
        }
    }

    #[test]
    fn lab_round_trip() {
        let w = White::d65_scaled(100.0).unwrap();
        for xyz in [
            [41.24, 21.26, 1.93],
            [0.001, 0.001, 0.001],
            [95.0, 100.0, 108.9],
            [-0.5, 0.2, 3.0],
        ] {
            let back = lab_to_xyz(xyz_to_lab(xyz, w), w);
            for c in 0..3 {
                assert!((back[c] - xyz[c]).abs() < 1e-10, "{xyz:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn bad_white_is_rejected() {
        assert!(White::new([0.0, 1.0, 1.0]).is_err());
        assert!(White::new([f64::NAN, 1.0, 1.0]).is_err());
        assert!(White::new([1.0, -1.0, 1.0]).is_err());
    }

    #[test]
    fn delta_h_sign_and_magnitude() {
        let a = Lab::new(50.0, 10.0, 0.0);
        let b = Lab::new(50.0, 0.0, 10.0);
        let dh = delta_h76(a, b);
        // the chord between two points of chroma 10 at 90° apart
        assert!((dh - 10.0 * 2f64.sqrt()).abs() < 1e-12);
        assert!(delta_h76(b, a) < 0.0);
    }
}
