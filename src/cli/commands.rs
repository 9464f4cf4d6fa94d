//! The CLI's commands as library functions that return serialisable records, so the binary
//! only parses arguments and prints, and tests can call the same code.

use crate::config::Config;
use crate::decode::{decode, CaptureFormat};
use crate::measure::averaging::{AverageOptions, CaptureStats};
use crate::measure::colour::{xyz_to_lab, Lab, Xyz};
use crate::setup::ProbeScatter;
use serde::Serialize;
use std::path::Path;

/// One line of `goniowatch average --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct AverageRecord {
    pub file: String,
    #[serde(flatten)]
    pub outcome: AverageOutcome,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub(crate) enum AverageOutcome {
    Ok(Box<AverageOk>),
    Err { error: String },
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct AverageOk {
    pub format: CaptureFormat,
    pub width: usize,
    pub height: usize,
    pub mean_rgb: [f64; 3],
    pub xyz: Xyz,
    /// L*a*b* under the configured white; absent when the white needs a reference capture.
    pub lab: Option<Lab>,
    pub pixels: u64,
    pub nonfinite: u64,
    pub negative: u64,
    pub clipped: u64,
    pub dark: u64,
    pub max_value: f64,
}

/// Read, decode and average one file. Every failure becomes an `Err` outcome with a message.
pub(crate) fn average_file(path: &Path, cfg: &Config, opts: &AverageOptions) -> AverageRecord {
    let file = path.display().to_string();
    let outcome = match average_file_inner(path, cfg, opts) {
        Ok(ok) => AverageOutcome::Ok(Box::new(ok)),
        Err(e) => AverageOutcome::Err {
            error: format!("{e:#}"),
        },
    };
    AverageRecord { file, outcome }
}

fn average_file_inner(
    path: &Path,
    cfg: &Config,
    opts: &AverageOptions,
) -> anyhow::Result<AverageOk> {
    use anyhow::Context;
    let limits = crate::daemon::ingest::decode_limits(&cfg.ingest);
    // the same safe read as the daemon's: a FIFO or device is refused at once, never waited on
    let (bytes, _) = crate::daemon::ingest::read_capture(None, path, &limits)
        .map_err(|e| anyhow::anyhow!("{}", e.reason))
        .context("cannot read file")?;
    let img = decode(&bytes, &limits)?;
    let s: CaptureStats = crate::daemon::ingest::average_decoded(&img, opts)?;
    let xyz = crate::setup::rgb_to_xyz(cfg).convert_scaled(s.mean_rgb, cfg.colour.scale());
    let lab = cfg
        .colour
        .white
        .resolve(None)
        .ok()
        .map(|w| xyz_to_lab(xyz, w));
    Ok(AverageOk {
        format: img.format,
        width: img.width,
        height: img.height,
        mean_rgb: s.mean_rgb,
        xyz,
        lab,
        pixels: s.pixels,
        nonfinite: s.nonfinite,
        negative: s.negative,
        clipped: s.clipped,
        dark: s.dark,
        max_value: s.max_value,
    })
}

/// A plan entry that the rig takes at a substitute pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SubstituteRecord {
    pub index: usize,
    pub light: usize,
    pub camera: usize,
    pub theta_i_planned_deg: f64,
    pub theta_i_used_deg: f64,
}

/// The output of `goniowatch plan --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct PlanSummary {
    pub directions: usize,
    pub captures: usize,
    pub reciprocal_pairs: usize,
    pub self_pairs: usize,
    pub isotropy_classes: usize,
    pub occlusion_substitutes: usize,
    pub order: crate::measure::plan::AcquisitionOrder,
    pub min_separation_deg: f64,
    /// Rows of the paper's Table 1: (θ, Δφ, directions at that θ).
    pub table1: Vec<(f64, f64, usize)>,
    pub substitutes: Vec<SubstituteRecord>,
    /// Plan entries the rig cannot take at all (no substitute); empty on a sane rig.
    pub unreachable: Vec<(usize, String)>,
    /// What reciprocal pairs alone tell about the lamp's drift, per acquisition order (the
    /// configured one first), at 7 s per capture.
    pub drift_from_pairs: Vec<OrderIdentifiability>,
    /// The probe cadence that meets the detection target (`detect::probe_plan`).
    pub probes: ProbePlanSummary,
}

/// `detect::probe_plan` for the config's sample, order and probe settings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct ProbePlanSummary {
    pub isotropic_sample: bool,
    /// Each probe round is followed by a joint-3 sentinel probe (anisotropic sample).
    pub sentinel: bool,
    pub session: crate::detect::probe_plan::ProbeSession,
    pub target: crate::detect::probe_plan::DetectionTarget,
    /// The configured cadence's figures (`[probes] every`), when probes are on.
    pub configured: Option<crate::detect::probe_plan::CadenceFigures>,
    pub design: crate::detect::probe_plan::ProbePlan,
}

/// `detect::identifiability` for one acquisition order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct OrderIdentifiability {
    pub order: String,
    /// Whether the config offers it (`[plan] order`).
    pub configurable: bool,
    #[serde(flatten)]
    pub pairs: crate::detect::identifiability::PairIdentifiability,
}

/// Identifiability of the drift from the plan's reciprocal pairs under each order: the
/// config's three and a light-outer order whose camera sweep starts at the light's own
/// direction (a design that breaks the per-direction form of the pairs' time differences at no
/// cost in wagon travel: one jump per sweep, as now).
fn drift_from_pairs(
    spec: &crate::measure::plan::PlanSpec,
) -> Result<Vec<OrderIdentifiability>, crate::measure::plan::PlanError> {
    use crate::detect::identifiability::pair_identifiability;
    use crate::measure::plan::{AcquisitionOrder, PlanSpec, SamplingPlan};
    let steps = [0.1, 0.25, 0.5, 0.75, 0.9];
    let t = crate::setup::SECONDS_PER_CAPTURE / 3600.0;
    let mut orders = vec![spec.order];
    for o in [
        AcquisitionOrder::LightOuter,
        AcquisitionOrder::LightOuterSerpentine,
        AcquisitionOrder::CameraOuter,
    ] {
        if !orders.contains(&o) {
            orders.push(o);
        }
    }
    let mut out = Vec::new();
    for order in orders {
        let plan = SamplingPlan::new(&PlanSpec {
            order,
            ..spec.clone()
        })?;
        out.push(OrderIdentifiability {
            order: format!("{order:?}"),
            configurable: true,
            pairs: pair_identifiability(&plan, |i| i as f64 * t, &steps),
        });
    }
    let lo = SamplingPlan::new(&PlanSpec {
        order: AcquisitionOrder::LightOuter,
        ..spec.clone()
    })?;
    let n = lo.direction_count();
    let rotated = |i: usize| {
        lo.entry(i)
            .map(|e| (e.light * n + (e.camera + n - e.light) % n) as f64 * t)
            .unwrap_or(f64::NAN)
    };
    out.push(OrderIdentifiability {
        order: "LightOuterRotated".into(),
        configurable: false,
        pairs: pair_identifiability(&lo, rotated, &steps),
    });
    Ok(out)
}

/// The probe plan: the design over the candidate cadences and the configured cadence's figures.
fn probe_plan(
    cfg: &Config,
    scatter: ProbeScatter,
    target: &crate::detect::probe_plan::DetectionTarget,
) -> anyhow::Result<ProbePlanSummary> {
    use crate::detect::probe_plan::{cadence_figures, design};
    use anyhow::Context;
    let plan = crate::setup::plan(cfg)?;
    let session = crate::setup::probe_session(cfg, &plan, scatter)?;
    let design = design(&session, &cfg.probes, target)
        .context("cannot design the drift probes (--probe-scatter-pct, --target-…)")?;
    let configured = cfg
        .probes
        .every
        .fixed()
        .filter(|&every| every > 0 && every < session.captures)
        .map(|every| cadence_figures(&session, &cfg.probes, target, every));
    Ok(ProbePlanSummary {
        isotropic_sample: cfg.sample.isotropic,
        sentinel: crate::setup::sentinel(cfg),
        session,
        target: *target,
        configured,
        design,
    })
}

pub(crate) fn plan_summary(
    cfg: &Config,
    probe_scatter: ProbeScatter,
    target: &crate::detect::probe_plan::DetectionTarget,
) -> anyhow::Result<PlanSummary> {
    let plan = crate::setup::plan(cfg)?;
    let rig = crate::setup::rig(cfg)?;
    let dirs = plan.directions();
    let mut substitutes = Vec::new();
    let mut unreachable = Vec::new();
    for i in 0..plan.capture_count() {
        let e = plan.entry(i)?;
        match rig.plan_pose(dirs[e.light].spherical(), dirs[e.camera].spherical()) {
            Ok(p) => {
                if let Some((planned, used)) = p.substitute {
                    substitutes.push(SubstituteRecord {
                        index: i,
                        light: e.light,
                        camera: e.camera,
                        theta_i_planned_deg: planned,
                        theta_i_used_deg: used,
                    });
                }
            }
            Err(err) => unreachable.push((i, err.to_string())),
        }
    }
    let table1 = cfg
        .plan
        .thetas_deg
        .iter()
        .zip(&cfg.plan.delta_phi_deg)
        .map(|(&t, &d)| (t, d, dirs.iter().filter(|x| x.theta_deg == t).count()))
        .collect();
    Ok(PlanSummary {
        directions: plan.direction_count(),
        captures: plan.capture_count(),
        reciprocal_pairs: plan.reciprocal_pairs().len(),
        self_pairs: plan.self_pairs().len(),
        isotropy_classes: plan.isotropy_classes().len(),
        occlusion_substitutes: substitutes.len(),
        order: plan.order(),
        min_separation_deg: cfg.rig.min_separation_deg,
        table1,
        substitutes,
        unreachable,
        drift_from_pairs: drift_from_pairs(&cfg.plan)?,
        probes: probe_plan(cfg, probe_scatter, target)?,
    })
}
