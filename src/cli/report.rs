//! Shell: `goniowatch report SESSION [--out DIR]`: the end-of-run report, one self-contained HTML
//! file with inline SVG plots (no fonts, images or scripts from anywhere), and the same tables as
//! CSV. It reads only the session's recorded files, so a replayed session's report is the live
//! session's report, byte for byte (no dates, no paths).

use super::compare::CompareReport;
use crate::checks::alarm::{Affects, Alarm, AlarmCode, Severity};
use crate::checks::evidence::Evidence;
use crate::checks::{CaptureRecord, PairRecord, Table2};
use crate::config::Config;
use crate::detect::sweeps::SweepRecord;
use crate::engine::Summary;
use crate::measure::plan::SamplingPlan;
use anyhow::{Context, Result};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What a report is made of: the session's recorded files.
pub(crate) struct ReportInputs {
    pub summary: Summary,
    pub config_text: String,
    pub config: Config,
    pub captures: Vec<CaptureRecord>,
    pub pairs: Vec<PairRecord>,
    pub alarms: Vec<Alarm>,
    /// The light sweeps (isotropic samples; empty when the checks did not run).
    pub sweeps: Vec<SweepRecord>,
    pub crossval: Option<CompareReport>,
    /// The checked count of `summary.json` when the run stopped before writing it again (a
    /// killed run): the capture counts shown are then those of `captures.jsonl`.
    pub summary_behind: Option<u64>,
    /// The BRDF section's inputs (none when the session gives no BRDF values).
    pub brdf: Option<super::brdf_plots::BrdfInputs>,
}

/// A run stopped between two writes of `summary.json` (killed, the machine lost) has capture
/// records the summary does not count: its capture counts are taken from the records (the
/// pairs and tables are as the summary last had them). Returns the summary's count when so.
fn catch_up_counts(summary: &mut Summary, captures: &[CaptureRecord]) -> Option<u64> {
    use crate::checks::CaptureStatus;
    let before = summary.checked.captures;
    if summary.finished || captures.len() as u64 <= before {
        return None;
    }
    let c = &mut summary.checked;
    let count =
        |f: &dyn Fn(&CaptureRecord) -> bool| captures.iter().filter(|r| f(r)).count() as u64;
    c.captures = captures.len() as u64;
    c.ok = count(&|r| r.status == CaptureStatus::Ok);
    c.failed = count(&|r| r.status == CaptureStatus::Failed);
    c.missing = count(&|r| r.status == CaptureStatus::Missing);
    c.probes = count(&|r| r.probe);
    Some(before)
}

pub(crate) fn load(dir: &Path) -> Result<ReportInputs> {
    use crate::session::folder::{load_config, load_summary, read_complete_records};
    let (config, config_text) = load_config(dir)?;
    let mut summary = load_summary(dir)?;
    let captures = crate::session::folder::read_session_captures(dir)?;
    let summary_behind = catch_up_counts(&mut summary, &captures);
    let crossval = match std::fs::read(dir.join("crossval.json")) {
        Ok(b) => Some(serde_json::from_slice(&b).context("crossval.json")?),
        Err(_) => None,
    };
    Ok(ReportInputs {
        summary,
        config_text,
        config,
        captures,
        pairs: read_complete_records(&dir.join("pairs.jsonl"))?,
        alarms: read_complete_records(&dir.join("alarms.jsonl"))?,
        // sessions recorded before the sweep checks existed have no sweeps.jsonl (read as empty)
        sweeps: read_complete_records(&dir.join("sweeps.jsonl"))?,
        crossval,
        summary_behind,
        brdf: super::brdf_plots::load(dir),
    })
}

/// Every alarm raised, as the summary counts them (repeats included, with or without a capture).
fn alarm_total(inp: &ReportInputs) -> u64 {
    inp.summary.alarms.values().sum()
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A perceptually ordered ramp (viridis stops), t in [0, 1].
pub(super) fn ramp(t: f64) -> String {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f64;
    let c: Vec<u8> = (0..3)
        .map(|k| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// ΔE00 per plan entry (both captures of a pair carry its residual), exact and interpolated pairs.
fn residual_by_entry(pairs: &[PairRecord]) -> BTreeMap<usize, f64> {
    let mut m = BTreeMap::new();
    for p in pairs {
        if let (Some(d), "exact" | "interpolated") = (&p.diff, p.status.as_str()) {
            m.insert(p.entries[0], d.de2000);
            m.insert(p.entries[1], d.de2000);
        }
    }
    m
}

struct Plot {
    svg: String,
    w: f64,
    h: f64,
    l: f64,
    r: f64,
    t: f64,
    b: f64,
    x: (f64, f64),
    y: (f64, f64),
}

impl Plot {
    fn new(w: f64, h: f64, x: (f64, f64), y: (f64, f64), xlabel: &str, ylabel: &str) -> Plot {
        let mut p = Plot {
            svg: String::new(),
            w,
            h,
            l: 52.0,
            r: 14.0,
            t: 12.0,
            b: 40.0,
            x,
            y,
        };
        let _ = write!(
            p.svg,
            r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}" width="{w}" height="{h}" class="plot">"##
        );
        let (x0, y0, x1, y1) = (p.l, h - p.b, w - p.r, p.t);
        let _ = write!(
            p.svg,
            r##"<line x1="{x0}" y1="{y0}" x2="{x1}" y2="{y0}" stroke="#8a96a3"/><line x1="{x0}" y1="{y0}" x2="{x0}" y2="{y1}" stroke="#8a96a3"/>"##
        );
        for i in 0..=4 {
            let xv = x.0 + (x.1 - x.0) * i as f64 / 4.0;
            let yv = y.0 + (y.1 - y.0) * i as f64 / 4.0;
            let (sx, sy) = (p.sx(xv), p.sy(yv));
            let _ = write!(
                p.svg,
                r##"<text x="{sx:.1}" y="{:.1}" text-anchor="middle">{}</text><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
                y0 + 15.0,
                tick(xv, x.1 - x.0),
                x0 - 5.0,
                sy + 4.0,
                tick(yv, y.1 - y.0)
            );
            let _ = write!(
                p.svg,
                r##"<line x1="{x0}" y1="{sy:.1}" x2="{x1}" y2="{sy:.1}" stroke="#eef1f4"/>"##
            );
        }
        let _ = write!(
            p.svg,
            r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
            (x0 + x1) / 2.0,
            h - 6.0,
            esc(xlabel)
        );
        let _ = write!(
            p.svg,
            r##"<text x="12" y="{:.1}" text-anchor="middle" transform="rotate(-90 12 {:.1})">{}</text>"##,
            (y0 + y1) / 2.0,
            (y0 + y1) / 2.0,
            esc(ylabel)
        );
        p
    }
    fn sx(&self, v: f64) -> f64 {
        self.l + (v - self.x.0) / (self.x.1 - self.x.0).max(1e-300) * (self.w - self.l - self.r)
    }
    fn sy(&self, v: f64) -> f64 {
        self.h
            - self.b
            - (v - self.y.0) / (self.y.1 - self.y.0).max(1e-300) * (self.h - self.b - self.t)
    }
    fn finish(mut self) -> String {
        self.svg.push_str("</svg>");
        self.svg
    }
}

fn tick(v: f64, span: f64) -> String {
    if span.abs() < 0.05 {
        format!("{v:.3}")
    } else if span.abs() < 5.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.0}")
    }
}

/// Polar position of a direction in a disc of radius `r` centred at (cx, cy): θ/90° to the rim.
fn polar(theta_deg: f64, phi_deg: f64, cx: f64, cy: f64, r: f64) -> (f64, f64) {
    let rr = r * theta_deg / 90.0;
    let a = phi_deg.to_radians();
    (cx + rr * a.cos(), cy - rr * a.sin())
}

fn hemisphere_maps(inp: &ReportInputs, plan: &SamplingPlan) -> String {
    let by_entry = residual_by_entry(&inp.pairs);
    let mut vals: Vec<f64> = by_entry
        .values()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    vals.sort_by(f64::total_cmp);
    let top = percentile(&vals, 0.95).max(0.5);
    let dirs = plan.directions();
    let mut s = String::new();
    // overview: each light direction coloured by its mean residual
    let _ = write!(
        s,
        r##"<div class="maps"><figure><svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 260 260" width="260" height="260">"##
    );
    let _ = write!(
        s,
        r##"<circle cx="130" cy="130" r="118" fill="none" stroke="#c5ccd3"/>"##
    );
    for (l, d) in dirs.iter().enumerate() {
        let v: Vec<f64> = (0..dirs.len())
            .filter_map(|c| plan.index_of(l, c))
            .filter_map(|e| by_entry.get(&e).copied())
            .collect();
        let (x, y) = polar(d.theta_deg, d.phi_deg, 130.0, 130.0, 118.0);
        let (fill, title) = if v.is_empty() {
            ("#e8edf2".to_string(), "no pairs".to_string())
        } else {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (
                ramp(m / top),
                format!("mean ΔE00 {m:.2} over {} pairs", v.len()),
            )
        };
        let _ = write!(
            s,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="8" fill="{fill}" stroke="#8a96a3" stroke-width="0.5"><title>light θ {}°, φ {}°: {title}</title></circle>"##,
            d.theta_deg, d.phi_deg
        );
    }
    let _ = write!(
        s,
        r##"</svg><figcaption>Mean reciprocity residual (ΔE00) per light direction</figcaption></figure>"##
    );
    // legend
    let _ = write!(
        s,
        r##"<figure><svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 60 260" width="60" height="260">"##
    );
    for i in 0..50 {
        let t = 1.0 - i as f64 / 49.0;
        let _ = write!(
            s,
            r##"<rect x="8" y="{:.1}" width="14" height="4.8" fill="{}"/>"##,
            10.0 + i as f64 * 4.8,
            ramp(t)
        );
    }
    let _ = write!(
        s,
        r##"<text x="26" y="16">{top:.1}</text><text x="26" y="254">0</text></svg><figcaption>ΔE00</figcaption></figure></div>"##
    );
    // small multiples: one disc per light direction, its camera directions coloured by residual
    let _ = write!(s, r##"<div class="multiples">"##);
    for (l, d) in dirs.iter().enumerate() {
        let _ = write!(
            s,
            r##"<figure><svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 84 84" width="84" height="84"><circle cx="42" cy="42" r="38" fill="#f7f9fb" stroke="#c5ccd3" stroke-width="0.6"/>"##
        );
        for (c, dc) in dirs.iter().enumerate() {
            let (x, y) = polar(dc.theta_deg, dc.phi_deg, 42.0, 42.0, 38.0);
            let fill = plan
                .index_of(l, c)
                .and_then(|e| by_entry.get(&e))
                .map(|v| ramp(v / top))
                .unwrap_or_else(|| "#e1e6eb".into());
            let _ = write!(
                s,
                r##"<circle cx="{x:.1}" cy="{y:.1}" r="2.6" fill="{fill}"/>"##
            );
        }
        let (x, y) = polar(d.theta_deg, d.phi_deg, 42.0, 42.0, 38.0);
        let _ = write!(
            s,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="4" fill="none" stroke="#c62828" stroke-width="1.2"/></svg><figcaption>{}°/{}°</figcaption></figure>"##,
            d.theta_deg, d.phi_deg
        );
    }
    s.push_str("</div>");
    s
}

fn alarm_colour(a: &Alarm) -> &'static str {
    match a.severity {
        Severity::Critical => "#c62828",
        Severity::Warning => "#d17a00",
        Severity::Info => "#8a96a3",
    }
}

/// The isotropy-class gain estimate as it was known at each capture's time (the gain divided
/// out of that capture), thinned to about 400 points: (hours, gain, σ of ln gain).
fn isotropy_curve(inp: &ReportInputs) -> Vec<(f64, f64, f64)> {
    let all: Vec<(f64, f64, f64)> = inp
        .captures
        .iter()
        .filter(|c| !c.probe)
        .filter_map(|c| {
            let g = c.gain_corrected.as_ref()?;
            (g.source == "isotropy classes" && g.gain.is_finite() && g.sigma_rel.is_finite())
                .then_some((c.t / 3600.0, g.gain, g.sigma_rel))
        })
        .collect();
    thin(all, 400)
}

/// At most about `max` of `all`, evenly spaced, always with the first and the last.
fn thin<T: Copy>(all: Vec<T>, max: usize) -> Vec<T> {
    let n = all.len();
    let step = n.div_ceil(max.max(1)).max(1);
    let last = all.last().copied();
    let mut v: Vec<T> = all.into_iter().step_by(step).collect();
    if let Some(l) = last {
        if !(n - 1).is_multiple_of(step) {
            v.push(l);
        }
    }
    v
}

fn drift_plot(inp: &ReportInputs) -> String {
    let mut curve = crate::checks::ProbeGainCurve::new(inp.config.checks.dark_y);
    let gain: Vec<(f64, f64)> = inp.captures.iter().filter_map(|c| curve.add(c)).collect();
    let t_end = end_hours(inp);
    let est = inp.summary.probe_drift;
    // the estimate covers the probes since its last reset (a step restarts it): draw its line
    // through them, pivoting the ± 2 SE band about their mean time
    let fit = est.map(|d| {
        let recent = &gain[gain.len().saturating_sub(d.pairs)..];
        let r = d.rate_pct_per_h / 100.0;
        if recent.is_empty() {
            (d, 0.0, 0.0, 0.0)
        } else {
            let n = recent.len() as f64;
            let tm = recent.iter().map(|g| g.0).sum::<f64>() / n;
            let lm = recent
                .iter()
                .map(|g| g.1.ln() - r * (g.0 - tm))
                .sum::<f64>()
                / n;
            (d, recent[0].0, tm, lm)
        }
    });
    let curve = |k: f64, t: f64| -> f64 {
        match fit {
            Some((d, _, tm, lm)) => {
                (lm + (d.rate_pct_per_h + k * d.se_pct_per_h) / 100.0 * (t - tm)).exp()
            }
            None => 1.0,
        }
    };
    let iso = isotropy_curve(inp);
    let mut lo = gain.iter().map(|g| g.1).fold(1.0f64, f64::min);
    let mut hi = gain.iter().map(|g| g.1).fold(1.0f64, f64::max);
    // σ is the standard uncertainty of ln g: the band is g·exp(± 2σ)
    for (_, g, s) in &iso {
        lo = lo.min(g * (-2.0 * s).exp());
        hi = hi.max(g * (2.0 * s).exp());
    }
    if let Some((_, t0, _, _)) = fit {
        for k in [-2.0, 2.0] {
            for t in [t0, t_end] {
                lo = lo.min(curve(k, t));
                hi = hi.max(curve(k, t));
            }
        }
    }
    let pad = ((hi - lo) * 0.1).max(0.005);
    let mut p = Plot::new(
        720.0,
        260.0,
        (0.0, t_end),
        (lo - pad, hi + pad),
        "controller time [h]",
        "relative gain",
    );
    if let Some((_, t0, _, _)) = fit {
        let n = 40;
        let pts = |k: f64| -> Vec<String> {
            (0..=n)
                .map(|i| {
                    let t = t0 + (t_end - t0) * i as f64 / n as f64;
                    format!("{:.1},{:.1}", p.sx(t), p.sy(curve(k, t)))
                })
                .collect()
        };
        let mut band = pts(2.0);
        let mut lower = pts(-2.0);
        let centre = pts(0.0);
        lower.reverse();
        band.extend(lower);
        let _ = write!(
            p.svg,
            r##"<polygon points="{}" fill="rgba(31,95,168,0.18)"/>"##,
            band.join(" ")
        );
        let _ = write!(
            p.svg,
            r##"<polyline points="{}" fill="none" stroke="#1f5fa8" stroke-width="2"/>"##,
            centre.join(" ")
        );
    } else if iso.len() < 2 {
        let _ = write!(
            p.svg,
            r##"<text x="{:.1}" y="{:.1}" text-anchor="middle">no gain estimate: drift probes were off (or too few) and the sample is not isotropic</text>"##,
            p.sx(t_end / 2.0),
            p.sy((lo + hi) / 2.0) - 20.0
        );
    }
    if iso.len() >= 2 {
        let mut band: Vec<String> = iso
            .iter()
            .map(|(t, g, s)| format!("{:.1},{:.1}", p.sx(*t), p.sy(g * (2.0 * s).exp())))
            .collect();
        band.extend(
            iso.iter()
                .rev()
                .map(|(t, g, s)| format!("{:.1},{:.1}", p.sx(*t), p.sy(g * (-2.0 * s).exp()))),
        );
        let line: Vec<String> = iso
            .iter()
            .map(|(t, g, _)| format!("{:.1},{:.1}", p.sx(*t), p.sy(*g)))
            .collect();
        let _ = write!(
            p.svg,
            r##"<polygon points="{}" fill="rgba(46,125,50,0.15)"/><polyline points="{}" fill="none" stroke="#2e7d32" stroke-width="2"><title>isotropy-class gain estimate, as known at each capture</title></polyline>"##,
            band.join(" "),
            line.join(" ")
        );
    }
    let (y1a, y1b) = (p.sy(1.0), p.sy(1.0));
    let _ = write!(
        p.svg,
        r##"<line x1="{:.1}" y1="{y1a:.1}" x2="{:.1}" y2="{y1b:.1}" stroke="#8a96a3" stroke-dasharray="4 3"/>"##,
        p.sx(0.0),
        p.sx(t_end)
    );
    for (t, g) in &gain {
        let _ = write!(
            p.svg,
            r##"<circle cx="{:.1}" cy="{:.1}" r="3" fill="#1f5fa8"/>"##,
            p.sx(*t),
            p.sy(*g)
        );
    }
    // alarms on the time axis
    alarm_ticks(&mut p, inp.alarms.iter());
    p.finish()
}

/// The lamp's chromaticity change as known at each capture's time (what the corrected output
/// divides out): (hours, ln X/Y, ln Z/Y), thinned to about 400 points.
fn colour_curve(inp: &ReportInputs) -> Vec<(f64, f64, f64)> {
    let all: Vec<(f64, f64, f64)> = inp
        .captures
        .iter()
        .filter(|c| !c.probe)
        .filter_map(|c| {
            let [u, v] = c.gain_corrected.as_ref()?.colour?;
            (u.is_finite() && v.is_finite()).then_some((c.t / 3600.0, u, v))
        })
        .collect();
    thin(all, 400)
}

/// The chromaticity drift over the run: ln(X/Y) (red) and ln(Z/Y) (blue) of the lamp against
/// the start, in %, with the alarms on the time axis.
fn colour_plot(inp: &ReportInputs) -> String {
    let pts = colour_curve(inp);
    let t_end = end_hours(inp);
    let lo = pts.iter().flat_map(|p| [p.1, p.2]).fold(0.0f64, f64::min) * 100.0;
    let hi = pts.iter().flat_map(|p| [p.1, p.2]).fold(0.0f64, f64::max) * 100.0;
    let pad = ((hi - lo) * 0.1).max(0.2);
    let mut p = Plot::new(
        720.0,
        220.0,
        (0.0, t_end),
        (lo - pad, hi + pad),
        "controller time [h]",
        "chromaticity change [%]",
    );
    for (k, colour, what) in [(1, "#c62828", "ln X/Y"), (2, "#1f5fa8", "ln Z/Y")] {
        let line: Vec<String> = pts
            .iter()
            .map(|q| {
                let v = if k == 1 { q.1 } else { q.2 };
                format!("{:.1},{:.1}", p.sx(q.0), p.sy(100.0 * v))
            })
            .collect();
        let _ = write!(
            p.svg,
            r##"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="2"><title>{what} of the lamp against the start, as known at each capture</title></polyline>"##,
            line.join(" ")
        );
    }
    zero_line(&mut p, t_end);
    alarm_ticks(&mut p, inp.alarms.iter());
    p.finish()
}

/// A tick per alarm on a time plot's axis (controller hours), coloured by severity, with the
/// message as its tooltip.
fn alarm_ticks<'a>(p: &mut Plot, alarms: impl Iterator<Item = &'a Alarm>) {
    let base = p.h - p.b;
    for a in alarms {
        let Some(t) = a.t else { continue };
        let x = p.sx(t / 3600.0);
        let _ = write!(
            p.svg,
            r##"<line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{base:.1}" stroke="{}" stroke-width="2.5"><title>{}</title></line>"##,
            base - 20.0,
            alarm_colour(a),
            esc(&format!("{} at {:.2} h: {}", a.code, t / 3600.0, a.message))
        );
    }
}

/// The last capture's controller time (hours; at least 0.1), the end of the time axes.
fn end_hours(inp: &ReportInputs) -> f64 {
    inp.captures
        .iter()
        .map(|c| c.t / 3600.0)
        .fold(0.0f64, f64::max)
        .max(0.1)
}

/// A dashed line at y = 0 across a time plot, from 0 to `t_end` hours.
fn zero_line(p: &mut Plot, t_end: f64) {
    let z = p.sy(0.0);
    let _ = write!(
        p.svg,
        r##"<line x1="{:.1}" y1="{z:.1}" x2="{:.1}" y2="{z:.1}" stroke="#8a96a3" stroke-dasharray="4 3"/>"##,
        p.sx(0.0),
        p.sx(t_end)
    );
}

/// A plot over controller time (hours, from 0 to `t_end`), with a dashed line at y = 0.
fn time_plot(h: f64, t_end: f64, y: (f64, f64), ylabel: &str) -> Plot {
    let mut p = Plot::new(720.0, h, (0.0, t_end), y, "controller time [h]", ylabel);
    zero_line(&mut p, t_end);
    p
}

/// Which alarms a time plot of the light sweeps marks.
fn sweep_ticked(a: &Alarm) -> bool {
    matches!(
        a.code.as_str(),
        "joint-offset-suspected" | "gain-step" | "gain-drift" | "encoder-mismatch"
    )
}

/// The light sweeps' gain level less what the sweep's θ layer predicts (± 2 SE), over
/// controller time, with the drift and positioning alarms.
fn sweep_levels_plot(inp: &ReportInputs) -> String {
    let t_end = end_hours(inp);
    let (mut lo, mut hi): (f64, f64) = (-0.5, 0.5);
    let level = |r: &SweepRecord| r.level_pct - r.level_expected_pct;
    for r in &inp.sweeps {
        lo = lo.min(level(r) - 2.0 * r.level_se_pct);
        hi = hi.max(level(r) + 2.0 * r.level_se_pct);
    }
    let (lo, hi) = (lo.max(-10.0), hi.min(10.0));
    let mut p = time_plot(200.0, t_end, (lo, hi), "level − layer's prediction [%]");
    for r in &inp.sweeps {
        let v = level(r);
        let x = p.sx(r.t / 3600.0);
        let (y, ya, yb) = (
            p.sy(v.clamp(lo, hi)),
            p.sy((v - 2.0 * r.level_se_pct).clamp(lo, hi)),
            p.sy((v + 2.0 * r.level_se_pct).clamp(lo, hi)),
        );
        let _ = write!(
            p.svg,
            r##"<line x1="{x:.1}" y1="{ya:.1}" x2="{x:.1}" y2="{yb:.1}" stroke="#1f5fa8" stroke-opacity="0.5"/><circle cx="{x:.1}" cy="{y:.1}" r="2.5" fill="#1f5fa8"><title>light {}: {v:+.2} % ± {:.2} against the layer's prediction {:+.2} %</title></circle>"##,
            r.light, r.level_se_pct, r.level_expected_pct
        );
    }
    alarm_ticks(&mut p, inp.alarms.iter().filter(|a| sweep_ticked(a)));
    p.finish()
}

/// The light sweeps: each sweep's fitted offset of joints 1 and 2 (± 1 SE), over controller
/// time, with the drift and positioning alarms.
fn sweeps_plot(inp: &ReportInputs) -> String {
    let t_end = end_hours(inp);
    let mut lo: f64 = -0.5;
    let mut hi: f64 = 0.5;
    for r in &inp.sweeps {
        for j in &r.joints {
            lo = lo.min(j.offset_deg - j.se_deg);
            hi = hi.max(j.offset_deg + j.se_deg);
        }
    }
    let (lo, hi) = (lo.max(-5.0), hi.min(5.0));
    let mut p = time_plot(240.0, t_end, (lo, hi), "fitted joint offset [°]");
    for (joint, colour, dx) in [(1usize, "#1f5fa8", -0.004), (2, "#d9822b", 0.004)] {
        for r in &inp.sweeps {
            let Some(j) = r.joints.iter().find(|j| j.joint == joint) else {
                continue;
            };
            let x = p.sx(r.t / 3600.0 + dx * t_end);
            let (y, ya, yb) = (
                p.sy(j.offset_deg.clamp(lo, hi)),
                p.sy((j.offset_deg - j.se_deg).clamp(lo, hi)),
                p.sy((j.offset_deg + j.se_deg).clamp(lo, hi)),
            );
            let _ = write!(
                p.svg,
                r##"<line x1="{x:.1}" y1="{ya:.1}" x2="{x:.1}" y2="{yb:.1}" stroke="{colour}"/><circle cx="{x:.1}" cy="{y:.1}" r="2.5" fill="{colour}"><title>light {}: joint {joint} {:+.2}° ± {:.2}</title></circle>"##,
                r.light, j.offset_deg, j.se_deg
            );
        }
    }
    alarm_ticks(&mut p, inp.alarms.iter().filter(|a| sweep_ticked(a)));
    p.finish()
}

fn histogram(inp: &ReportInputs) -> String {
    let mut exact: Vec<f64> = Vec::new();
    let mut interp: Vec<f64> = Vec::new();
    for p in &inp.pairs {
        if let Some(d) = &p.diff {
            match p.status.as_str() {
                "exact" => exact.push(d.de2000),
                "interpolated" => interp.push(d.de2000),
                _ => {}
            }
        }
    }
    let mut all: Vec<f64> = exact
        .iter()
        .chain(&interp)
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    all.sort_by(f64::total_cmp);
    let top = percentile(&all, 0.99).max(0.5);
    let nb = 40usize;
    let w = top / nb as f64;
    let count = |v: &[f64]| {
        let mut h = vec![0usize; nb];
        for x in v {
            let k = ((x / w).floor().max(0.0) as usize).min(nb - 1);
            h[k] += 1;
        }
        h
    };
    let (he, hi) = (count(&exact), count(&interp));
    let ymax = he.iter().chain(&hi).copied().max().unwrap_or(1).max(1) as f64;
    let mut p = Plot::new(
        720.0,
        240.0,
        (0.0, top),
        (0.0, ymax * 1.05),
        "CIEDE2000 of a pair (last bin: and above)",
        "pairs",
    );
    for (k, n) in he.iter().enumerate() {
        let (x0, x1) = (p.sx(k as f64 * w), p.sx((k + 1) as f64 * w));
        let (y0, y1) = (p.sy(*n as f64), p.sy(0.0));
        let _ = write!(
            p.svg,
            r##"<rect x="{x0:.1}" y="{y0:.1}" width="{:.1}" height="{:.1}" fill="#1f5fa8" opacity="0.8"/>"##,
            (x1 - x0 - 1.0).max(0.5),
            y1 - y0
        );
    }
    for (k, n) in hi.iter().enumerate().filter(|(_, n)| **n > 0) {
        let (x0, x1) = (p.sx(k as f64 * w), p.sx((k + 1) as f64 * w));
        let y0 = p.sy(*n as f64);
        let _ = write!(
            p.svg,
            r##"<line x1="{x0:.1}" y1="{y0:.1}" x2="{x1:.1}" y2="{y0:.1}" stroke="#e07b00" stroke-width="3"/>"##
        );
    }
    p.finish()
}

fn table2_rows(sets: &[(&str, &Table2)]) -> String {
    let mut s = String::from("<table><thead><tr><th></th><th>pairs</th><th>|ΔX|</th><th>|ΔY|</th><th>|ΔZ|</th><th>ΔE*ab</th><th>ΔC*ab</th><th>ΔH*ab</th><th>ΔE00</th></tr></thead><tbody>");
    for (name, t) in sets {
        let _ = write!(s, "<tr><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>", esc(name), t.pairs, t.abs_dx, t.abs_dy, t.abs_dz, t.de76, t.dc, t.dh, t.de2000);
    }
    s.push_str("</tbody></table>");
    s
}

fn table3_html(c: &CompareReport) -> String {
    let mut s = String::new();
    let x = &c.result;
    let _ = write!(s, "<p>Against <b>{}</b> ({} samples, θi layers {}°): {} captures compared, {} not reached by the reference, {} where the resampled reference is uncertain by more than {:.0} %, {} grazing.</p>",
        esc(c.reference_name.as_deref().unwrap_or("the reference")), c.reference_samples,
        x.reference_layers_deg.iter().map(|t| format!("{t:.0}")).collect::<Vec<_>>().join(", "),
        x.captures_compared, x.captures_not_covered, x.captures_reference_uncertain, 100.0 * x.max_reference_spread, x.captures_grazing);
    let mut tables = vec![("as measured".to_string(), &x.table3)];
    if let Some((g, t)) = &x.gain_corrected {
        tables.push((
            format!(
                "gain-corrected ({:+.3} ± {:.3} %/h, {})",
                g.rate_pct_per_h, g.se_pct_per_h, g.source
            ),
            t,
        ));
    }
    s.push_str("<table><thead><tr><th></th><th>metric</th><th>max</th><th>avg</th><th>median</th><th>κ(T), columns scaled</th></tr></thead><tbody>");
    for (name, t) in &tables {
        let flag = if t.transform.ill_conditioned {
            " (ill-conditioned)"
        } else {
            ""
        };
        let _ = write!(s, "<tr><td rowspan=2>{}</td><td>ΔE*ab</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td rowspan=2>{:.0}{flag}</td></tr><tr><td>CIEDE2000</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td></tr>",
            esc(name), t.de76.max, t.de76.avg, t.de76.median, t.transform.condition_scaled, t.de2000.max, t.de2000.avg, t.de2000.median);
    }
    s.push_str("</tbody></table>");
    if let Some(w) = x.table3.worst.first() {
        let _ = write!(s, "<p>Largest deviation: capture {} (θi {:.1}°, φi {:.1}°, θo {:.1}°, φo {:.1}°) at ΔE00 {:.2}.</p>", w.idx, w.angles_deg[0], w.angles_deg[1], w.angles_deg[2], w.angles_deg[3], w.de2000);
    }
    s
}

/// A files source's accounting: plan entries without a capture, entries with more than one
/// file (which one was checked), and the files not placed with why. Empty for a rig session
/// with none of these.
fn files_section(inp: &ReportInputs) -> String {
    let s = &inp.summary;
    let skipped: u64 = s.files_skipped.values().sum();
    if s.entries_not_captured == 0 && s.entries_with_duplicates == 0 && skipped == 0 {
        return String::new();
    }
    let mut h = String::from("<h2>Plan entries and files</h2><table>");
    let _ = write!(
        h,
        "<tr><td>plan entries without a capture{}</td><td>{}</td></tr>",
        if s.finished {
            " (on the retake list)"
        } else {
            " so far"
        },
        s.entries_not_captured
    );
    let _ = write!(
        h,
        "<tr><td>plan entries with more than one file (one checked)</td><td>{}</td></tr>",
        s.entries_with_duplicates
    );
    for (kind, n) in &s.files_skipped {
        let _ = write!(
            h,
            "<tr><td>files not placed: {}</td><td>{n}</td></tr>",
            esc(kind)
        );
    }
    h.push_str("</table>");
    const SHOWN: usize = 200;
    let mut rows: Vec<(String, String)> = Vec::new();
    for a in inp.alarms.iter() {
        match &a.evidence {
            Evidence::DuplicateFiles(d) => {
                for g in &d.groups {
                    for o in &g.others {
                        rows.push((
                            o.clone(),
                            format!("plan entry {} again ({} is checked)", g.entry, g.kept),
                        ));
                    }
                }
            }
            Evidence::SkippedFiles(sk) => {
                for f in &sk.files {
                    rows.push((f.file.clone(), f.why.clone()));
                }
            }
            _ => {}
        }
    }
    if !rows.is_empty() {
        rows.sort();
        rows.dedup();
        let _ = write!(
            h,
            "<table class=alarms><thead><tr><th>file not placed</th><th>why</th></tr></thead><tbody>"
        );
        for (f, why) in rows.iter().take(SHOWN) {
            let _ = write!(h, "<tr><td>{}</td><td>{}</td></tr>", esc(f), esc(why));
        }
        h.push_str("</tbody></table>");
        if rows.len() > SHOWN {
            let _ = write!(
                h,
                "<p class=muted>… and {} more (the alarms' evidence in alarms.jsonl has them all).</p>",
                rows.len() - SHOWN
            );
        }
    }
    h
}

/// The report on paper (A4; the margins suit Letter too): one column the page's width, every plot
/// scaled to it (an SVG keeps its aspect ratio through its viewBox) and kept whole on one page
/// with its caption, headings (and the paragraph that introduces a plot) kept with what follows
/// them, long tables broken between rows with their header repeated on the next page, the
/// configuration wrapped instead of clipped, links as plain text (the alarm codes stay links
/// inside a PDF), no background tint. A small multiple of the residual maps is a plot of its own:
/// the grid of them may break between its rows. Nothing may be wider than the page: a browser
/// shrinks the whole report to fit its widest block.
const PRINT_STYLE: &str = "\
@page{size:A4;margin:14mm 12mm 16mm}
@media print{
body{font-size:10pt;line-height:1.35;max-width:none;margin:0;padding:0;color:#000;background:#fff}
h1{font-size:16pt} h2{font-size:13pt;margin-top:16pt} h3{font-size:11pt}
h1,h2,h3,p:has(+ figure,+ .maps){break-after:avoid;page-break-after:avoid}
figure,figcaption,.maps,.alarm-entry{break-inside:avoid;page-break-inside:avoid}
.multiples{grid-template-columns:repeat(9,minmax(0,1fr))}
table{max-width:100%} thead{display:table-header-group}
tr{break-inside:avoid;page-break-inside:avoid}
table.alarms td{overflow-wrap:anywhere}
pre{white-space:pre-wrap;overflow-wrap:anywhere;overflow:visible;background:none;border:1px solid #c5ccd3;font-size:8pt}
a,td a{color:inherit;text-decoration:none}
}
";

/// A plot as a figure of the report: what the print style keeps whole on one page.
fn figure(svg: &str) -> String {
    format!("<figure>{svg}</figure>")
}

/// The report's HTML.
pub(crate) fn render_html(inp: &ReportInputs) -> Result<String> {
    let plan = crate::setup::plan(&inp.config).context("the session's plan")?;
    let s = &inp.summary;
    let c = &s.checked;
    let mut h = String::new();
    let title = format!(
        "goniowatch report: session {}",
        s.session.as_deref().unwrap_or("?")
    );
    let _ = write!(
        h,
        r##"<!doctype html><html lang="en"><head><meta charset="utf-8"><title>{}</title><style>
body{{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d232a;max-width:1100px;margin:24px auto;padding:0 18px}}
h1{{font-size:22px}} h2{{font-size:17px;margin-top:28px;border-bottom:1px solid #d9dee3;padding-bottom:4px}}
table{{border-collapse:collapse;margin:8px 0}} td,th{{padding:3px 10px;border-bottom:1px solid #eef1f4;text-align:right;font-variant-numeric:tabular-nums}} td:first-child,th:first-child{{text-align:left}}
.muted{{color:#5d6b78}} .maps{{display:flex;gap:8px;align-items:flex-start}} figure{{margin:0}} figcaption{{font-size:11px;color:#5d6b78;text-align:center}}
.multiples{{display:grid;grid-template-columns:repeat(9,84px);gap:4px;margin-top:10px}}
svg text{{font:11px system-ui,sans-serif;fill:#5d6b78}} pre{{background:#f5f7f9;padding:10px;overflow:auto;font-size:12px}}
table.alarms td,table.alarms th{{text-align:left}} table.alarms td:nth-child(3){{white-space:nowrap}}
.sev-critical{{color:#c62828;font-weight:600}} .sev-warning{{color:#b86e00;font-weight:600}} .sev-info{{color:#5d6b78}}
figure svg{{max-width:100%;height:auto}} td a{{color:inherit;text-decoration:underline dotted}}
{entry_style}{print_style}</style></head><body>"##,
        esc(&title),
        entry_style = crate::checks::catalogue::ENTRY_STYLE,
        print_style = PRINT_STYLE,
    );
    let _ = write!(
        h,
        "<h1>{}</h1><p class=muted>rig {} · {} · {} of {} planned captures checked{}</p>",
        esc(&title),
        esc(s.rig.as_deref().unwrap_or("?")),
        esc(&inp.config.sample.name),
        c.captures.saturating_sub(c.probes),
        s.captures_planned,
        if s.finished {
            " · run finished".to_string()
        } else if let Some(before) = inp.summary_behind {
            format!(" · run not finished; it stopped after its summary was last written ({before} captures): the capture counts are those of captures.jsonl, the pairs and tables those of the summary")
        } else {
            " · run not finished".to_string()
        }
    );

    // summary
    let _ = write!(h, "<h2>Summary</h2><table><tr><td>captures checked</td><td>{}</td></tr><tr><td>usable</td><td>{}</td></tr><tr><td>failed</td><td>{}</td></tr><tr><td>missing</td><td>{}</td></tr><tr><td>drift probes</td><td>{}</td></tr><tr><td>exact reciprocal pairs</td><td>{}</td></tr><tr><td>occlusion substitutes vs interpolated partner</td><td>{} ({} unresolved)</td></tr><tr><td>pairs needing resampling / grazing</td><td>{} / {}</td></tr><tr><td>isotropy comparisons</td><td>{}</td></tr><tr><td>captures off the plan / encoders against commands</td><td>{} / {}</td></tr><tr><td>alarms</td><td>{}</td></tr></table>",
        c.captures, c.ok, c.failed, c.missing, c.probes, c.pairs_exact, c.pairs_interpolated, c.pairs_unresolved, c.pairs_needs_resampling, c.pairs_grazing, c.isotropy_comparisons, c.pose_off_plan, c.encoder_mismatch, alarm_total(inp));

    h.push_str(&files_section(inp));

    let _ = write!(h, "<h2>Reciprocity (the paper's Table 2)</h2><p class=muted>Means over pairs after the cosine re-correction; XYZ on the configured scale, L*a*b* under the configured white.</p>");
    let mut sets: Vec<(&str, &Table2)> = vec![("exact reciprocal pairs", &s.table2)];
    if !s.by_command.is_empty() {
        sets.push(("of which placed by the commanded pose", &s.by_command));
    }
    if s.interpolated.pairs > 0 {
        sets.push(("substitutes vs interpolated partner", &s.interpolated));
    }
    if s.isotropy.pairs > 0 {
        sets.push(("isotropy (capture vs class mean)", &s.isotropy));
    }
    h.push_str(&table2_rows(&sets));
    h.push_str("<h3>Residual per light direction</h3><p class=muted>Centre: θ = 0°, rim: θ = 90°, φ counter-clockwise from the right. The small discs show, for each light direction (ringed), the residual of every camera direction's pair.</p>");
    h.push_str(&hemisphere_maps(inp, &plan));
    h.push_str("<h3>Distribution</h3><p class=muted>Bars: exact pairs; orange marks: substitutes against their interpolated partner.</p>");
    h.push_str(&figure(&histogram(inp)));

    if !s.observability.blind.is_empty() {
        h.push_str("<h2>What this session could not see</h2><ul>");
        for b in &s.observability.blind {
            let _ = write!(
                h,
                "<li><b>{}</b>: {}. To observe it: {}.</li>",
                esc(&b.what),
                esc(&b.why),
                esc(&b.remedy)
            );
        }
        h.push_str("</ul>");
    }
    let _ = write!(h, "<h2>Gain drift</h2>");
    if let Some(d) = &s.isotropy_drift {
        let _ = write!(h, "<p>From {} isotropy comparisons (each capture against the first capture of the same geometry): <b>{:+.3} ± {:.3} %/h</b> (standard error; a rate over the whole run: steps are not in it). captures.csv carries every capture's colour with the drift known at its time divided out.</p>", d.pairs, d.rate_pct_per_h, d.se_pct_per_h);
    }
    match &s.probe_drift {
        Some(d) => {
            let _ = write!(h, "<p>From the last {} drift probes (a step restarts the estimate): <b>{:+.3} ± {:.3} %/h</b> (standard error). The dots are all probes (luminance over the original capture of the same pose); the line is the fitted drift over the probes it uses, the band ± 2 standard errors of the rate; ticks on the time axis are alarms (orange warnings, red critical, grey info).</p>", d.pairs, d.rate_pct_per_h, d.se_pct_per_h);
        }
        None if isotropy_curve(inp).len() >= 2 => h.push_str("<p>No probe estimate: drift probes were off (`[probes] every`) or too few. The green line is the isotropy-class gain estimate as it was known at each capture's time (the gain divided out of that capture), the band a factor exp(± 2σ) with σ the standard uncertainty of its logarithm; ticks on the time axis are the alarms.</p>"),
        None => h.push_str("<p>No gain estimate: drift probes were off (`[probes] every`) or too few, and the isotropy classes gave none (they need an isotropic sample and repeated geometries). Ticks on the time axis are the alarms.</p>"),
    }
    h.push_str(&figure(&drift_plot(inp)));

    if let Some(c) = &s.colour_drift {
        let _ = write!(h, "<h2>Lamp colour</h2><p>From {} observations ({}: the same geometry at other times), the chromaticity over time (ln X/Y and ln Z/Y, each a rate fit like the gain's), read through a black-body lamp at {:.0} K: <b>{:+.1} ± {:.1} K/h</b> (standard error; negative is redder), ΔE00 {:.3} per hour on a white. The corrected colours in captures.csv have this drift divided out of X and Z. The lines are the chromaticity change as known at each capture's time (red ln X/Y, blue ln Z/Y); ticks are the alarms.</p>",
            c.observations, esc(c.source.as_str()), c.lamp_cct_k, c.k_per_h, c.se_k_per_h, c.de00_per_h);
        h.push_str(&figure(&colour_plot(inp)));
    }

    if !inp.sweeps.is_empty() {
        let last = inp.sweeps.last();
        let _ = write!(h, "<h2>Light sweeps</h2><p>{} completed light directions were each compared with the earlier ones (isotropy classes; ARCHITECTURE.md). The first plot is each sweep's gain level less what its θ layer's earlier lights predict (± 2 standard errors): a lamp step moves every later sweep. In the second, a slipped arm joint shows as a run of sweeps whose fitted offset (dots ± 1 standard error; blue joint 1, orange joint 2) leaves zero; these per-sweep fits are biased towards zero, so read them as a lower bound; a joint alarm's own size is fitted afresh against the captures before the slip with a smooth model of the BRDF, and is not. Joint 3 cannot be seen on an isotropic sample. Ticks are drift and positioning alarms. The last sweep's gain level against the earlier ones: {}. sweeps.csv has every sweep.</p>",
            inp.sweeps.len(),
            last.map(|r| esc(&super::summary::sweep_level_words(r))).unwrap_or_default());
        h.push_str(&figure(&sweep_levels_plot(inp)));
        h.push_str(&figure(&sweeps_plot(inp)));
    }

    if let Some(cv) = &inp.crossval {
        h.push_str("<h2>Cross-validation (the paper's Table 3)</h2>");
        h.push_str(&table3_html(cv));
    }

    if let Some(b) = &inp.brdf {
        h.push_str(&super::brdf_plots::section(b, figure));
    }

    // capture quality
    let nonfinite: u64 = inp.captures.iter().filter_map(|c| c.nonfinite).sum();
    let clipped_caps = inp
        .captures
        .iter()
        .filter(|c| c.clipped.unwrap_or(0) > 0)
        .count();
    let max_pose = inp
        .captures
        .iter()
        .filter_map(|c| c.pose_error_deg)
        .fold(0.0f64, f64::max);
    let subs = inp
        .captures
        .iter()
        .filter(|c| c.substitute.is_some())
        .count();
    let _ = write!(h, "<h2>Capture quality</h2><table><tr><td>non-finite pixels (left out of the means)</td><td>{nonfinite}</td></tr><tr><td>captures with clipped pixels</td><td>{clipped_caps}</td></tr><tr><td>occlusion substitutes</td><td>{subs}</td></tr><tr><td>largest pose error (encoders vs plan)</td><td>{max_pose:.3}°</td></tr></table>");

    let l = &s.link;
    let _ = write!(h, "<h2>Link</h2><table><tr><td>lines received</td><td>{}</td></tr><tr><td>CRC errors</td><td>{}</td></tr><tr><td>framing errors</td><td>{}</td></tr><tr><td>sequence gaps</td><td>{}</td></tr><tr><td>port opened / lost</td><td>{} / {}</td></tr><tr><td>controller reboots</td><td>{}</td></tr><tr><td>resyncs</td><td>{}</td></tr><tr><td>daemon restarts</td><td>{}</td></tr></table>",
        l.lines, l.crc_errors, l.framing_errors, l.sequence_gaps, l.connects, l.disconnects, l.reboots, l.resyncs, l.restarts);

    let total = alarm_total(inp);
    let _ = write!(h, "<h2>Alarms ({total})</h2>");
    if total > inp.alarms.len() as u64 {
        let _ = write!(
            h,
            "<p class=muted>{total} alarms were raised; repeats of one kind beyond five in a short span are written as one line with their count, so alarms.jsonl has {} lines.</p>",
            inp.alarms.len()
        );
    }
    if inp.alarms.is_empty() {
        h.push_str("<p>None.</p>");
    } else {
        let mut by_code: BTreeMap<AlarmCode, usize> = BTreeMap::new();
        for a in &inp.alarms {
            *by_code.entry(a.code).or_default() += 1;
        }
        h.push_str("<p>");
        h.push_str(
            &by_code
                .iter()
                .map(|(code, n)| {
                    format!(
                        "{n} × <a href=\"#{}\">{}</a>",
                        esc(&crate::checks::catalogue::anchor(*code)),
                        esc(code.as_str())
                    )
                })
                .collect::<Vec<_>>()
                .join(", "),
        );
        h.push_str("</p><table class=alarms><thead><tr><th>capture</th><th>time [h]</th><th>alarm</th><th>message</th><th>what to do</th><th>captures affected</th></tr></thead><tbody>");
        for a in inp.alarms.iter().take(300) {
            let sev = serde_json::to_value(a.severity)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td class=\"sev-{sev}\"><a href=\"#{}\">{}</a></td><td>{}</td><td>{}</td><td>{}</td></tr>",
                a.idx.map(|i| i.to_string()).unwrap_or_default(),
                a.t.map(|t| format!("{:.2}", t / 3600.0))
                    .unwrap_or_default(),
                esc(&crate::checks::catalogue::anchor(a.code)),
                esc(a.code.as_str()),
                esc(&a.message),
                esc(a.action.as_deref().unwrap_or("")),
                esc(&a.affects.as_ref().map(Affects::describe).unwrap_or_default())
            );
        }
        h.push_str("</tbody></table>");
        if inp.alarms.len() > 300 {
            let _ = write!(
                h,
                "<p class=muted>… and {} more in alarms.csv.</p>",
                inp.alarms.len() - 300
            );
        }
    }
    let _ = write!(
        h,
        "<h2>Configuration</h2><pre>{}</pre>",
        esc(&inp.config_text)
    );
    // the retake list ends the report's body: what to take again, and why
    let retakes = session_retakes(inp);
    h.push_str("<h2>Retake list</h2>");
    if retakes.is_empty() {
        h.push_str("<p>No capture needs taking again: none failed, went missing, was dark or had bad pixels, was taken off the plan, or came after a slipped joint. (Lamp drift is not a reason: the corrected colours divide it out.)</p>");
    } else {
        let plan = crate::setup::plan(&inp.config).ok();
        let _ = write!(h, "<p><b>{} captures</b> should be taken again (retakes.csv has them all; lamp drift is not a reason, the corrected colours divide it out):</p><table><thead><tr><th>capture</th><th>plan entry</th><th>light (θ, φ)</th><th>camera (θ, φ)</th><th>why</th></tr></thead><tbody>", retakes.len());
        let dir = |k: usize| {
            plan.as_ref()
                .and_then(|p| {
                    p.directions()
                        .get(k)
                        .map(|d| format!("{}°, {}°", d.theta_deg, d.phi_deg))
                })
                .unwrap_or_else(|| k.to_string())
        };
        for r in retakes.iter().take(300) {
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                opt(r.idx),
                r.entry,
                dir(r.light),
                dir(r.camera),
                esc(&r.why)
            );
        }
        h.push_str("</tbody></table>");
        if retakes.len() > 300 {
            let _ = write!(
                h,
                "<p class=muted>… and {} more in retakes.csv.</p>",
                retakes.len() - 300
            );
        }
    }
    h.push_str(&alarm_appendix(inp));
    h.push_str("<p class=muted>Tables as CSV beside this file: captures.csv, pairs.csv, alarms.csv, table2.csv, light_residuals.csv, retakes.csv, sweeps.csv (isotropic samples) and table3.csv (after a cross-validation).</p></body></html>\n");
    Ok(h)
}

/// The appendix after the retake list: the catalogue's entry of every alarm code the session
/// raised (those in alarms.jsonl and those the summary counts), each under its anchor
/// `alarm-<code>` that the alarm table links to. Empty for a session without alarms.
fn alarm_appendix(inp: &ReportInputs) -> String {
    let codes: std::collections::BTreeSet<AlarmCode> = inp
        .alarms
        .iter()
        .map(|a| a.code)
        .chain(inp.summary.alarms.keys().filter_map(|k| k.parse().ok()))
        .collect();
    if codes.is_empty() {
        return String::new();
    }
    format!(
        "<h2 id=\"appendix-alarms\">Appendix: the alarm codes of this session</h2><p class=muted>Each code's entry in goniowatch's alarm catalogue (<code>goniowatch alarms</code>; docs/alarms.md).</p>{}",
        crate::checks::catalogue::entries_html(codes)
    )
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|x| x.to_string()).unwrap_or_default()
}

/// The CSV files: (name, contents).
/// A record that is a row of one of the report's CSV tables: it owns its header and its row.
trait CsvRow {
    const HEADER: &'static str;
    fn row(&self) -> String;
}

/// A CSV table: the header, then one row per record.
fn csv_table<T: CsvRow>(records: &[T]) -> String {
    let mut out = String::from(T::HEADER);
    out.push('\n');
    for r in records {
        out.push_str(&r.row());
        out.push('\n');
    }
    out
}

impl CsvRow for CaptureRecord {
    const HEADER: &'static str = "idx,entry,light,camera,probe,t_s,status,theta_i,phi_i,theta_o,phi_o,R,G,B,X,Y,Z,L,a,b,pixels,nonfinite,clipped,pose_error_deg,by_command,substitute_theta_i,X_gain_corrected,Y_gain_corrected,Z_gain_corrected,gain,gain_sigma_rel,gain_source,error";
    fn row(&self) -> String {
        let c = self;
        let a = c.angles;
        format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
        c.idx,
        c.entry,
        c.light,
        c.camera,
        c.probe,
        c.t,
        c.status,
        opt(a.map(|a| a.theta_i_deg)),
        opt(a.map(|a| a.phi_i_deg)),
        opt(a.map(|a| a.theta_o_deg)),
        opt(a.map(|a| a.phi_o_deg)),
        opt(c.mean_rgb.map(|v| v[0])),
        opt(c.mean_rgb.map(|v| v[1])),
        opt(c.mean_rgb.map(|v| v[2])),
        opt(c.xyz.map(|v| v[0])),
        opt(c.xyz.map(|v| v[1])),
        opt(c.xyz.map(|v| v[2])),
        opt(c.lab.map(|v| v.l)),
        opt(c.lab.map(|v| v.a)),
        opt(c.lab.map(|v| v.b)),
        opt(c.pixels),
        opt(c.nonfinite),
        opt(c.clipped),
        opt(c.pose_error_deg),
        c.by_command,
        opt(c.substitute),
        opt(c.gain_corrected.as_ref().map(|g| g.xyz[0])),
        opt(c.gain_corrected.as_ref().map(|g| g.xyz[1])),
        opt(c.gain_corrected.as_ref().map(|g| g.xyz[2])),
        opt(c.gain_corrected.as_ref().map(|g| g.gain)),
        opt(c.gain_corrected.as_ref().map(|g| g.sigma_rel)),
        csv_field(c.gain_corrected.as_ref().map(|g| g.source.as_str()).unwrap_or("")),
        csv_field(c.error.as_deref().unwrap_or(""))
        )
    }
}

impl CsvRow for PairRecord {
    const HEADER: &'static str = "a,b,entry_a,entry_b,status,t_s,mismatch_deg,abs_dX,abs_dY,abs_dZ,dE76,dC,dH,dE00,sigma_dE00,by_command";
    fn row(&self) -> String {
        let p = self;
        let d = p.diff;
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            p.a,
            p.b,
            p.entries[0],
            p.entries[1],
            p.status,
            p.t,
            p.mismatch_deg,
            opt(d.map(|d| d.abs_dxyz[0])),
            opt(d.map(|d| d.abs_dxyz[1])),
            opt(d.map(|d| d.abs_dxyz[2])),
            opt(d.map(|d| d.de76)),
            opt(d.map(|d| d.dc)),
            opt(d.map(|d| d.dh)),
            opt(d.map(|d| d.de2000)),
            opt(p.interpolated.as_ref().and_then(|i| i.sigma_de2000)),
            p.by_command
        )
    }
}

impl CsvRow for Alarm {
    const HEADER: &'static str = "idx,t_s,severity,kind,code,message,action,affects";
    fn row(&self) -> String {
        let a = self;
        let sev = serde_json::to_value(a.severity)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let kind = serde_json::to_value(a.kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        format!(
            "{},{},{},{},{},{},{},{}",
            opt(a.idx),
            opt(a.t),
            sev,
            kind,
            csv_field(a.code.as_str()),
            csv_field(&a.message),
            csv_field(a.action.as_deref().unwrap_or("")),
            csv_field(
                &a.affects
                    .as_ref()
                    .map(Affects::describe)
                    .unwrap_or_default()
            )
        )
    }
}

impl CsvRow for SweepRecord {
    const HEADER: &'static str = "light,idx,t_s,captures,level_pct,level_expected_pct,level_se_pct,level_z,level_cusum,joint1_offset_deg,joint1_se_deg,joint1_z,joint1_cusum,joint2_offset_deg,joint2_se_deg,joint2_z,joint2_cusum,residual_sd,wagon_offset_deg,wagon_se_deg,wagon_backlash_deg,wagon_backlash_se_deg";
    fn row(&self) -> String {
        let r = self;
        let j = |k: usize| r.joints.iter().find(|f| f.joint == k);
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.light,
            r.idx,
            r.t,
            r.captures,
            r.level_pct,
            r.level_expected_pct,
            r.level_se_pct,
            opt(r.level_z),
            r.level_cusum,
            opt(j(1).map(|f| f.offset_deg)),
            opt(j(1).map(|f| f.se_deg)),
            opt(j(1).and_then(|f| f.z)),
            opt(j(1).map(|f| f.cusum)),
            opt(j(2).map(|f| f.offset_deg)),
            opt(j(2).map(|f| f.se_deg)),
            opt(j(2).and_then(|f| f.z)),
            opt(j(2).map(|f| f.cusum)),
            r.residual_sd,
            opt(r.wagon.map(|w| w.offset_deg)),
            opt(r.wagon.map(|w| w.offset_se_deg)),
            opt(r.wagon.map(|w| w.backlash_deg)),
            opt(r.wagon.map(|w| w.backlash_se_deg))
        )
    }
}

/// The session's retake list (with its never-captured plan entries once it is finished).
fn session_retakes(inp: &ReportInputs) -> Vec<crate::checks::retakes::Retake> {
    match crate::setup::plan(&inp.config) {
        Ok(plan) => crate::checks::retakes::session_retakes(
            &inp.captures,
            &inp.alarms,
            &inp.config.checks,
            &plan,
            usize::try_from(inp.summary.captures_planned).unwrap_or(usize::MAX),
            inp.summary.finished,
        ),
        Err(_) => crate::checks::retakes::retakes(&inp.captures, &inp.alarms, &inp.config.checks),
    }
}

/// retakes.csv: one row per capture to take again (a never-captured plan entry has no idx).
fn retakes_csv(inp: &ReportInputs) -> String {
    let mut out = String::from("idx,entry,light,camera,why\n");
    for r in session_retakes(inp) {
        let _ = writeln!(
            out,
            "{},{},{},{},{}",
            opt(r.idx),
            r.entry,
            r.light,
            r.camera,
            csv_field(&r.why)
        );
    }
    out
}

pub(crate) fn render_csvs(inp: &ReportInputs) -> Result<Vec<(&'static str, String)>> {
    let plan = crate::setup::plan(&inp.config).context("the session's plan")?;
    let s = &inp.summary;
    let mut t2 = String::from("set,pairs,abs_dX,abs_dY,abs_dZ,dE76,dC,dH,dE00\n");
    for (name, t) in [
        ("exact", &s.table2),
        ("exact_by_command", &s.by_command),
        ("interpolated", &s.interpolated),
        ("isotropy", &s.isotropy),
    ] {
        let _ = writeln!(
            t2,
            "{name},{},{},{},{},{},{},{},{}",
            t.pairs, t.abs_dx, t.abs_dy, t.abs_dz, t.de76, t.dc, t.dh, t.de2000
        );
    }
    let by_entry = residual_by_entry(&inp.pairs);
    let dirs = plan.directions();
    let mut lights = String::from("light,theta_deg,phi_deg,pairs,mean_dE00,max_dE00\n");
    for (l, d) in dirs.iter().enumerate() {
        let v: Vec<f64> = (0..dirs.len())
            .filter_map(|c| plan.index_of(l, c))
            .filter_map(|e| by_entry.get(&e).copied())
            .collect();
        let mean = if v.is_empty() {
            String::new()
        } else {
            (v.iter().sum::<f64>() / v.len() as f64).to_string()
        };
        let max = if v.is_empty() {
            String::new()
        } else {
            v.iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max)
                .to_string()
        };
        let _ = writeln!(
            lights,
            "{l},{},{},{},{mean},{max}",
            d.theta_deg,
            d.phi_deg,
            v.len()
        );
    }
    let mut out = vec![
        ("captures.csv", csv_table(&inp.captures)),
        ("pairs.csv", csv_table(&inp.pairs)),
        ("alarms.csv", csv_table(&inp.alarms)),
        ("table2.csv", t2),
        ("light_residuals.csv", lights),
        ("retakes.csv", retakes_csv(inp)),
    ];
    if !inp.sweeps.is_empty() {
        out.push(("sweeps.csv", csv_table(&inp.sweeps)));
    }
    if let Some(cv) = &inp.crossval {
        let mut t3 = String::from("table,metric,max,avg,median,condition,condition_scaled\n");
        let x = &cv.result;
        let mut tables = vec![("as measured", &x.table3)];
        if let Some((_, t)) = &x.gain_corrected {
            tables.push(("gain-corrected", t));
        }
        for (name, t) in tables {
            let _ = writeln!(
                t3,
                "{name},dE76,{},{},{},{},{}",
                t.de76.max,
                t.de76.avg,
                t.de76.median,
                t.transform.condition,
                t.transform.condition_scaled
            );
            let _ = writeln!(
                t3,
                "{name},dE00,{},{},{},{},{}",
                t.de2000.max,
                t.de2000.avg,
                t.de2000.median,
                t.transform.condition,
                t.transform.condition_scaled
            );
        }
        out.push(("table3.csv", t3));
    }
    Ok(out)
}

/// Write the report of `session` into `out` (default SESSION/report); returns the files written.
pub(crate) fn report(session: &Path, out: Option<&Path>) -> Result<Vec<PathBuf>> {
    let inp = load(session)?;
    let out_dir = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| session.join("report"));
    std::fs::create_dir_all(&out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let mut written = Vec::new();
    let html = render_html(&inp)?;
    let path = out_dir.join("report.html");
    crate::session::folder::write_atomic(&path, html.as_bytes())?;
    written.push(path);
    for (name, text) in render_csvs(&inp)? {
        let path = out_dir.join(name);
        crate::session::folder::write_atomic(&path, text.as_bytes())?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::thin;

    #[test]
    fn thinning_keeps_at_most_about_max_with_the_ends() {
        let v: Vec<u32> = (0..1001).collect();
        let t = thin(v, 400);
        assert!(t.len() <= 401, "{}", t.len());
        assert_eq!(t.first(), Some(&0));
        assert_eq!(t.last(), Some(&1000));
        let t = thin((0..7).collect::<Vec<u32>>(), 400);
        assert_eq!(t, (0..7).collect::<Vec<u32>>());
        assert!(thin(Vec::<u32>::new(), 400).is_empty());
        assert_eq!(thin(vec![5u32], 400), vec![5]);
        let t = thin((0..800).collect::<Vec<u32>>(), 400);
        assert_eq!(t.len(), 401);
        assert_eq!(t.last(), Some(&799));
    }
}
