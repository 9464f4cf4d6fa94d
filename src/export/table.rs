//! One row per capture: where it was, what was measured, what the drift correction made of it
//! and the BRDF it gives (`goniowatch export --format table`). The row is flat so that the CSV
//! header and the JSON lines' keys are the same names in the same order (docs/outputs.md).

use super::correction::{DriftCorrection, Photometry};
use crate::checks::{CaptureRecord, CaptureStatus};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;

/// One capture's row. Angles are the placed directions in degrees (sample frame); colour
/// values are on the white's scale (Y = the white's luminance for the white) unless named
/// `file_*` (the file's own mean) or `brdf_*` (sr⁻¹).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExportRow {
    pub idx: u64,
    pub file: String,
    pub entry: usize,
    pub light: usize,
    pub camera: usize,
    pub probe: bool,
    pub t_s: f64,
    pub status: CaptureStatus,
    pub theta_i_deg: Option<f64>,
    pub phi_i_deg: Option<f64>,
    pub theta_o_deg: Option<f64>,
    pub phi_o_deg: Option<f64>,
    /// The file's mean RGB over the region of interest (the files' own scale).
    pub file_r: Option<f64>,
    pub file_g: Option<f64>,
    pub file_b: Option<f64>,
    /// XYZ as checked (cos θi and the drift still in it).
    pub raw_x: Option<f64>,
    pub raw_y: Option<f64>,
    pub raw_z: Option<f64>,
    /// The factors X, Y and Z were divided by (g·cx, g, g·cz).
    pub gain: f64,
    pub factor_x: f64,
    pub factor_z: f64,
    pub corrected_x: Option<f64>,
    pub corrected_y: Option<f64>,
    pub corrected_z: Option<f64>,
    /// Corrected linear RGB of the configured primaries, each channel relative to the white's.
    pub corrected_r: Option<f64>,
    pub corrected_g: Option<f64>,
    pub corrected_b: Option<f64>,
    /// The BRDF (sr⁻¹): per RGB channel and of Y.
    pub brdf_r: Option<f64>,
    pub brdf_g: Option<f64>,
    pub brdf_b: Option<f64>,
    pub brdf_y: Option<f64>,
    /// Divide the image's R, G and B by these to take the drift out of it.
    pub image_factor_r: Option<f64>,
    pub image_factor_g: Option<f64>,
    pub image_factor_b: Option<f64>,
    /// The capture stands for its plan entry in the exported grid (first good capture of the
    /// entry, not a probe, above the dark level).
    pub in_grid: bool,
    /// Why the capture has no colour (failed or missing).
    pub error: Option<String>,
}

/// The rows of `records` (in their order), corrected by `drift`; captures at or below
/// `dark_y` are rows but not in the grid.
pub fn rows(
    records: &[CaptureRecord],
    drift: &DriftCorrection,
    photometry: &Photometry,
    dark_y: f64,
) -> Vec<ExportRow> {
    let mut taken = HashSet::new();
    records
        .iter()
        .map(|rec| {
            let f = drift.xyz_factors(rec.t);
            let corrected = rec.xyz.map(|x| drift.correct(x, rec.t));
            let cos_i = rec.angles.map(|a| a.theta_i_deg.to_radians().cos());
            let brdf = match (corrected, cos_i) {
                (Some(x), Some(c)) => photometry.brdf_rgb(x, c),
                _ => None,
            };
            let brdf_y = match (corrected, cos_i) {
                (Some(x), Some(c)) => photometry.brdf_y(x, c),
                _ => None,
            };
            // a mean with a channel at or below zero (a dark frame) has no colour to keep:
            // the gain alone is divided out
            let image = match (rec.mean_rgb, corrected) {
                (Some(m), Some(x)) => photometry.image_factors(m, x).or(Some([f[1]; 3])),
                _ => None,
            };
            let rel = corrected.map(|x| photometry.relative_rgb(x));
            let in_grid = !rec.probe
                && rec.status == CaptureStatus::Ok
                && brdf.is_some()
                && rec.xyz.is_some_and(|x| x[1] > dark_y)
                && taken.insert(rec.entry);
            ExportRow {
                idx: rec.idx,
                file: rec.file.clone(),
                entry: rec.entry,
                light: rec.light,
                camera: rec.camera,
                probe: rec.probe,
                t_s: rec.t,
                status: rec.status,
                theta_i_deg: rec.angles.map(|a| a.theta_i_deg),
                phi_i_deg: rec.angles.map(|a| a.phi_i_deg),
                theta_o_deg: rec.angles.map(|a| a.theta_o_deg),
                phi_o_deg: rec.angles.map(|a| a.phi_o_deg),
                file_r: rec.mean_rgb.map(|m| m[0]),
                file_g: rec.mean_rgb.map(|m| m[1]),
                file_b: rec.mean_rgb.map(|m| m[2]),
                raw_x: rec.xyz.map(|x| x[0]),
                raw_y: rec.xyz.map(|x| x[1]),
                raw_z: rec.xyz.map(|x| x[2]),
                gain: f[1],
                factor_x: f[0],
                factor_z: f[2],
                corrected_x: corrected.map(|x| x[0]),
                corrected_y: corrected.map(|x| x[1]),
                corrected_z: corrected.map(|x| x[2]),
                corrected_r: rel.map(|v| v[0]),
                corrected_g: rel.map(|v| v[1]),
                corrected_b: rel.map(|v| v[2]),
                brdf_r: brdf.map(|v| v[0]),
                brdf_g: brdf.map(|v| v[1]),
                brdf_b: brdf.map(|v| v[2]),
                brdf_y,
                image_factor_r: image.map(|v| v[0]),
                image_factor_g: image.map(|v| v[1]),
                image_factor_b: image.map(|v| v[2]),
                in_grid,
                error: rec.error.clone(),
            }
        })
        .collect()
}

/// The CSV header: the row's field names in order.
pub const COLUMNS: &[&str] = &[
    "idx",
    "file",
    "entry",
    "light",
    "camera",
    "probe",
    "t_s",
    "status",
    "theta_i_deg",
    "phi_i_deg",
    "theta_o_deg",
    "phi_o_deg",
    "file_r",
    "file_g",
    "file_b",
    "raw_x",
    "raw_y",
    "raw_z",
    "gain",
    "factor_x",
    "factor_z",
    "corrected_x",
    "corrected_y",
    "corrected_z",
    "corrected_r",
    "corrected_g",
    "corrected_b",
    "brdf_r",
    "brdf_g",
    "brdf_b",
    "brdf_y",
    "image_factor_r",
    "image_factor_g",
    "image_factor_b",
    "in_grid",
    "error",
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::correction::GainSource;
    use crate::measure::colour::{RgbPrimaries, RgbToXyz, White};
    use crate::measure::kinematics::Angles;

    fn record(idx: u64, entry: usize, probe: bool, rgb: Option<[f64; 3]>) -> CaptureRecord {
        let conv = RgbToXyz::new(RgbPrimaries::SrgbIec);
        CaptureRecord {
            idx,
            entry,
            light: entry / 81,
            camera: entry % 81,
            probe,
            sentinel: false,
            t: idx as f64 * 7.0,
            file: format!("c{idx}.exr"),
            status: if rgb.is_some() {
                CaptureStatus::Ok
            } else {
                CaptureStatus::Missing
            },
            error: rgb.is_none().then(|| "never appeared".to_string()),
            mean_rgb: rgb,
            xyz: rgb.map(|m| conv.convert_scaled(m, 100.0)),
            lab: None,
            pixels: None,
            nonfinite: None,
            clipped: None,
            negative: None,
            angles: Some(Angles {
                theta_i_deg: 60.0,
                phi_i_deg: 0.0,
                theta_o_deg: 30.0,
                phi_o_deg: 180.0,
            }),
            substitute: None,
            pose_error_deg: None,
            by_command: false,
            gain_corrected: None,
        }
    }

    #[test]
    fn the_columns_are_the_rows_fields_in_order() {
        let p = Photometry::new(
            RgbPrimaries::SrgbIec,
            White::d65_scaled(100.0).unwrap(),
            1.0,
            100.0,
        )
        .unwrap();
        let r = rows(
            &[record(0, 5, false, Some([0.2; 3]))],
            &DriftCorrection::none(),
            &p,
            0.5,
        );
        let v = serde_json::to_value(&r[0]).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        let mut sorted_cols: Vec<&str> = COLUMNS.to_vec();
        sorted_cols.sort();
        let mut sorted_keys = keys.clone();
        sorted_keys.sort();
        assert_eq!(sorted_keys, sorted_cols);
        let mut w = csv::Writer::from_writer(Vec::new());
        w.serialize(&r[0]).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
    }

    #[test]
    fn the_first_good_capture_of_an_entry_is_in_the_grid_and_probes_retakes_and_dark_are_not() {
        let p = Photometry::new(
            RgbPrimaries::SrgbIec,
            White::d65_scaled(100.0).unwrap(),
            1.0,
            100.0,
        )
        .unwrap();
        let mut d = DriftCorrection::none();
        d.gain_source = GainSource::IsotropyClasses;
        d.rate_pct_per_h = -1.0;
        let recs = [
            record(0, 5, false, None),
            record(1, 5, false, Some([0.0001; 3])),
            record(2, 5, false, Some([0.2; 3])),
            record(3, 5, false, Some([0.2; 3])),
            record(4, 5, true, Some([0.2; 3])),
        ];
        let r = rows(&recs, &d, &p, 0.5);
        let grid: Vec<bool> = r.iter().map(|x| x.in_grid).collect();
        assert_eq!(grid, [false, false, true, false, false]);
        assert_eq!(r[0].brdf_r, None);
        assert_eq!(r[0].error.as_deref(), Some("never appeared"));
        let row = &r[2];
        let g = d.gain(row.t_s);
        assert!((row.gain - g).abs() < 1e-15 && g < 1.0);
        assert!((row.corrected_y.unwrap() - row.raw_y.unwrap() / g).abs() < 1e-12);
        // 0.2 of a white at cos 60° is a BRDF of 0.4 / π; the drift divided out raises it
        let want = 0.2 / 0.5 / std::f64::consts::PI / g;
        assert!((row.brdf_g.unwrap() / want - 1.0).abs() < 3e-4, "{row:?}");
        assert!((row.image_factor_g.unwrap() - g).abs() < 1e-9);
    }

    #[test]
    fn the_capture_scatter_is_pooled_over_repeated_geometries() {
        let p = Photometry::new(
            RgbPrimaries::SrgbIec,
            White::d65_scaled(100.0).unwrap(),
            1.0,
            100.0,
        )
        .unwrap();
        // two classes of two captures each: ±1 % and ±2 % about their means
        let mut recs = Vec::new();
        for (k, (level, phi)) in [(1.01, 0.0), (0.99, 40.0), (1.02, 0.0), (0.98, 40.0)]
            .into_iter()
            .enumerate()
        {
            let mut r = record(k as u64, k, false, Some([0.2 * level; 3]));
            let a = r.angles.as_mut().unwrap();
            a.phi_i_deg = phi;
            a.phi_o_deg = phi + 180.0;
            a.theta_o_deg = if k < 2 { 30.0 } else { 45.0 };
            recs.push(r);
        }
        let s = capture_scatter(&rows(&recs, &DriftCorrection::none(), &p, 0.5)).unwrap();
        assert_eq!((s.classes, s.dof), (2, 2));
        let want = ((1.01f64.ln() - 0.99f64.ln()).powi(2) / 2.0
            + (1.02f64.ln() - 0.98f64.ln()).powi(2) / 2.0)
            / 2.0;
        assert!((s.relative_pct - 100.0 * want.sqrt()).abs() < 1e-9, "{s:?}");
        // nothing repeats: no estimate
        assert_eq!(
            capture_scatter(&rows(&recs[..1], &DriftCorrection::none(), &p, 0.5)),
            None
        );
    }
}

/// The captures' own scatter: how much repeated measurements of one geometry differ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CaptureScatter {
    /// The standard deviation of one capture's BRDF about its isotropy class's mean, relative
    /// (pooled over the classes; the worst of R, G and B), in %.
    pub relative_pct: f64,
    /// Classes with at least two captures, and the degrees of freedom pooled.
    pub classes: usize,
    pub dof: usize,
}

/// The scatter of the in-grid rows within their isotropy classes (same θi, θo and |φo − φi|
/// to 0.01°): the noise a single capture carries beyond what the interpolant smooths. None
/// when no class repeats (an anisotropic plan, or too few captures).
pub fn capture_scatter(rows: &[ExportRow]) -> Option<CaptureScatter> {
    use std::collections::BTreeMap;
    let key = |r: &ExportRow| -> Option<[i64; 3]> {
        let dphi = (r.phi_o_deg? - r.phi_i_deg?).rem_euclid(360.0);
        let dphi = if dphi > 180.0 { 360.0 - dphi } else { dphi };
        let k = |v: f64| (v * 100.0).round() as i64;
        Some([k(r.theta_i_deg?), k(r.theta_o_deg?), k(dphi)])
    };
    let mut classes: BTreeMap<[i64; 3], Vec<[f64; 3]>> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.in_grid) {
        let (Some(k), Some(red), Some(green), Some(blue)) = (key(r), r.brdf_r, r.brdf_g, r.brdf_b)
        else {
            continue;
        };
        if red > 0.0 && green > 0.0 && blue > 0.0 {
            classes
                .entry(k)
                .or_default()
                .push([red.ln(), green.ln(), blue.ln()]);
        }
    }
    let (mut ss, mut dof, mut n_classes) = ([0.0f64; 3], 0usize, 0usize);
    for members in classes.values().filter(|m| m.len() >= 2) {
        n_classes += 1;
        dof += members.len() - 1;
        for c in 0..3 {
            let mean = members.iter().map(|m| m[c]).sum::<f64>() / members.len() as f64;
            ss[c] += members.iter().map(|m| (m[c] - mean).powi(2)).sum::<f64>();
        }
    }
    if dof == 0 {
        return None;
    }
    let worst = ss
        .iter()
        .map(|s| (s / dof as f64).sqrt())
        .fold(0.0, f64::max);
    Some(CaptureScatter {
        relative_pct: 100.0 * worst,
        classes: n_classes,
        dof,
    })
}
