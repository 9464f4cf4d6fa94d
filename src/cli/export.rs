//! `goniowatch export SESSION --format merl|table|corrected-images`: the shell around
//! `export`. Reads the session's records, summary and config, builds the drift model from the
//! session's end-of-run estimates, and writes the outputs. Never writes under the capture root.

use crate::checks::alarm::{AlarmCode, AlarmKind};
use crate::checks::catalogue;
use crate::checks::{CaptureRecord, CaptureStatus};
use crate::config::{Config, WhiteSpec};
use crate::engine::Summary;
use crate::export::correction::{ColourRates, DriftCorrection, GainSource, GainStep, Photometry};
use crate::export::merl::{self, CellCounts, MerlGrid};
use crate::export::table::{self, ExportRow};
use crate::export::ExportError;
use crate::measure::colour::{White, Xyz};
use crate::measure::geometry::Spherical;
use crate::measure::resample::{LayeredResampler, ResampleSpec, Sample, LAYER_TOL_DEG};
use crate::session::folder::{inside_capture_folder, write_atomic};
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What to export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// The MERL isotropic BRDF binary (90 × 90 × 180 cells) and a JSON sidecar.
    Merl,
    /// One row per capture, CSV and JSON lines.
    Table,
    /// Drift-corrected OpenEXR copies of the captures.
    CorrectedImages,
}

/// What the MERL export interpolates across the θi layers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum LayerInterpolation {
    /// The BRDF itself (the default: exact for a matte sample's flat BRDF).
    Brdf,
    /// The BRDF × cos θi × cos θo (a microfacet lobe's D·F·G/4, slow in θi): several times
    /// closer on glossy samples at θi ≥ 45°, somewhat further on matte ones.
    CosineWeighted,
}

/// The session as the export reads it.
pub(crate) struct SessionData {
    pub dir: PathBuf,
    pub config: Config,
    pub summary: Summary,
    pub drift: DriftCorrection,
    pub white: WhiteUsed,
    pub rows: Vec<ExportRow>,
}

/// The white the BRDF is relative to, as the sidecar states it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct WhiteUsed {
    /// `d65`, `xyz` or `reference-capture N` (its XYZ ÷ cos θi of its pose).
    pub kind: String,
    pub xyz: Xyz,
    pub rgb: [f64; 3],
    pub reflectance: f64,
    pub rgb_scale: f64,
    pub primaries: String,
}

/// The session's drift model at the end of the run (see `export::correction`).
fn drift_model(dir: &Path, cfg: &Config, summary: &Summary) -> Result<DriftCorrection> {
    let mut d = DriftCorrection::none();
    let curve = crate::cli::compare::probe_gain_curve(dir, cfg.checks.dark_y)?;
    if curve.len() >= 2 {
        d.gain_source = GainSource::ProbeCurve;
        d.curve = curve;
        if let Some(p) = summary.probe_drift {
            d.rate_pct_per_h = p.rate_pct_per_h;
            d.se_pct_per_h = p.se_pct_per_h;
        }
    } else if let Some(iso) = summary.isotropy_drift {
        d.gain_source = GainSource::IsotropyClasses;
        d.rate_pct_per_h = iso.rate_pct_per_h;
        d.se_pct_per_h = iso.se_pct_per_h;
        d.steps = summary
            .isotropy_steps
            .iter()
            .map(|s| GainStep {
                t_h: s.t_h,
                ln_size: s.ln_size,
            })
            .collect();
    }
    d.colour = summary.colour_drift.as_ref().map(|c| ColourRates {
        x_rate_pct_per_h: c.x_rate_pct_per_h,
        z_rate_pct_per_h: c.z_rate_pct_per_h,
        k_per_h: c.k_per_h,
        se_k_per_h: c.se_k_per_h,
    });
    Ok(d)
}

/// The configured white on the captures' scale.
fn white_of(cfg: &Config, records: &[CaptureRecord]) -> Result<(White, String)> {
    match cfg.colour.white {
        WhiteSpec::ReferenceCapture { index } => {
            let rec = records
                .iter()
                .find(|r| r.idx == index as u64 && r.status == CaptureStatus::Ok)
                .with_context(|| format!("the white is capture {index} (colour.white), which the session has no usable record of"))?;
            let (Some(xyz), Some(a)) = (rec.xyz, rec.angles) else {
                bail!("the white's capture {index} has no colour or pose");
            };
            let c = a.theta_i_deg.to_radians().cos();
            if !(c > 1e-3) {
                bail!("the white's capture {index} is lit at grazing incidence");
            }
            let w = White::new([xyz[0] / c, xyz[1] / c, xyz[2] / c])
                .context("the white's capture is not a usable white")?;
            Ok((w, format!("reference-capture {index}")))
        }
        ref spec => Ok((
            spec.resolve(None).context("colour.white")?,
            match spec {
                WhiteSpec::D65 { .. } => "d65".to_string(),
                _ => "xyz".to_string(),
            },
        )),
    }
}

/// Read a session for export.
pub(crate) fn load(dir: &Path, correct_drift: bool) -> Result<SessionData> {
    let (config, _) = crate::session::folder::load_config(dir)?;
    if !dir.join("captures.jsonl").exists() {
        bail!(
            "{} has no captures.jsonl (is this a goniowatch session folder?)",
            dir.display()
        );
    }
    let summary = crate::session::folder::load_summary(dir)?;
    let records = crate::session::folder::read_session_captures(dir)?;
    let drift = if correct_drift {
        drift_model(dir, &config, &summary)?
    } else {
        DriftCorrection::none()
    };
    let (white, kind) = white_of(&config, &records)?;
    let photometry = Photometry::new(
        config.colour.primaries,
        white,
        config.colour.white_reflectance(),
        config.colour.scale(),
    )?;
    let (xyz, rgb) = photometry.white();
    let white_used = WhiteUsed {
        kind,
        xyz,
        rgb,
        reflectance: config.colour.white_reflectance(),
        rgb_scale: config.colour.scale(),
        primaries: serde_json::to_value(config.colour.primaries)?
            .as_str()
            .unwrap_or_default()
            .to_string(),
    };
    let rows = table::rows(&records, &drift, &photometry, config.checks.dark_y);
    Ok(SessionData {
        dir: dir.to_path_buf(),
        config,
        summary,
        drift,
        white: white_used,
        rows,
    })
}

/// The checks' verdict a file carries with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Verdict {
    pub finished: bool,
    pub captures_planned: u64,
    pub captures_checked: u64,
    /// Table 2 of the exact reciprocal pairs and of the isotropy classes.
    pub table2: crate::checks::Table2,
    pub isotropy: crate::checks::Table2,
    /// Alarm counts by kind (the summary's) and by code (alarms.jsonl).
    pub alarms: BTreeMap<String, u64>,
    pub alarm_codes: BTreeMap<String, u64>,
    /// Why the sample's isotropy is in doubt (an isotropy alarm), if it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub isotropy_warning: Option<String>,
}

/// Alarm counts by code from the session's alarms.jsonl (none when it has no such file).
fn alarm_codes(dir: &Path) -> BTreeMap<String, u64> {
    let mut out = BTreeMap::new();
    let path = dir.join("alarms.jsonl");
    if let Ok(records) = crate::session::folder::read_records::<serde_json::Value>(&path) {
        for a in records {
            if let Some(code) = a.get("code").and_then(|c| c.as_str()) {
                *out.entry(code.to_string()).or_insert(0) += 1;
            }
        }
    }
    out
}

fn verdict(dir: &Path, s: &Summary, rows: &[ExportRow]) -> Verdict {
    let codes = alarm_codes(dir);
    let isotropy_codes: Vec<String> = codes
        .keys()
        .filter(|k| {
            serde_json::from_value::<AlarmCode>(serde_json::Value::String((*k).clone()))
                .map(|c| catalogue::entry(c).kind == AlarmKind::Isotropy)
                .unwrap_or(false)
        })
        .cloned()
        .collect();
    let isotropy_alarms = s
        .alarms
        .get(AlarmKind::Isotropy.as_str())
        .copied()
        .unwrap_or(0);
    Verdict {
        finished: s.finished,
        captures_planned: s.captures_planned,
        captures_checked: rows
            .iter()
            .filter(|r| r.status == CaptureStatus::Ok)
            .count() as u64,
        table2: s.table2.clone(),
        isotropy: s.isotropy.clone(),
        alarms: s.alarms.clone(),
        alarm_codes: codes,
        isotropy_warning: (isotropy_alarms > 0 || !isotropy_codes.is_empty()).then(|| {
            format!(
                "the session raised {} isotropy alarm(s){}: the sample may not be isotropic (or sits off the rotation centre), and an isotropic export folds its azimuths together",
                isotropy_alarms.max(isotropy_codes.len() as u64),
                if isotropy_codes.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", isotropy_codes.join(", "))
                }
            )
        }),
    }
}

/// The interpolant and its settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Interpolant {
    pub name: String,
    pub nc_2d: usize,
    pub nw_2d: usize,
    pub log_values: bool,
    /// What is interpolated across the θi layers.
    pub across_layers: LayerInterpolation,
    /// θi of the layers interpolated across (degrees).
    pub layers_deg: Vec<f64>,
}

/// The MERL file's sidecar (`FILE.json`): what the numbers are and how far to trust them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MerlSidecar {
    pub format: String,
    /// The MERL file's name (the sidecar sits beside it).
    pub file: String,
    pub sha256: String,
    pub goniowatch: String,
    pub session: Option<String>,
    pub sample: String,
    pub units: String,
    pub channels: String,
    pub channel_scale: [f64; 3],
    pub no_value: f64,
    pub white: WhiteUsed,
    pub correction: DriftCorrection,
    /// Captures the grid is interpolated from (one per plan entry).
    pub captures_used: usize,
    /// The θ limit of the cells (the largest measured θ plus the layer tolerance).
    pub theta_max_deg: f64,
    pub cells: CellCounts,
    /// Filled cells over cells with both directions above the horizon.
    pub filled_fraction_above_horizon: f64,
    /// Per θh cell row (outer) and θd cell (inner), the fraction of its 180 φd cells filled.
    pub coverage: Vec<Vec<f64>>,
    pub interpolant: Interpolant,
    /// The filled cells' σ relative to their value (worst channel): 50 %, 95 %, max.
    pub relative_sigma: Option<[f64; 3]>,
    /// One capture's own scatter about its isotropy class (what the interpolant's σ leaves
    /// out): a single capture differs from a cell by about √(σ² + (scatter × value)²).
    pub capture_scatter: Option<crate::export::table::CaptureScatter>,
    /// The σ file (the same layout), when one was written.
    pub sigma_file: Option<String>,
    pub verdict: Verdict,
}

/// Where the report finds the latest MERL export's sidecar.
pub(crate) const MERL_SIDECAR_IN_SESSION: &str = "merl-export.json";

/// What an export did, for the printed summary.
pub(crate) struct Exported {
    pub lines: Vec<String>,
    /// Nothing usable came out (exit 6).
    pub meaningless: bool,
    /// Some items failed (exit 3).
    pub failed: bool,
}

fn default_out(dir: &Path, name: &str) -> PathBuf {
    dir.join("export").join(name)
}

fn ensure_parent(path: &Path) -> Result<()> {
    if let Some(p) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(p).with_context(|| format!("cannot create {}", p.display()))?;
    }
    Ok(())
}

/// The session's capture root as recorded (absent in a replay's output folder).
fn recorded_capture_root(dir: &Path) -> Option<PathBuf> {
    let text = std::fs::read_to_string(dir.join("session.json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v.get("capture_root")?.as_str().map(PathBuf::from)
}

/// Refuse an output under the capture root.
fn refuse_capture_root(out: &Path, dir: &Path, given: Option<&Path>) -> Result<()> {
    let root = given
        .map(Path::to_path_buf)
        .or_else(|| recorded_capture_root(dir));
    if let Some(root) = root {
        if inside_capture_folder(out, &root) {
            return Err(crate::cli::exit::UsageError(format!(
                "--out {} is inside the capture folder {}; goniowatch never writes there. Give a folder elsewhere",
                out.display(),
                root.display()
            ))
            .into());
        }
    }
    Ok(())
}

pub(crate) fn export_merl(
    data: &SessionData,
    out: Option<&Path>,
    sigma_out: Option<&Path>,
    (fit_nodes, weight_nodes): (usize, usize),
    across: LayerInterpolation,
    threads: usize,
) -> Result<Exported> {
    if !data.config.sample.isotropic {
        return Err(crate::cli::exit::UsageError(
            "the sample is anisotropic ([sample] isotropic = false): the MERL layout holds isotropic BRDFs only (no φh). Export the measured values with --format table instead".into(),
        )
        .into());
    }
    let out = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| default_out(&data.dir, "brdf.binary"));
    refuse_capture_root(&out, &data.dir, None)?;
    if let Some(s) = sigma_out {
        refuse_capture_root(s, &data.dir, None)?;
    }
    let verdict = verdict(&data.dir, &data.summary, &data.rows);
    let mut lines = Vec::new();
    if let Some(w) = &verdict.isotropy_warning {
        eprintln!("goniowatch: warning: {w}");
        lines.push(format!("warning: {w}"));
    }
    let samples: Vec<Sample> = data
        .rows
        .iter()
        .filter(|r| r.in_grid)
        .filter_map(|r| {
            let (ti, pi, to, po) = (r.theta_i_deg?, r.phi_i_deg?, r.theta_o_deg?, r.phi_o_deg?);
            Some(Sample {
                omega_i: Spherical::from_deg(ti, pi).to_vector(),
                omega_o: Spherical::from_deg(to, po).to_vector(),
                value: [r.brdf_r?, r.brdf_g?, r.brdf_b?],
            })
        })
        .collect();
    if samples.is_empty() {
        return Err(ExportError::NothingToExport(
            "the session has no usable capture (decoded, above the dark level, with a pose)".into(),
        )
        .into());
    }
    let theta_max = data
        .rows
        .iter()
        .filter(|r| r.in_grid)
        .flat_map(|r| [r.theta_i_deg, r.theta_o_deg])
        .flatten()
        .fold(0.0, f64::max)
        + LAYER_TOL_DEG;
    let spec = ResampleSpec {
        nc_2d: fit_nodes,
        nw_2d: weight_nodes,
        cosine_across_layers: across == LayerInterpolation::CosineWeighted,
        ..ResampleSpec::default()
    };
    let resampler = LayeredResampler::new(&samples, &spec)
        .context("the session's captures cannot be interpolated")?;
    let grid: MerlGrid = merl::fill(&resampler, theta_max, threads);
    let cells = grid.counts();
    let mut bytes = Vec::with_capacity(12 + 24 * merl::CELLS);
    grid.write(&mut bytes, false)?;
    ensure_parent(&out)?;
    write_atomic(&out, &bytes).with_context(|| format!("cannot write {}", out.display()))?;
    let sha256 = format!("{:x}", Sha256::digest(&bytes));
    if let Some(s) = sigma_out {
        let mut sb = Vec::with_capacity(bytes.len());
        grid.write(&mut sb, true)?;
        ensure_parent(s)?;
        write_atomic(s, &sb).with_context(|| format!("cannot write {}", s.display()))?;
    }
    let above = merl::CELLS as u64 - cells.below_horizon;
    let sidecar = MerlSidecar {
        format: "merl".into(),
        file: out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        sha256,
        goniowatch: env!("CARGO_PKG_VERSION").into(),
        session: data.summary.session.clone(),
        sample: data.config.sample.name.clone(),
        units: "sr^-1 (stored value × channel_scale)".into(),
        channels: format!(
            "linear RGB of the {} primaries, each relative to the white's (a white of the stated reflectance reads reflectance/π)",
            data.white.primaries
        ),
        channel_scale: merl::CHANNEL_SCALE,
        no_value: merl::NO_VALUE,
        white: data.white.clone(),
        correction: data.drift.clone(),
        captures_used: samples.len(),
        theta_max_deg: theta_max,
        cells,
        filled_fraction_above_horizon: if above > 0 {
            cells.filled as f64 / above as f64
        } else {
            0.0
        },
        coverage: grid
            .coverage()
            .into_iter()
            .map(|row| row.into_iter().map(|f| (f * 1000.0).round() / 1000.0).collect())
            .collect(),
        interpolant: Interpolant {
            name: "layered: cubic (or quadratic) modified Shepard in each θi layer's mirror-aligned concentric square, Lagrange across θi".into(),
            nc_2d: spec.nc_2d,
            nw_2d: spec.nw_2d,
            log_values: spec.log_values,
            across_layers: across,
            layers_deg: resampler.layer_thetas(),
        },
        relative_sigma: grid.relative_sigma_quantiles(),
        capture_scatter: table::capture_scatter(&data.rows),
        sigma_file: sigma_out.and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned())),
        verdict,
    };
    let json = serde_json::to_vec_pretty(&sidecar)?;
    let side_path = PathBuf::from(format!("{}.json", out.display()));
    write_atomic(&side_path, &json)
        .with_context(|| format!("cannot write {}", side_path.display()))?;
    write_atomic(&data.dir.join(MERL_SIDECAR_IN_SESSION), &json).with_context(|| {
        format!(
            "cannot write {}",
            data.dir.join(MERL_SIDECAR_IN_SESSION).display()
        )
    })?;
    lines.push(format!(
        "MERL BRDF {}: {} of {} cells filled from {} captures ({:.1} % of the cells above the horizon); empty (−1): {} below the horizon, {} beyond θ = {:.2}°, {} too far from the captures, {} not finite",
        out.display(),
        cells.filled,
        merl::CELLS,
        samples.len(),
        100.0 * sidecar.filled_fraction_above_horizon,
        cells.below_horizon,
        cells.beyond_theta_range,
        theta_max,
        cells.outside_interpolant,
        cells.not_finite
    ));
    if let Some(q) = sidecar.relative_sigma {
        lines.push(format!(
            "interpolation σ relative to the value: median {:.2} %, 95 % of cells below {:.2} %",
            100.0 * q[0],
            100.0 * q[1]
        ));
    }
    if let Some(c) = sidecar.capture_scatter {
        lines.push(format!(
            "one capture's scatter about its isotropy class: {:.2} % ({} classes)",
            c.relative_pct, c.classes
        ));
    }
    lines.push(correction_line(&data.drift));
    lines.push(format!("sidecar {}", side_path.display()));
    Ok(Exported {
        lines,
        meaningless: cells.filled == 0,
        failed: false,
    })
}

pub(crate) fn correction_line(d: &DriftCorrection) -> String {
    let gain = match d.gain_source {
        GainSource::ProbeCurve => {
            format!("the drift probes' gain curve ({} points)", d.curve.len())
        }
        GainSource::IsotropyClasses => format!(
            "the isotropy classes' rate {:+.3} ± {:.3} %/h{}",
            d.rate_pct_per_h,
            d.se_pct_per_h,
            if d.steps.is_empty() {
                String::new()
            } else {
                format!(" with {} step(s)", d.steps.len())
            }
        ),
        GainSource::None => "none".into(),
    };
    let colour = match &d.colour {
        Some(c) => format!(
            "; lamp colour {:+.1} ± {:.1} K/h divided out of X and Z",
            c.k_per_h, c.se_k_per_h
        ),
        None => String::new(),
    };
    format!("drift divided out: gain from {gain}{colour}")
}

pub(crate) fn export_table(data: &SessionData, out: Option<&Path>) -> Result<Exported> {
    let csv_path = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| default_out(&data.dir, "captures-table.csv"));
    refuse_capture_root(&csv_path, &data.dir, None)?;
    let jsonl_path = csv_path.with_extension("jsonl");
    if jsonl_path == csv_path {
        return Err(crate::cli::exit::UsageError(format!(
            "--out {} must not end in .jsonl: the JSON lines go beside the CSV as .jsonl",
            csv_path.display()
        ))
        .into());
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut jl = Vec::new();
    for r in &data.rows {
        w.serialize(r)?;
        serde_json::to_writer(&mut jl, r)?;
        jl.push(b'\n');
    }
    let csv_bytes = w.into_inner().context("cannot assemble the CSV")?;
    ensure_parent(&csv_path)?;
    write_atomic(&csv_path, &csv_bytes)
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    write_atomic(&jsonl_path, &jl)
        .with_context(|| format!("cannot write {}", jsonl_path.display()))?;
    let with_brdf = data.rows.iter().filter(|r| r.brdf_y.is_some()).count();
    let in_grid = data.rows.iter().filter(|r| r.in_grid).count();
    Ok(Exported {
        lines: vec![
            format!(
                "table {} and {}: {} rows ({} with a BRDF, {} standing for their plan entry)",
                csv_path.display(),
                jsonl_path.display(),
                data.rows.len(),
                with_brdf,
                in_grid
            ),
            correction_line(&data.drift),
        ],
        meaningless: with_brdf == 0,
        failed: false,
    })
}

/// One corrected image: where from, where to, the factors, or why not.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct CorrectedImage {
    pub idx: u64,
    pub source: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub factors: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The output path of a capture's corrected copy: its relative name under `out`, as `.exr`.
/// None for a name that would leave `out` (absolute, or with `..`).
fn corrected_path(out: &Path, file: &str) -> Option<PathBuf> {
    let rel = Path::new(file);
    if rel.is_absolute()
        || rel
            .components()
            .any(|c| !matches!(c, std::path::Component::Normal(_)))
    {
        return None;
    }
    Some(out.join(rel).with_extension("exr"))
}

fn correct_one(
    root: &Path,
    out: &Path,
    row: &ExportRow,
    factors: [f64; 3],
    limits: &crate::decode::DecodeLimits,
) -> Result<PathBuf> {
    let dest = corrected_path(out, &row.file)
        .with_context(|| format!("the name {} leaves the output folder", row.file))?;
    let src = root.join(&row.file);
    let bytes = std::fs::read(&src).with_context(|| format!("cannot read {}", src.display()))?;
    let img = crate::decode::decode(&bytes, limits)
        .with_context(|| format!("cannot decode {}", src.display()))?;
    let inv = factors.map(|f| (1.0 / f) as f32);
    let (w, h) = (img.width, img.height);
    let pixel = |x: usize, y: usize| -> (f32, f32, f32) {
        let p = img.pixel(x, y).unwrap_or([f32::NAN; 3]);
        (p[0] * inv[0], p[1] * inv[1], p[2] * inv[2])
    };
    use exr::prelude::*;
    let image = Image::from_channels((w, h), SpecificChannels::rgb(|Vec2(x, y)| pixel(x, y)));
    let mut buf = std::io::Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut buf)
        .map_err(|e| anyhow::anyhow!("cannot encode {}: {e}", dest.display()))?;
    ensure_parent(&dest)?;
    write_atomic(&dest, buf.get_ref())
        .with_context(|| format!("cannot write {}", dest.display()))?;
    Ok(dest)
}

pub(crate) fn export_images(
    data: &SessionData,
    out: Option<&Path>,
    capture_root: Option<&Path>,
    threads: usize,
) -> Result<Exported> {
    let Some(out) = out else {
        return Err(crate::cli::exit::UsageError(
            "--format corrected-images needs --out DIR (a folder outside the capture root)".into(),
        )
        .into());
    };
    let root = capture_root
        .map(Path::to_path_buf)
        .or_else(|| recorded_capture_root(&data.dir))
        .with_context(|| {
            format!(
                "{} records no capture root (a replay's folder?): give --capture-root",
                data.dir.display()
            )
        })?;
    refuse_capture_root(out, &data.dir, Some(&root))?;
    if inside_capture_folder(out, &root) {
        bail!("--out is inside the capture folder");
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let limits = crate::decode::DecodeLimits {
        threads: 1,
        max_bytes: data.config.ingest.max_decode_mib.saturating_mul(1 << 20),
        ..Default::default()
    };
    // one copy per file: the first row of a file that has factors
    let mut seen = std::collections::HashSet::new();
    let jobs: Vec<&ExportRow> = data
        .rows
        .iter()
        .filter(|r| r.status == CaptureStatus::Ok && seen.insert(r.file.clone()))
        .collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<(usize, CorrectedImage)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.clamp(1, 64))
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(row) = jobs.get(k) else { break };
                        let factors =
                            match (row.image_factor_r, row.image_factor_g, row.image_factor_b) {
                                (Some(r), Some(g), Some(b)) => Some([r, g, b]),
                                _ => None,
                            };
                        let mut rec = CorrectedImage {
                            idx: row.idx,
                            source: row.file.clone(),
                            output: None,
                            factors,
                            error: None,
                        };
                        match factors {
                            None => {
                                rec.error = Some(
                                    "no correction factors (a channel of its mean is not positive)"
                                        .into(),
                                )
                            }
                            Some(f) => {
                                match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                                    correct_one(&root, out, row, f, &limits)
                                })) {
                                    Ok(Ok(p)) => rec.output = Some(p.display().to_string()),
                                    Ok(Err(e)) => rec.error = Some(format!("{e:#}")),
                                    Err(_) => rec.error = Some("the encoder panicked".into()),
                                }
                            }
                        }
                        mine.push((k, rec));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    results.sort_by_key(|r| r.0);
    let records: Vec<CorrectedImage> = results.into_iter().map(|r| r.1).collect();
    let written = records.iter().filter(|r| r.output.is_some()).count();
    let failed = records.len() - written;
    let lost = jobs.len() - records.len();
    let mut manifest = Vec::new();
    for r in &records {
        serde_json::to_writer(&mut manifest, r)?;
        manifest.push(b'\n');
    }
    let manifest_path = out.join("corrected-images.jsonl");
    write_atomic(&manifest_path, &manifest)
        .with_context(|| format!("cannot write {}", manifest_path.display()))?;
    let mut lines = vec![
        format!(
            "corrected images under {}: {written} written, {} failed (each listed with its error in {})",
            out.display(),
            failed + lost,
            manifest_path.display()
        ),
        correction_line(&data.drift),
    ];
    for r in records.iter().filter(|r| r.error.is_some()).take(5) {
        lines.push(format!(
            "  {}: {}",
            r.source,
            r.error.as_deref().unwrap_or_default()
        ));
    }
    Ok(Exported {
        lines,
        meaningless: written == 0,
        failed: failed + lost > 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_corrected_copy_keeps_its_relative_name_under_the_output_and_never_leaves_it() {
        let out = Path::new("/tmp/out");
        assert_eq!(
            corrected_path(out, "light00/tl015_pl060_tv030_pv000.hdr"),
            Some(PathBuf::from(
                "/tmp/out/light00/tl015_pl060_tv030_pv000.exr"
            ))
        );
        assert_eq!(
            corrected_path(out, "c0001.exr"),
            Some(PathBuf::from("/tmp/out/c0001.exr"))
        );
        assert_eq!(corrected_path(out, "../escape.exr"), None);
        assert_eq!(corrected_path(out, "/etc/passwd"), None);
        assert_eq!(
            corrected_path(out, "a/./b.exr"),
            Some(PathBuf::from("/tmp/out/a/b.exr"))
        );
    }
}
