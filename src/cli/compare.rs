//! `goniowatch compare SESSION REFERENCE`: the shell around `measure::crossval::cross_validate`.
//! Reads the session's recorded captures and summary and the reference file, and writes the
//! result to `SESSION/crossval.json` (for the report) besides returning it.

use crate::checks::CaptureRecord;
use crate::engine::Summary;
use crate::measure::colour::White;
use crate::measure::crossval::{cross_validate, CrossValidation, GainCorrection, SessionValue};
use crate::measure::geometry::Spherical;
use crate::measure::resample::{LayeredResampler, ResampleSpec};
use crate::reference;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::path::Path;

/// What `compare` reports: the inputs' names and the cross-validation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct CompareReport {
    pub session: String,
    pub reference: String,
    pub reference_name: Option<String>,
    pub reference_samples: usize,
    pub sample_isotropic: bool,
    #[serde(flatten)]
    pub result: CrossValidation,
}

/// How to correct for gain drift.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum GainChoice {
    /// The session's own drift estimate, when it has one.
    Session,
    /// A rate given by the operator (%/h).
    Rate(f64),
    None,
}

/// The session's captures as comparison inputs: first good capture of each plan entry, no probes,
/// nothing at or below the dark level (`[checks] dark_y`: a lamp off is not a colour).
pub(crate) fn session_values(dir: &Path, dark_y: f64) -> Result<Vec<SessionValue>> {
    let path = dir.join("captures.jsonl");
    if !path.exists() {
        bail!(
            "{} has no captures.jsonl (is this a goniowatch session folder?)",
            dir.display()
        );
    }
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    for rec in crate::session::folder::read_session_captures(dir)? {
        if rec.probe || rec.status != crate::checks::CaptureStatus::Ok || seen.contains(&rec.entry)
        {
            continue;
        }
        let (Some(a), Some(xyz)) = (rec.angles, rec.xyz) else {
            continue;
        };
        // a dark capture does not count as the entry's capture: a good retake still can
        if !(xyz[1] > dark_y) {
            continue;
        }
        seen.insert(rec.entry);
        out.push(SessionValue {
            idx: rec.idx,
            entry: rec.entry,
            t_s: rec.t,
            omega_i: Spherical::from_deg(a.theta_i_deg, a.phi_i_deg).to_vector(),
            omega_o: Spherical::from_deg(a.theta_o_deg, a.phi_o_deg).to_vector(),
            xyz,
        });
    }
    Ok(out)
}

/// The probes' gain curve: (t in hours, Y of the probe / Y of the first capture of its entry),
/// starting at (t of that first capture, 1).
pub(crate) fn probe_gain_curve(dir: &Path, dark_y: f64) -> Result<Vec<(f64, f64)>> {
    let records: Vec<CaptureRecord> = crate::session::folder::read_session_captures(dir)?;
    let mut curve = crate::checks::ProbeGainCurve::new(dark_y);
    let mut points = Vec::new();
    for rec in &records {
        if let Some(p) = curve.add(rec) {
            // the curve starts at 1 at the probed pose's original capture
            if points.is_empty() {
                if let Some(t0) = curve.origin_s(rec.entry) {
                    points.push((t0 / 3600.0, 1.0));
                }
            }
            points.push(p);
        }
    }
    Ok(points)
}

pub(crate) fn compare(
    session: &Path,
    reference_file: &Path,
    gain: GainChoice,
    worst: usize,
    max_reference_spread: f64,
) -> Result<CompareReport> {
    let (cfg, _) = crate::session::folder::load_config(session)?;
    let values = session_values(session, cfg.checks.dark_y)?;
    if values.is_empty() {
        bail!("{} has no usable captures", session.display());
    }
    let text = std::fs::read_to_string(reference_file)
        .with_context(|| format!("cannot read reference {}", reference_file.display()))?;
    let reference = reference::parse(&text)
        .with_context(|| format!("invalid reference {}", reference_file.display()))?;
    let samples: Vec<_> = reference
        .samples
        .iter()
        .map(|s| crate::measure::resample::Sample {
            omega_i: s.omega_i,
            omega_o: s.omega_o,
            value: s.xyz,
        })
        .collect();
    let resampler = LayeredResampler::new(&samples, &ResampleSpec::default())
        .context("the reference cannot be interpolated")?;
    // the reference is on the Y = 100 scale of a perfect reflector: judge colour against D65 there
    let white = White::d65_scaled(100.0).context("white")?;
    let gain = match gain {
        GainChoice::None => None,
        GainChoice::Rate(r) => Some(GainCorrection {
            rate_pct_per_h: r,
            se_pct_per_h: 0.0,
            source: "command line".into(),
            points: Vec::new(),
        }),
        GainChoice::Session => {
            let summary: Option<Summary> = crate::session::folder::load_summary(session).ok();
            let points = probe_gain_curve(session, cfg.checks.dark_y)?;
            match (summary, points.len()) {
                (Some(s), n) if n >= 2 => Some(GainCorrection {
                    rate_pct_per_h: s.probe_drift.map(|d| d.rate_pct_per_h).unwrap_or(0.0),
                    se_pct_per_h: s.probe_drift.map(|d| d.se_pct_per_h).unwrap_or(0.0),
                    source: format!(
                        "the session's measured probe gain curve ({} probes, steps included)",
                        n - 1
                    ),
                    points,
                }),
                (Some(s), _) => s.isotropy_drift.map(|d| GainCorrection {
                    rate_pct_per_h: d.rate_pct_per_h,
                    se_pct_per_h: d.se_pct_per_h,
                    source: format!("the session's isotropy classes ({} comparisons)", d.pairs),
                    points: Vec::new(),
                }),
                (None, _) => None,
            }
        }
    };
    let result = cross_validate(
        &values,
        &resampler,
        white,
        cfg.reciprocity.min_cos,
        max_reference_spread,
        gain,
        worst,
    )
    .context("cross-validation failed")?;
    let report = CompareReport {
        session: session.display().to_string(),
        reference: reference_file.display().to_string(),
        reference_name: reference.name.clone(),
        reference_samples: reference.samples.len(),
        sample_isotropic: cfg.sample.isotropic,
        result,
    };
    let json = serde_json::to_vec_pretty(&report)?;
    crate::session::folder::write_atomic(&session.join("crossval.json"), &json)
        .with_context(|| format!("cannot write {}", session.join("crossval.json").display()))?;
    Ok(report)
}

/// The human-readable form.
pub(crate) fn render(r: &CompareReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let x = &r.result;
    let _ = writeln!(
        s,
        "cross-validation of {} against {}{}",
        r.session,
        r.reference,
        r.reference_name
            .as_deref()
            .map(|n| format!(" ({n})"))
            .unwrap_or_default()
    );
    let layers: Vec<String> = x
        .reference_layers_deg
        .iter()
        .map(|t| format!("{t:.0}"))
        .collect();
    let _ = writeln!(
        s,
        "reference: {} samples, θi layers {}°; resampled at the session's poses (median uncertainty {:.2} %)",
        r.reference_samples,
        layers.join(" "),
        100.0 * x.reference_rel_spread_median
    );
    let _ = writeln!(
        s,
        "session: {} captures compared, {} not reached by the reference, {} where the reference is too uncertain (> {:.0} %), {} grazing",
        x.captures_compared,
        x.captures_not_covered,
        x.captures_reference_uncertain,
        100.0 * x.max_reference_spread,
        x.captures_grazing
    );
    if !r.sample_isotropic {
        let _ = writeln!(s, "note: the session's sample is declared anisotropic; the reference is resampled as isotropic");
    }
    let mut table = |title: &str, t: &crate::measure::crossval::Table3| {
        let tr = &t.transform;
        let _ = writeln!(
            s,
            "\n{title}\nT (session XYZ/cos θi → reference XYZ), condition number {:.1} (of the fit with columns scaled to unit norm; {:.1} unscaled){}:",
            tr.condition_scaled,
            tr.condition,
            if tr.ill_conditioned {
                " — ILL-CONDITIONED: the data are nearly grey, T is poorly determined"
            } else {
                ""
            }
        );
        for row in &tr.t {
            let _ = writeln!(s, "  [{:>10.5} {:>10.5} {:>10.5}]", row[0], row[1], row[2]);
        }
        let _ = writeln!(s, "Table 3          max      avg      median");
        let _ = writeln!(
            s,
            "  ΔE*ab       {:>8.3} {:>8.3} {:>8.3}",
            t.de76.max, t.de76.avg, t.de76.median
        );
        let _ = writeln!(
            s,
            "  CIEDE2000   {:>8.3} {:>8.3} {:>8.3}",
            t.de2000.max, t.de2000.avg, t.de2000.median
        );
        if !t.worst.is_empty() {
            let _ = writeln!(s, "largest deviations:\n  capture  entry   θi     φi     θo     φo    t [h]   ΔE00   ΔE*ab  ref ±");
            for d in &t.worst {
                let a = d.angles_deg;
                let _ = writeln!(
                    s,
                    "  {:>7} {:>6} {:>5.1} {:>6.1} {:>5.1} {:>6.1} {:>7.2} {:>6.2} {:>7.2} {:>5.1}%",
                    d.idx, d.entry, a[0], a[1], a[2], a[3], d.t_h, d.de2000, d.de76, 100.0 * d.reference_rel_spread
                );
            }
        }
    };
    table("as measured", &x.table3);
    match &x.gain_corrected {
        Some((g, t)) => table(
            &format!(
                "gain-corrected ({:+.3} ± {:.3} %/h from {})",
                g.rate_pct_per_h, g.se_pct_per_h, g.source
            ),
            t,
        ),
        None => {
            let _ = writeln!(
                s,
                "\nno gain correction: the session has no drift estimate (enable [probes], declare an isotropic sample, or pass --drift-rate)"
            );
        }
    }
    s
}
