//! The report's BRDF section: in-plane slices of the measured BRDF (the plane of incidence of
//! each θi layer's first light, corrected and as measured) and the coverage of the latest MERL
//! export's grid (`SESSION/merl-export.json`).

use crate::export::table::ExportRow;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

/// What the section draws from.
pub(crate) struct BrdfInputs {
    pub rows: Vec<ExportRow>,
    /// How the drift was divided out (the export's words).
    pub correction: String,
    pub merl: Option<MerlCoverage>,
}

/// The parts of a MERL export's sidecar the report shows.
#[derive(Debug, Clone, Deserialize)]
pub(crate) struct MerlCoverage {
    pub file: String,
    pub cells: crate::export::merl::CellCounts,
    pub filled_fraction_above_horizon: f64,
    pub theta_max_deg: f64,
    pub coverage: Vec<Vec<f64>>,
    pub relative_sigma: Option<[f64; 3]>,
}

/// Read what the section needs; None when the session cannot be turned into BRDF values
/// (the reason is logged).
pub(crate) fn load(dir: &Path) -> Option<BrdfInputs> {
    let data = match crate::cli::export::load(dir, true) {
        Ok(d) => d,
        Err(e) => {
            tracing::warn!("the report's BRDF section is left out: {e:#}");
            return None;
        }
    };
    let merl = std::fs::read(dir.join(crate::cli::export::MERL_SIDECAR_IN_SESSION))
        .ok()
        .and_then(|b| serde_json::from_slice::<MerlCoverage>(&b).ok());
    Some(BrdfInputs {
        correction: crate::cli::export::correction_line(&data.drift),
        rows: data.rows,
        merl,
    })
}

const LAYER_COLOURS: [&str; 8] = [
    "#1f5fa8", "#e07b00", "#2e8b57", "#c62828", "#7b3fa0", "#8a6d3b", "#00838f", "#5d6b78",
];

/// One θi layer's in-plane captures: (signed θo, corrected BRDF of Y, as-measured BRDF of Y),
/// forward (the mirror's side) positive.
type Slice = (f64, Vec<(f64, f64, f64)>);

/// For each θi layer (to the degree), the in-plane captures of the light nearest φ = 0.
fn slices(rows: &[ExportRow]) -> Vec<Slice> {
    // (θi to the degree) → light → its in-grid rows
    let mut layers: BTreeMap<i64, BTreeMap<usize, Vec<&ExportRow>>> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.in_grid && r.brdf_y.is_some()) {
        let Some(ti) = r.theta_i_deg else { continue };
        layers
            .entry(ti.round() as i64)
            .or_default()
            .entry(r.light)
            .or_default()
            .push(r);
    }
    let mut out = Vec::new();
    for (ti, lights) in layers {
        // the light of the layer nearest φ = 0 that has the most captures (a substitute's
        // lone captures land in layers of their own and are skipped below)
        let Some(members) = lights.values().filter(|m| m.len() >= 5).min_by(|a, b| {
            let az = |m: &Vec<&ExportRow>| {
                let p = m[0].phi_i_deg.unwrap_or(0.0).rem_euclid(360.0);
                p.min(360.0 - p)
            };
            az(a).total_cmp(&az(b))
        }) else {
            continue;
        };
        let mut pts = Vec::new();
        for r in members {
            let (Some(pi), Some(to), Some(po), Some(f), Some(raw), Some(cor)) = (
                r.phi_i_deg,
                r.theta_o_deg,
                r.phi_o_deg,
                r.brdf_y,
                r.raw_y,
                r.corrected_y,
            ) else {
                continue;
            };
            let d = (po - pi).to_radians();
            if to > 0.5 && d.sin().abs() * to.to_radians().sin() > 0.5f64.to_radians().sin() {
                continue;
            }
            let signed = if to <= 0.5 || d.cos() < 0.0 { to } else { -to };
            let measured = if cor.abs() > 0.0 { f * raw / cor } else { f };
            pts.push((signed, f, measured));
        }
        if pts.len() >= 3 {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            out.push((ti as f64, pts));
        }
    }
    out
}

/// The in-plane polar plot: direction = θo from the normal (up), radius = log10 of the BRDF
/// over 2.5 decades below the largest value.
fn polar_plot(sl: &[Slice]) -> String {
    let (w, h) = (560.0, 320.0);
    let (cx, cy, rad) = (w / 2.0, h - 34.0, 250.0);
    let fmax = sl
        .iter()
        .flat_map(|s| s.1.iter().flat_map(|p| [p.1, p.2]))
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold(0.0f64, f64::max);
    if !(fmax > 0.0) {
        return String::new();
    }
    let hi = fmax.log10().ceil();
    let lo = hi - 3.0;
    let r_of = |f: f64| rad * ((f.max(1e-300).log10() - lo) / (hi - lo)).clamp(0.0, 1.0);
    let xy = |theta: f64, r: f64| {
        let a = theta.to_radians();
        (cx + r * a.sin(), cy - r * a.cos())
    };
    let mut s = String::new();
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" height="{h}" class="plot">"##
    );
    // decade rings and angle spokes
    for k in 0..=3 {
        let r = rad * k as f64 / 3.0;
        let _ = write!(
            s,
            r##"<path d="M{:.1},{cy:.1} A{r:.1},{r:.1} 0 0 1 {:.1},{cy:.1}" fill="none" stroke="#eef1f4"/>"##,
            cx - r,
            cx + r
        );
        if k > 0 {
            let _ = write!(
                s,
                r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">1e{:.0}</text>"##,
                cx + r,
                cy + 14.0,
                lo + k as f64
            );
        }
    }
    for a in (-90i32..=90).step_by(15) {
        let (x, y) = xy(a as f64, rad);
        let _ = write!(
            s,
            r##"<line x1="{cx:.1}" y1="{cy:.1}" x2="{x:.1}" y2="{y:.1}" stroke="#eef1f4"/>"##
        );
        if a % 30 == 0 {
            let (tx, ty) = xy(a as f64, rad + 10.0);
            let _ = write!(
                s,
                r##"<text x="{tx:.1}" y="{ty:.1}" text-anchor="middle">{}°</text>"##,
                a.abs()
            );
        }
    }
    let _ = write!(
        s,
        r##"<text x="8" y="{:.1}">← towards the light</text><text x="{:.1}" y="{:.1}" text-anchor="end">the mirror's side →</text>"##,
        h - 6.0,
        w - 8.0,
        h - 6.0
    );
    for (k, (ti, pts)) in sl.iter().enumerate() {
        let col = LAYER_COLOURS[k % LAYER_COLOURS.len()];
        for (measured, dash) in [(true, r##" stroke-dasharray="4 3""##), (false, "")] {
            let path: Vec<String> = pts
                .iter()
                .map(|p| {
                    let (x, y) = xy(p.0, r_of(if measured { p.2 } else { p.1 }));
                    format!("{x:.1},{y:.1}")
                })
                .collect();
            let _ = write!(
                s,
                r##"<polyline points="{}" fill="none" stroke="{col}" stroke-width="{}"{dash}/>"##,
                path.join(" "),
                if measured { 1.0 } else { 1.6 }
            );
        }
        // the light's direction
        let (lx, ly) = xy(-ti, rad + 2.0);
        let _ = write!(
            s,
            r##"<circle cx="{lx:.1}" cy="{ly:.1}" r="3" fill="{col}"/><text x="14" y="{:.1}" fill="{col}" style="fill:{col}">θi = {ti:.0}°</text>"##,
            16.0 + 14.0 * k as f64
        );
    }
    s.push_str("</svg>");
    s
}

/// The MERL grid's coverage: for each θh and θd cell row (2 × 2 cells a square), the share
/// of its φd cells with a value.
fn coverage_map(m: &MerlCoverage) -> String {
    let n = 45usize;
    let px = 6.0;
    let (l, t) = (52.0, 10.0);
    let (w, h) = (l + n as f64 * px + 90.0, t + n as f64 * px + 44.0);
    let mut s = String::new();
    let _ = write!(
        s,
        r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" height="{h}" class="plot">"##
    );
    for i in 0..n {
        for j in 0..n {
            let mut sum = 0.0;
            let mut k = 0;
            for a in 0..2 {
                for b in 0..2 {
                    if let Some(v) = m.coverage.get(2 * i + a).and_then(|r| r.get(2 * j + b)) {
                        sum += v;
                        k += 1;
                    }
                }
            }
            let f = if k > 0 { sum / k as f64 } else { 0.0 };
            let colour = if f > 0.0 {
                super::report::ramp(f)
            } else {
                "#f7f9fb".into()
            };
            let _ = write!(
                s,
                r##"<rect x="{:.1}" y="{:.1}" width="{px}" height="{px}" fill="{colour}"/>"##,
                l + i as f64 * px,
                t + (n - 1 - j) as f64 * px
            );
        }
    }
    // θh runs on the format's square-root index
    for th in [0.0f64, 5.0, 20.0, 45.0, 90.0] {
        let x = l + (th / 90.0).sqrt() * n as f64 * px;
        let _ = write!(
            s,
            r##"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{th:.0}°</text>"##,
            t + n as f64 * px + 14.0
        );
    }
    for td in [0.0f64, 30.0, 60.0, 90.0] {
        let y = t + n as f64 * px * (1.0 - td / 90.0);
        let _ = write!(
            s,
            r##"<text x="{:.1}" y="{:.1}" text-anchor="end">{td:.0}°</text>"##,
            l - 5.0,
            y + 4.0
        );
    }
    let _ = write!(
        s,
        r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">θh (the format's square-root axis)</text><text x="12" y="{:.1}" text-anchor="middle" transform="rotate(-90 12 {:.1})">θd</text>"##,
        l + n as f64 * px / 2.0,
        h - 4.0,
        t + n as f64 * px / 2.0,
        t + n as f64 * px / 2.0
    );
    // legend
    let lx = l + n as f64 * px + 16.0;
    for k in 0..=5 {
        // the lowest entry is "none": a square without any value
        let (colour, label) = match k {
            0 => ("#f7f9fb".to_string(), "none".to_string()),
            _ => {
                let f = (k - 1) as f64 / 4.0;
                (
                    super::report::ramp(f),
                    if k == 1 {
                        "a few".into()
                    } else {
                        format!("{:.0} %", 100.0 * f)
                    },
                )
            }
        };
        let _ = write!(
            s,
            r##"<rect x="{lx:.1}" y="{:.1}" width="12" height="12" fill="{colour}" stroke="#c5ccd3" stroke-width="0.5"/><text x="{:.1}" y="{:.1}">{label}</text>"##,
            t + 8.0 + 18.0 * (5 - k) as f64,
            lx + 16.0,
            t + 18.0 + 18.0 * (5 - k) as f64,
        );
    }
    s.push_str("</svg>");
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The section's HTML.
pub(crate) fn section(b: &BrdfInputs, figure: impl Fn(&str) -> String) -> String {
    let mut h = String::from("<h2>BRDF</h2>");
    let sl = slices(&b.rows);
    if sl.is_empty() {
        h.push_str(
            "<p class=muted>No θi layer has captures in its plane of incidence to draw.</p>",
        );
    } else {
        let _ = write!(
            h,
            "<p>The BRDF of the luminance (sr⁻¹, relative to the configured white) in the plane of incidence of each θi layer's light nearest φ = 0: solid corrected, dashed as measured ({}). Direction is θo from the normal, radius the BRDF on a log scale (three decades); dots on the rim are the lights. `goniowatch export SESSION --format table` has every capture's values.</p>",
            esc(&b.correction)
        );
        h.push_str(&figure(&polar_plot(&sl)));
    }
    match &b.merl {
        Some(m) => {
            let _ = write!(
                h,
                "<h3>The MERL export's coverage</h3><p>{}: {} of 1,458,000 cells have a value ({:.1} % of those with both directions above the horizon); empty: {} below the horizon, {} beyond θ = {:.2}°, {} out of the captures' reach{}. Each square is the share of its φd cells with a value.</p>",
                esc(&m.file),
                m.cells.filled,
                100.0 * m.filled_fraction_above_horizon,
                m.cells.below_horizon,
                m.cells.beyond_theta_range,
                m.theta_max_deg,
                m.cells.outside_interpolant,
                m.relative_sigma
                    .map(|q| format!("; the interpolation's σ is {:.1} % of the value in the median cell, under {:.1} % in 95 %", 100.0 * q[0], 100.0 * q[1]))
                    .unwrap_or_default()
            );
            h.push_str(&figure(&coverage_map(m)));
        }
        None => h.push_str("<p class=muted>No MERL export of this session yet: `goniowatch export SESSION --format merl` writes one, and this report then shows its coverage.</p>"),
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::CaptureStatus;

    fn row(light: usize, ti: f64, pi: f64, to: f64, po: f64, f: f64) -> ExportRow {
        let v: serde_json::Value = serde_json::json!({
            "idx": 0, "file": "x", "entry": 0, "light": light, "camera": 0, "probe": false,
            "t_s": 0.0, "status": "ok", "theta_i_deg": ti, "phi_i_deg": pi, "theta_o_deg": to,
            "phi_o_deg": po, "file_r": null, "file_g": null, "file_b": null, "raw_x": null,
            "raw_y": 0.9 * f, "raw_z": null, "gain": 0.9, "factor_x": 0.9, "factor_z": 0.9,
            "corrected_x": null, "corrected_y": f, "corrected_z": null, "corrected_r": null,
            "corrected_g": null, "corrected_b": null, "brdf_r": null, "brdf_g": null,
            "brdf_b": null, "brdf_y": f, "image_factor_r": null, "image_factor_g": null,
            "image_factor_b": null, "in_grid": true, "error": null
        });
        let r: ExportRow = serde_json::from_value(v).unwrap();
        assert_eq!(r.status, CaptureStatus::Ok);
        r
    }

    #[test]
    fn a_layers_slice_takes_the_in_plane_captures_of_its_light_nearest_phi_zero() {
        let mut rows = Vec::new();
        for (light, pi) in [(1, 0.0), (2, 60.0)] {
            for (to, po) in [
                (0.0, 0.0),
                (30.0, pi),
                (30.0, pi + 180.0),
                (45.0, pi + 180.0),
                (45.0, pi + 90.0),
                (60.0, pi),
            ] {
                rows.push(row(light, 30.0, pi, to, po, 0.1 + to / 100.0));
            }
        }
        let sl = slices(&rows);
        assert_eq!(sl.len(), 1);
        let (ti, pts) = &sl[0];
        assert_eq!(*ti, 30.0);
        let signed: Vec<f64> = pts.iter().map(|p| p.0).collect();
        // the camera at φi + 90° is out of the plane; backward negative, forward positive
        assert_eq!(signed, vec![-60.0, -30.0, 0.0, 30.0, 45.0]);
        // the as-measured value has the gain back in it
        assert!((pts[0].2 / pts[0].1 - 0.9).abs() < 1e-12);
        let svg = polar_plot(&sl);
        assert!(svg.starts_with("<svg") && svg.contains("θi = 30°") && svg.ends_with("</svg>"));
    }
}
