//! Averaging one capture (BTF → BRDF): the mean linear RGB over a region of interest, with
//! per-capture pixel statistics. Works on an already decoded interleaved RGB f32 buffer; the
//! decoders live in the shell (`crate::decode`).
//!
//! Arithmetic: every row is summed in f64 (two interleaved partial sums, even and odd pixels)
//! and the row sums are added in f64, so a 1e36 pixel
//! neither overflows (an f32 sum would) nor swamps the rounding of the other rows. Non-finite
//! pixels (any channel NaN or ±Inf) are counted and excluded from the mean; negative and
//! clipped pixels are counted and included.

use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum AverageError {
    #[error("buffer holds {got} floats, expected {expected} for {width}×{height} RGB")]
    BufferSize {
        got: usize,
        expected: usize,
        width: usize,
        height: usize,
    },
    #[error("region of interest {roi} leaves no pixel of the {width}×{height} image")]
    EmptyRoi {
        roi: String,
        width: usize,
        height: usize,
    },
    #[error("no finite pixel in the region of interest ({nonfinite} non-finite of {pixels})")]
    NoFinitePixel { pixels: u64, nonfinite: u64 },
}

/// Which pixels count: the whole image, a rectangle, or all but a border (the sample holder).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Roi {
    #[default]
    Full,
    /// x, y of the top-left pixel, width, height (clipped to the image).
    Rect {
        x: usize,
        y: usize,
        width: usize,
        height: usize,
    },
    /// Leave out `pixels` on every side.
    Margin { pixels: usize },
    /// Leave out this fraction of the width/height on every side (0 ≤ f < 0.5).
    MarginFraction { fraction: f64 },
}

impl Roi {
    /// Parse the CLI form: `full`, `rect:X,Y,W,H`, `margin:PIXELS`, `margin:F%`.
    pub fn parse(s: &str) -> Result<Roi, String> {
        let s = s.trim();
        if s == "full" {
            return Ok(Roi::Full);
        }
        if let Some(r) = s.strip_prefix("rect:") {
            let v: Vec<usize> = r
                .split(',')
                .map(|t| t.trim().parse::<usize>())
                .collect::<Result<_, _>>()
                .map_err(|e| format!("rect: {e}"))?;
            if v.len() != 4 {
                return Err("rect needs X,Y,W,H".into());
            }
            return Ok(Roi::Rect {
                x: v[0],
                y: v[1],
                width: v[2],
                height: v[3],
            });
        }
        if let Some(m) = s.strip_prefix("margin:") {
            if let Some(p) = m.strip_suffix('%') {
                let f: f64 = p.trim().parse().map_err(|e| format!("margin: {e}"))?;
                if !(0.0..50.0).contains(&f) {
                    return Err("margin percentage must be in [0, 50)".into());
                }
                return Ok(Roi::MarginFraction {
                    fraction: f / 100.0,
                });
            }
            let px: usize = m.trim().parse().map_err(|e| format!("margin: {e}"))?;
            return Ok(Roi::Margin { pixels: px });
        }
        Err(format!(
            "unknown region '{s}': use full, rect:X,Y,W,H, margin:PIXELS or margin:PERCENT%"
        ))
    }

    /// The pixel rectangle (x0, y0, x1, y1), half-open, for an image of the given size.
    pub(crate) fn bounds(&self, width: usize, height: usize) -> (usize, usize, usize, usize) {
        match *self {
            Roi::Full => (0, 0, width, height),
            Roi::Rect {
                x,
                y,
                width: w,
                height: h,
            } => {
                let x0 = x.min(width);
                let y0 = y.min(height);
                (
                    x0,
                    y0,
                    x.saturating_add(w).min(width),
                    y.saturating_add(h).min(height),
                )
            }
            Roi::Margin { pixels } => (
                pixels.min(width),
                pixels.min(height),
                width.saturating_sub(pixels),
                height.saturating_sub(pixels),
            ),
            Roi::MarginFraction { fraction } => {
                let f = if fraction.is_finite() {
                    fraction.clamp(0.0, 0.5)
                } else {
                    0.0
                };
                let mx = (width as f64 * f).floor() as usize;
                let my = (height as f64 * f).floor() as usize;
                (mx, my, width.saturating_sub(mx), height.saturating_sub(my))
            }
        }
    }
}

/// Options for averaging.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AverageOptions {
    #[serde(default)]
    pub roi: Roi,
    /// A pixel with any channel at or above this value counts as clipped (saturated).
    /// Default 65504, the largest finite half float: HDR merges that saturate write it.
    #[serde(default = "default_clip")]
    pub clip_level: f32,
    /// A finite pixel whose luminance-like mean (R+G+B)/3 is at or below this counts as dark.
    #[serde(default)]
    pub dark_level: f32,
}

fn default_clip() -> f32 {
    65504.0
}

impl Default for AverageOptions {
    fn default() -> Self {
        AverageOptions {
            roi: Roi::Full,
            clip_level: default_clip(),
            dark_level: 0.0,
        }
    }
}

/// How the three channels of a decoded capture lie in memory.
#[derive(Debug, Clone, Copy)]
pub enum Layout<'a> {
    /// R, G, B, R, G, B, … row-major, top row first (Radiance).
    Interleaved(&'a [f32]),
    /// One plane per channel, each row-major, top row first (OpenEXR).
    Planar(&'a [f32], &'a [f32], &'a [f32]),
}

/// A decoded capture: linear RGB, `width × height` pixels.
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    pub width: usize,
    pub height: usize,
    pub layout: Layout<'a>,
}

fn check_len(got: usize, expected: usize, width: usize, height: usize) -> Result<(), AverageError> {
    if got == expected {
        Ok(())
    } else {
        Err(AverageError::BufferSize {
            got,
            expected,
            width,
            height,
        })
    }
}

impl<'a> RgbView<'a> {
    /// An interleaved RGB buffer of exactly `width × height × 3` floats.
    pub fn new(width: usize, height: usize, data: &'a [f32]) -> Result<Self, AverageError> {
        check_len(
            data.len(),
            width.saturating_mul(height).saturating_mul(3),
            width,
            height,
        )?;
        Ok(RgbView {
            width,
            height,
            layout: Layout::Interleaved(data),
        })
    }

    /// Three planes of exactly `width × height` floats each (the decoder's layout, built directly
    /// by `decode`; the tests build it here).
    #[cfg(test)]
    fn planar(
        width: usize,
        height: usize,
        r: &'a [f32],
        g: &'a [f32],
        b: &'a [f32],
    ) -> Result<Self, AverageError> {
        for p in [r, g, b] {
            check_len(p.len(), width.saturating_mul(height), width, height)?;
        }
        Ok(RgbView {
            width,
            height,
            layout: Layout::Planar(r, g, b),
        })
    }
}

/// The result of averaging one capture.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CaptureStats {
    /// Mean linear RGB over the finite pixels of the region.
    pub mean_rgb: [f64; 3],
    /// Pixels in the region.
    pub pixels: u64,
    /// Pixels with a NaN or infinite channel (excluded from the mean).
    pub nonfinite: u64,
    /// Finite pixels with a negative channel (included).
    pub negative: u64,
    /// Finite pixels with a channel ≥ clip level (included).
    pub clipped: u64,
    /// Finite pixels at or below the dark level (included).
    pub dark: u64,
    /// Largest finite channel value in the region.
    pub max_value: f64,
}

#[derive(Default, Clone, Copy)]
struct RowAcc {
    sum: [f64; 3],
    finite: u64,
    negative: u64,
    clipped: u64,
    dark: u64,
    max: f32,
}

/// Per-lane partial sums of one row. Two lanes (even and odd pixels) break the dependency
/// chain of the f64 additions, which roughly halves the time on an out-of-order core; the
/// summation order is fixed, so results stay bit-identical run to run.
#[derive(Clone, Copy)]
struct Lane {
    s: [f64; 3],
    fin: u64,
    neg: u64,
    clp: u64,
    drk: u64,
    max: f32,
}

impl Lane {
    const ZERO: Lane = Lane {
        s: [0.0; 3],
        fin: 0,
        neg: 0,
        clp: 0,
        drk: 0,
        max: f32::NEG_INFINITY,
    };

    #[inline(always)]
    fn add(&mut self, r: f32, g: f32, b: f32, clip: f32, dark: f32) {
        if r.is_finite() & g.is_finite() & b.is_finite() {
            self.s[0] += r as f64;
            self.s[1] += g as f64;
            self.s[2] += b as f64;
            self.fin += 1;
            self.neg += ((r < 0.0) | (g < 0.0) | (b < 0.0)) as u64;
            let m = r.max(g).max(b);
            self.clp += (m >= clip) as u64;
            self.drk += ((r + g + b) * (1.0 / 3.0) <= dark) as u64;
            self.max = self.max.max(m);
        }
    }
}

impl RowAcc {
    #[inline(always)]
    fn merge(&mut self, a: Lane, b: Lane) {
        for c in 0..3 {
            self.sum[c] += a.s[c] + b.s[c];
        }
        self.finite += a.fin + b.fin;
        self.negative += a.neg + b.neg;
        self.clipped += a.clp + b.clp;
        self.dark += a.drk + b.drk;
        self.max = self.max.max(a.max).max(b.max);
    }

    fn row_interleaved(&mut self, row: &[f32], clip: f32, dark: f32) {
        let (mut a, mut b) = (Lane::ZERO, Lane::ZERO);
        let (pairs, rest) = row.as_chunks::<6>();
        for p in pairs {
            a.add(p[0], p[1], p[2], clip, dark);
            b.add(p[3], p[4], p[5], clip, dark);
        }
        if let [r, g, bl] = *rest {
            a.add(r, g, bl, clip, dark);
        }
        self.merge(a, b);
    }

    fn row_planar(&mut self, r: &[f32], g: &[f32], bl: &[f32], clip: f32, dark: f32) {
        let (mut a, mut b) = (Lane::ZERO, Lane::ZERO);
        let n = r.len().min(g.len()).min(bl.len());
        let (r, g, bl) = (&r[..n], &g[..n], &bl[..n]);
        let (r2, rr) = r.as_chunks::<2>();
        let (g2, _) = g.as_chunks::<2>();
        let (b2, _) = bl.as_chunks::<2>();
        for ((pr, pg), pb) in r2.iter().zip(g2).zip(b2) {
            a.add(pr[0], pg[0], pb[0], clip, dark);
            b.add(pr[1], pg[1], pb[1], clip, dark);
        }
        if !rr.is_empty() {
            a.add(r[n - 1], g[n - 1], bl[n - 1], clip, dark);
        }
        self.merge(a, b);
    }
}

/// Average a capture over the options' region.
pub fn average(img: &RgbView<'_>, opts: &AverageOptions) -> Result<CaptureStats, AverageError> {
    let (x0, y0, x1, y1) = opts.roi.bounds(img.width, img.height);
    if x1 <= x0 || y1 <= y0 {
        return Err(AverageError::EmptyRoi {
            roi: format!("{:?}", opts.roi),
            width: img.width,
            height: img.height,
        });
    }
    let mut acc = RowAcc {
        max: f32::NEG_INFINITY,
        ..RowAcc::default()
    };
    let (clip, dark) = (opts.clip_level, opts.dark_level);
    let w = img.width;
    match img.layout {
        Layout::Interleaved(data) => {
            for y in y0..y1 {
                acc.row_interleaved(&data[(y * w + x0) * 3..(y * w + x1) * 3], clip, dark);
            }
        }
        Layout::Planar(r, g, b) => {
            for y in y0..y1 {
                let span = y * w + x0..y * w + x1;
                acc.row_planar(&r[span.clone()], &g[span.clone()], &b[span], clip, dark);
            }
        }
    }
    let pixels = ((x1 - x0) * (y1 - y0)) as u64;
    let nonfinite = pixels - acc.finite;
    if acc.finite == 0 {
        return Err(AverageError::NoFinitePixel { pixels, nonfinite });
    }
    let n = acc.finite as f64;
    Ok(CaptureStats {
        mean_rgb: [acc.sum[0] / n, acc.sum[1] / n, acc.sum[2] / n],
        pixels,
        nonfinite,
        negative: acc.negative,
        clipped: acc.clipped,
        dark: acc.dark,
        max_value: acc.max as f64,
    })
}

/// The machine's own limit for the benchmark: a plain f64 sum of every float of the capture.
pub fn plain_sum(img: &RgbView<'_>) -> f64 {
    let sum = |d: &[f32]| d.iter().map(|&v| v as f64).sum::<f64>();
    match img.layout {
        Layout::Interleaved(d) => sum(d),
        Layout::Planar(r, g, b) => sum(r) + sum(g) + sum(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_parse_and_bounds() {
        assert_eq!(Roi::parse("full").unwrap(), Roi::Full);
        assert_eq!(Roi::parse("margin:3").unwrap().bounds(10, 8), (3, 3, 7, 5));
        assert_eq!(
            Roi::parse("margin:10%").unwrap().bounds(100, 50),
            (10, 5, 90, 45)
        );
        assert_eq!(
            Roi::parse("rect:2,1,100,2").unwrap().bounds(10, 8),
            (2, 1, 10, 3)
        );
        assert!(Roi::parse("rect:1,2,3").is_err());
        assert!(Roi::parse("margin:60%").is_err());
        assert!(Roi::parse("circle:3").is_err());
    }

    #[test]
    fn counts_and_exclusions() {
        let data = [
            1.0,
            2.0,
            3.0, //
            f32::NAN,
            0.0,
            0.0, //
            -1.0,
            0.0,
            1.0, //
            70000.0,
            0.0,
            0.0, //
            0.0,
            f32::INFINITY,
            0.0, //
            0.0,
            0.0,
            0.0,
        ];
        let v = RgbView::new(3, 2, &data).unwrap();
        let s = average(&v, &AverageOptions::default()).unwrap();
        assert_eq!(s.pixels, 6);
        assert_eq!(s.nonfinite, 2);
        assert_eq!(s.negative, 1);
        assert_eq!(s.clipped, 1);
        assert_eq!(s.dark, 2); // (-1+0+1)/3 = 0 and the black pixel
        assert_eq!(s.mean_rgb, [(1.0 - 1.0 + 70000.0) / 4.0, 0.5, 1.0]);
        assert_eq!(s.max_value, 70000.0);
    }

    #[test]
    fn planar_and_interleaved_agree() {
        let inter = [
            1.0,
            2.0,
            3.0,
            f32::NAN,
            5.0,
            6.0,
            -7.0,
            8.0,
            9.0,
            10.0,
            11.0,
            1e30,
        ];
        let (r, g, b): (Vec<f32>, Vec<f32>, Vec<f32>) = (
            inter.iter().step_by(3).copied().collect(),
            inter.iter().skip(1).step_by(3).copied().collect(),
            inter.iter().skip(2).step_by(3).copied().collect(),
        );
        for roi in [
            Roi::Full,
            Roi::Rect {
                x: 1,
                y: 0,
                width: 1,
                height: 2,
            },
        ] {
            let o = AverageOptions {
                roi,
                ..AverageOptions::default()
            };
            let a = average(&RgbView::new(2, 2, &inter).unwrap(), &o).unwrap();
            let b = average(&RgbView::planar(2, 2, &r, &g, &b).unwrap(), &o).unwrap();
            assert_eq!(a, b);
        }
        assert!(RgbView::planar(2, 2, &r, &g, &b[..3]).is_err());
    }

    #[test]
    fn matches_a_naive_reference_for_every_small_size_and_both_layouts() {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f32 / (1u64 << 31) as f32) * 4.0 - 0.5
        };
        for w in 1..8 {
            for h in 1..4 {
                let mut inter: Vec<f32> = (0..w * h * 3).map(|_| rnd()).collect();
                inter[0] = f32::NAN;
                let planes: Vec<Vec<f32>> = (0..3)
                    .map(|c| inter.iter().skip(c).step_by(3).copied().collect())
                    .collect();
                let a = average(
                    &RgbView::new(w, h, &inter).unwrap(),
                    &AverageOptions::default(),
                );
                let b = average(
                    &RgbView::planar(w, h, &planes[0], &planes[1], &planes[2]).unwrap(),
                    &AverageOptions::default(),
                );
                assert_eq!(a, b, "{w}×{h}");
                if w * h == 1 {
                    assert!(a.is_err());
                    continue;
                }
                let a = a.unwrap();
                let finite: Vec<&[f32]> = inter
                    .chunks(3)
                    .filter(|p| p.iter().all(|v| v.is_finite()))
                    .collect();
                for c in 0..3 {
                    let m = finite.iter().map(|p| p[c] as f64).sum::<f64>() / finite.len() as f64;
                    assert!((a.mean_rgb[c] - m).abs() < 1e-12, "{w}×{h}");
                }
                assert_eq!(
                    a.negative as usize,
                    finite.iter().filter(|p| p.iter().any(|v| *v < 0.0)).count()
                );
            }
        }
    }

    #[test]
    fn empty_and_all_nan() {
        let data = [f32::NAN; 6];
        let v = RgbView::new(2, 1, &data).unwrap();
        assert_eq!(
            average(&v, &AverageOptions::default()),
            Err(AverageError::NoFinitePixel {
                pixels: 2,
                nonfinite: 2
            })
        );
        let o = AverageOptions {
            roi: Roi::Margin { pixels: 1 },
            ..AverageOptions::default()
        };
        assert!(matches!(
            average(&v, &o),
            Err(AverageError::EmptyRoi { .. })
        ));
        assert!(RgbView::new(2, 2, &data).is_err());
    }

    #[test]
    fn huge_values_do_not_overflow() {
        let data = vec![1e36f32; 3 * 1000 * 100];
        let v = RgbView::new(1000, 100, &data).unwrap();
        let s = average(&v, &AverageOptions::default()).unwrap();
        // f32 sum would be inf past ~3.4e38; f64 row sums are exact to a few ulp
        for c in 0..3 {
            assert!(((s.mean_rgb[c] - 1e36f32 as f64) / 1e36).abs() < 1e-12);
        }
        let f32_sum: f32 = data.iter().step_by(3).sum();
        assert!(
            f32_sum.is_infinite(),
            "the f32 sum overflows, which is why we sum in f64"
        );
    }
}
