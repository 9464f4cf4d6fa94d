//! The tabulated reference-BRDF format (docs/reference-format.md): an independent measurement of
//! the same sample, spectral (e.g. 30 bands 400–690 nm, as the Integra data) or RGB/XYZ, for the
//! cross-validation (`compare`, the paper's Section 6.2). Pure parsing; every error names its line and column (both from
//! 1, columns counted in characters), and the time is linear in the length of the text.

use crate::measure::colour::{RgbPrimaries, RgbToXyz, SpectralToXyz, Xyz};
use crate::measure::geometry::{Spherical, Vec3};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
#[error("line {line}, column {column}: {message}")]
pub struct ReferenceError {
    pub line: usize,
    pub column: usize,
    pub message: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueKind {
    Spectral,
    Rgb,
    Xyz,
}

/// One reference sample: the directions and its XYZ (spectral data converted under D65 with the
/// CIE 1931 observer, Y = 100 for a perfect reflector; RGB converted with the IEC sRGB matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSample {
    pub line: usize,
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub angles_deg: [f64; 4],
    pub xyz: Xyz,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub kind: ValueKind,
    pub bands: Vec<f64>,
    pub name: Option<String>,
    pub samples: Vec<ReferenceSample>,
}

fn err(line: usize, column: usize, message: impl Into<String>) -> ReferenceError {
    ReferenceError {
        line,
        column,
        message: message.into(),
    }
}

/// Whitespace-separated tokens with their 1-based columns (in characters), in one pass: the
/// column is counted along the way, never recounted from the start of the line per token.
fn tokens(s: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    // (byte offset, 0-based column) of the token being read
    let mut start: Option<(usize, usize)> = None;
    for (col, (i, ch)) in s.char_indices().enumerate() {
        if ch.is_whitespace() {
            if let Some((b, c)) = start.take() {
                out.push((c + 1, &s[b..i]));
            }
        } else if start.is_none() {
            start = Some((i, col));
        }
    }
    if let Some((b, c)) = start {
        out.push((c + 1, &s[b..]));
    }
    out
}

fn number(line: usize, col: usize, t: &str, what: &str) -> Result<f64, ReferenceError> {
    t.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| err(line, col, format!("{what} '{t}' is not a finite number")))
}

/// One data line (`line`, its text without the comment `content`): four angles and the values
/// of `kind`, turned into XYZ.
fn data_line(
    line: usize,
    content: &str,
    k: ValueKind,
    bands: &[f64],
    converter: Option<&SpectralToXyz>,
    rgb: &RgbToXyz,
) -> Result<ReferenceSample, ReferenceError> {
    let expected = match k {
        ValueKind::Spectral => {
            if bands.is_empty() {
                return Err(err(line, 1, "spectral data need a 'bands = …' header"));
            }
            bands.len()
        }
        ValueKind::Rgb | ValueKind::Xyz => 3,
    };
    let toks = tokens(content);
    if toks.len() != 4 + expected {
        let col = toks
            .get(4 + expected)
            .map(|t| t.0)
            .unwrap_or(content.chars().count() + 1);
        return Err(err(
            line,
            col,
            format!(
                "expected 4 angles and {expected} values, found {} fields",
                toks.len()
            ),
        ));
    }
    let mut a = [0.0; 4];
    for i in 0..4 {
        let (c, t) = toks[i];
        a[i] = number(line, c, t, ["theta_i", "phi_i", "theta_o", "phi_o"][i])?;
        if (i == 0 || i == 2) && !(0.0..=90.0).contains(&a[i]) {
            return Err(err(
                line,
                c,
                format!(
                    "{} = {} is not in [0, 90]°",
                    ["theta_i", "", "theta_o"][i],
                    a[i]
                ),
            ));
        }
    }
    let mut vals = Vec::with_capacity(expected);
    for &(c, t) in &toks[4..] {
        vals.push(number(line, c, t, "value")?);
    }
    let xyz = match k {
        ValueKind::Spectral => converter
            .as_ref()
            .ok_or_else(|| err(line, 1, "no band set"))?
            .convert(&vals)
            .map_err(|e| err(line, 1, e.to_string()))?,
        ValueKind::Rgb => rgb.convert([vals[0], vals[1], vals[2]]),
        ValueKind::Xyz => [vals[0], vals[1], vals[2]],
    };
    Ok(ReferenceSample {
        line,
        omega_i: Spherical::from_deg(a[0], a[1]).to_vector(),
        omega_o: Spherical::from_deg(a[2], a[3]).to_vector(),
        angles_deg: a,
        xyz,
    })
}

pub fn parse(text: &str) -> Result<Reference, ReferenceError> {
    let mut kind: Option<ValueKind> = None;
    let mut bands: Vec<f64> = Vec::new();
    let mut name = None;
    let mut samples = Vec::new();
    let mut converter: Option<SpectralToXyz> = None;
    let rgb = RgbToXyz::new(RgbPrimaries::SrgbIec);
    let mut seen_version = false;
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let content = raw.split('#').next().unwrap_or("");
        if n == 0 {
            if !raw.trim_start().starts_with("# goniowatch reference") {
                return Err(err(
                    1,
                    1,
                    "the first line must be '# goniowatch reference BRDF, version 1'",
                ));
            }
            if !raw.contains("version 1") {
                return Err(err(
                    1,
                    1,
                    "unsupported version (this build reads version 1)",
                ));
            }
            seen_version = true;
            continue;
        }
        if content.trim().is_empty() {
            continue;
        }
        if let Some(eq) = content.find('=') {
            if !samples.is_empty() {
                return Err(err(line, 1, "header lines must come before the data"));
            }
            let key = content[..eq].trim();
            let after = &content[eq + 1..];
            let value = after.trim();
            // the value's column: past the key, the '=' and the blanks after it, in characters
            let vcol = content[..eq].chars().count()
                + 2
                + (after.chars().count() - after.trim_start().chars().count());
            match key {
                "format" => {
                    if kind.is_some() {
                        return Err(err(line, 1, "'format' is given twice"));
                    }
                    kind = Some(match value {
                        "spectral" => ValueKind::Spectral,
                        "rgb" => ValueKind::Rgb,
                        "xyz" => ValueKind::Xyz,
                        _ => {
                            return Err(err(
                                line,
                                vcol,
                                format!("format '{value}' is not spectral, rgb or xyz"),
                            ))
                        }
                    });
                }
                "bands" => {
                    if !bands.is_empty() {
                        return Err(err(line, 1, "'bands' is given twice"));
                    }
                    for (c, t) in tokens(value) {
                        bands.push(number(line, vcol + c - 1, t, "band")?);
                    }
                    converter = Some(
                        SpectralToXyz::d65(&bands).map_err(|e| err(line, vcol, e.to_string()))?,
                    );
                }
                "name" => name = Some(value.to_string()),
                _ => {
                    return Err(err(
                        line,
                        1,
                        format!("unknown header key '{key}' (format, bands, name)"),
                    ))
                }
            }
            continue;
        }
        let Some(k) = kind else {
            return Err(err(line, 1, "data before the 'format = …' header"));
        };
        samples.push(data_line(
            line,
            content,
            k,
            &bands,
            converter.as_ref(),
            &rgb,
        )?);
    }
    if !seen_version {
        return Err(err(1, 1, "empty file"));
    }
    let kind = kind.ok_or_else(|| err(1, 1, "no 'format = …' header"))?;
    if samples.is_empty() {
        return Err(err(text.lines().count().max(1), 1, "no data lines"));
    }
    Ok(Reference {
        kind,
        bands,
        name,
        samples,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECTRAL: &str = "# goniowatch reference BRDF, version 1
# an Integra-like measurement
name = walkway
format = spectral
bands = 400 500 600 700
30 0 45 180   0.5 0.5 0.5 0.5   # a comment
30 0 40 170.5 1 1 1 1
";

    #[test]
    fn spectral_file_parses_and_converts() {
        let r = parse(SPECTRAL).unwrap();
        assert_eq!(r.kind, ValueKind::Spectral);
        assert_eq!(r.bands, vec![400.0, 500.0, 600.0, 700.0]);
        assert_eq!(r.name.as_deref(), Some("walkway"));
        assert_eq!(r.samples.len(), 2);
        // a perfect reflector is the white (Y = 100), half of it Y = 50
        assert!((r.samples[1].xyz[1] - 100.0).abs() < 1e-9);
        assert!((r.samples[0].xyz[1] - 50.0).abs() < 1e-9);
        assert_eq!(r.samples[0].line, 6);
    }

    #[test]
    fn rgb_and_xyz_variants() {
        let r = parse("# goniowatch reference BRDF, version 1\nformat = xyz\n0 0 10 0 1 2 3\n")
            .unwrap();
        assert_eq!(r.samples[0].xyz, [1.0, 2.0, 3.0]);
        let r = parse("# goniowatch reference BRDF, version 1\nformat = rgb\n0 0 10 0 1 1 1\n")
            .unwrap();
        assert!((r.samples[0].xyz[1] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn every_error_names_line_and_column() {
        let h = "# goniowatch reference BRDF, version 1\n";
        for (text, line, column, what) in [
            ("nothing here\n".to_string(), 1, 1, "first line"),
            (
                "# goniowatch reference BRDF, version 2\n".to_string(),
                1,
                1,
                "version",
            ),
            (format!("{h}format = png\n"), 2, 10, "png"),
            (format!("{h}0 0 10 0 1 2 3\n"), 2, 1, "before"),
            (
                format!("{h}format = xyz\n0 0 10 0 1 2\n"),
                3,
                13,
                "found 6 fields",
            ),
            (format!("{h}format = xyz\n0 0 10 0 1 x 3\n"), 3, 12, "'x'"),
            (
                format!("{h}format = xyz\n0 0 95 0 1 2 3\n"),
                3,
                5,
                "theta_o",
            ),
            (
                format!("{h}format = xyz\n0 0 10 nan 1 2 3\n"),
                3,
                8,
                "phi_o",
            ),
            (
                format!("{h}format = spectral\n0 0 10 0 1 2 3\n"),
                3,
                1,
                "bands",
            ),
            (
                format!("{h}format = spectral\nbands = 400 bad\n"),
                3,
                13,
                "band",
            ),
            (
                format!("{h}format = spectral\nbands = 400 300\n"),
                3,
                9,
                "increasing",
            ),
            (format!("{h}colour = red\n"), 2, 1, "unknown header"),
            (format!("{h}format = xyz\nformat = rgb\n"), 3, 1, "twice"),
            (
                format!("{h}format = xyz\n0 0 10 0 1 2 3\nname = late\n"),
                4,
                1,
                "before the data",
            ),
            (format!("{h}format = xyz\n"), 2, 1, "no data"),
        ] {
            let e = parse(&text).unwrap_err();
            assert_eq!((e.line, e.column), (line, column), "{what}: {e}");
            assert!(e.to_string().contains(what), "{what}: {e}");
        }
    }
}
