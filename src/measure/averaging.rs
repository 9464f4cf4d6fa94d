//! Averaging one capture (BTF → BRDF): the mean linear RGB over a region of interest, with
//! per-capture pixel statistics. Works on an already decoded interleaved RGB f32 buffer; the
//! decoders live in the shell (`crate::decode`).
//!
//! Arithmetic: every row is summed in f64 and the row sums are added in f64, so a 1e36 pixel
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
                return Ok(Roi::MarginFraction { fraction: f / 100.0 });
            }
            let px: usize = m.trim().parse().map_err(|e| format!("margin: {e}"))?;
            return Ok(Roi::Margin { pixels: px });
        }
        Err(format!("unknown region '{s}': use full, rect:X,Y,W,H, margin:PIXELS or margin:PERCENT%"))
    }

    /// The pixel rectangle (x0, y0, x1, y1), half-open, for an image of the given size.
    pub fn bounds(&self, width: usize, height: usize) -> (usize, usize, usize, usize) {
        match *self {
            Roi::Full => (0, 0, width, height),
            Roi::Rect { x, y, width: w, height: h } => {
                let x0 = x.min(width);
                let y0 = y.min(height);
                (x0, y0, x.saturating_add(w).min(width), y.saturating_add(h).min(height))
            }
            Roi::Margin { pixels } => (
                pixels.min(width),
                pixels.min(height),
                width.saturating_sub(pixels),
                height.saturating_sub(pixels),
            ),
            Roi::MarginFraction { fraction } => {
                let f = if fraction.is_finite() { fraction.clamp(0.0, 0.5) } else { 0.0 };
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

/// A decoded capture: interleaved linear RGB, row-major, top row first.
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    pub width: usize,
    pub height: usize,
    pub data: &'a [f32],
}

impl<'a> RgbView<'a> {
    pub fn new(width: usize, height: usize, data: &'a [f32]) -> Result<Self, AverageError> {
        let expected = width.saturating_mul(height).saturating_mul(3);
        if data.len() != expected {
            return Err(AverageError::BufferSize {
                got: data.len(),
                expected,
                width,
                height,
            });
        }
        Ok(RgbView { width, height, data })
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

#[inline(always)]
fn accumulate_row(row: &[f32], clip: f32, dark: f32, acc: &mut RowAcc) {
    let mut s = [0.0f64; 3];
    let (mut fin, mut neg, mut clp, mut drk) = (0u64, 0u64, 0u64, 0u64);
    let mut mx = acc.max;
    for px in row.chunks_exact(3) {
        let (r, g, b) = (px[0], px[1], px[2]);
        let finite = r.is_finite() & g.is_finite() & b.is_finite();
        if finite {
            s[0] += r as f64;
            s[1] += g as f64;
            s[2] += b as f64;
            fin += 1;
            neg += ((r < 0.0) | (g < 0.0) | (b < 0.0)) as u64;
            let m = r.max(g).max(b);
            clp += (m >= clip) as u64;
            drk += ((r + g + b) * (1.0 / 3.0) <= dark) as u64;
            mx = mx.max(m);
        }
    }
    for c in 0..3 {
        acc.sum[c] += s[c];
    }
    acc.finite += fin;
    acc.negative += neg;
    acc.clipped += clp;
    acc.dark += drk;
    acc.max = mx;
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
    let stride = img.width * 3;
    for y in y0..y1 {
        let row = &img.data[y * stride + x0 * 3..y * stride + x1 * 3];
        accumulate_row(row, opts.clip_level, opts.dark_level, &mut acc);
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

/// The machine's own limit for the benchmark: a plain f64 sum of every float in the buffer.
pub fn plain_sum(data: &[f32]) -> f64 {
    data.iter().map(|&v| v as f64).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_parse_and_bounds() {
        assert_eq!(Roi::parse("full").unwrap(), Roi::Full);
        assert_eq!(Roi::parse("margin:3").unwrap().bounds(10, 8), (3, 3, 7, 5));
        assert_eq!(Roi::parse("margin:10%").unwrap().bounds(100, 50), (10, 5, 90, 45));
        assert_eq!(Roi::parse("rect:2,1,100,2").unwrap().bounds(10, 8), (2, 1, 10, 3));
        assert!(Roi::parse("rect:1,2,3").is_err());
        assert!(Roi::parse("margin:60%").is_err());
        assert!(Roi::parse("circle:3").is_err());
    }

    #[test]
    fn counts_and_exclusions() {
        let data = [
            1.0, 2.0, 3.0, //
            f32::NAN, 0.0, 0.0, //
            -1.0, 0.0, 1.0, //
            70000.0, 0.0, 0.0, //
            0.0, f32::INFINITY, 0.0, //
            0.0, 0.0, 0.0,
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
    fn empty_and_all_nan() {
        let data = [f32::NAN; 6];
        let v = RgbView::new(2, 1, &data).unwrap();
        assert_eq!(
            average(&v, &AverageOptions::default()),
            Err(AverageError::NoFinitePixel { pixels: 2, nonfinite: 2 })
        );
        let o = AverageOptions {
            roi: Roi::Margin { pixels: 1 },
            ..AverageOptions::default()
        };
        assert!(matches!(average(&v, &o), Err(AverageError::EmptyRoi { .. })));
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
        assert!(f32_sum.is_infinite(), "the f32 sum overflows, which is why we sum in f64");
    }
}
