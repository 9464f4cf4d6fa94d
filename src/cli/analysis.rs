//! The commands that read files and print: `average`, `compare`, `report` and `plan`.

use super::args::{AlarmsArgs, AverageArgs, CompareArgs, ExportArgs, PlanArgs, ReportArgs};
use super::commands::{average_file, plan_summary, AverageOutcome, ProbePlanSummary};
use super::exit::{self, UsageError};
use crate::config::Config;
use crate::detect::probe_plan::{CadenceFigures, DetectionTarget, ProbePlan};
use crate::measure::averaging::Roi;
use crate::setup::ProbeScatter;
use anyhow::{Context, Result};
use std::io::Write;
use std::path::Path;
use std::process::ExitCode;

fn load_config(path: Option<&Path>) -> Result<Config> {
    match path {
        None => Ok(Config::default()),
        Some(p) => Ok(Config::load(p)
            .with_context(|| format!("invalid config {}", p.display()))?
            .0),
    }
}

pub(super) fn average_command(args: AverageArgs, out: &mut impl Write) -> Result<ExitCode> {
    let AverageArgs {
        files,
        config,
        json,
        roi,
    } = args;
    let cfg = load_config(config.as_deref())?;
    let mut opts = cfg.capture;
    if let Some(r) = roi {
        opts.roi = Roi::parse(&r).map_err(|e| UsageError(format!("--roi: {e}")))?;
    }
    let mut failed = 0usize;
    for f in &files {
        let rec = average_file(f, &cfg, &opts);
        if json {
            writeln!(out, "{}", serde_json::to_string(&rec)?)?;
        } else {
            match &rec.outcome {
                AverageOutcome::Ok(ok) => writeln!(
                    out,
                    "{}: {}×{} {:?}  mean RGB [{:.6e} {:.6e} {:.6e}]  XYZ [{:.4} {:.4} {:.4}]  pixels {}  non-finite {}  negative {}  clipped {}",
                    rec.file, ok.width, ok.height, ok.format, ok.mean_rgb[0], ok.mean_rgb[1], ok.mean_rgb[2],
                    ok.xyz[0], ok.xyz[1], ok.xyz[2], ok.pixels, ok.nonfinite, ok.negative, ok.clipped
                )?,
                AverageOutcome::Err { error } => writeln!(out, "{}: ERROR {error}", rec.file)?,
            }
        }
        if matches!(rec.outcome, AverageOutcome::Err { .. }) {
            tracing::warn!(file = %rec.file, "capture failed");
            failed += 1;
        }
    }
    if failed > 0 {
        eprintln!("{failed} of {} files failed", files.len());
        return Ok(ExitCode::from(exit::EXIT_FILE_FAILED));
    }

    Ok(ExitCode::SUCCESS)
}

pub(super) fn compare_command(args: CompareArgs, out: &mut impl Write) -> Result<ExitCode> {
    let CompareArgs {
        session,
        reference,
        json,
        worst,
        drift_rate,
        no_gain_correction,
        max_reference_spread_pct,
    } = args;
    if !(max_reference_spread_pct > 0.0 && max_reference_spread_pct.is_finite()) {
        return Err(UsageError(format!(
            "--max-reference-spread-pct {max_reference_spread_pct} must be a positive number"
        ))
        .into());
    }
    use crate::cli::compare::{compare, render, GainChoice};
    if let Some(r) = drift_rate {
        if !r.is_finite() {
            return Err(UsageError(format!("--drift-rate {r} is not a finite number")).into());
        }
    }
    let gain = match (drift_rate, no_gain_correction) {
        (Some(r), _) => GainChoice::Rate(r),
        (None, true) => GainChoice::None,
        (None, false) => GainChoice::Session,
    };
    let report = compare(
        &session,
        &reference,
        gain,
        worst,
        max_reference_spread_pct / 100.0,
    )?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&report)?)?;
    } else {
        write!(out, "{}", render(&report))?;
    }

    Ok(ExitCode::SUCCESS)
}

pub(super) fn report_command(args: ReportArgs, out: &mut impl Write) -> Result<ExitCode> {
    let ReportArgs {
        session,
        out: out_dir,
    } = args;
    let files = crate::cli::report::report(&session, out_dir.as_deref())?;
    for f in &files {
        writeln!(out, "{}", f.display())?;
    }

    Ok(ExitCode::SUCCESS)
}

pub(super) fn plan_command(args: PlanArgs, out: &mut impl Write) -> Result<ExitCode> {
    let PlanArgs {
        config,
        json,
        probe_scatter_pct,
        target_decay_pct_per_h,
        target_decay_by,
        target_step_pct,
        target_step_within,
        target_false_alarms,
        colour_scatter_pct,
        target_colour_k_per_h,
        target_colour_by,
    } = args;
    let cfg = load_config(config.as_deref())?;
    let target = DetectionTarget {
        decay_pct_per_h: target_decay_pct_per_h,
        decay_by_fraction: target_decay_by,
        step_pct: target_step_pct,
        step_within_captures: target_step_within,
        false_alarms_per_run: target_false_alarms,
        colour_k_per_h: target_colour_k_per_h,
        colour_by_fraction: target_colour_by,
        ..DetectionTarget::default()
    };
    let luminance_pct = probe_scatter_pct.unwrap_or(cfg.probes.design_scatter_pct);
    let s = plan_summary(
        &cfg,
        ProbeScatter {
            luminance_pct,
            chromaticity_pct: colour_scatter_pct.unwrap_or(luminance_pct),
        },
        &target,
    )?;
    if json {
        writeln!(out, "{}", serde_json::to_string_pretty(&s)?)?;
    } else {
        writeln!(out, "Sampling plan ({:?} order)", s.order)?;
        writeln!(out, "  θ [deg]   Δφ [deg]   directions")?;
        for (t, d, n) in &s.table1 {
            writeln!(
                out,
                "  {t:>7}   {:>8}   {n:>10}",
                if *t == 0.0 {
                    "-".to_string()
                } else {
                    d.to_string()
                }
            )?;
        }
        writeln!(out, "directions             {}", s.directions)?;
        writeln!(out, "captures               {}", s.captures)?;
        writeln!(
            out,
            "reciprocal pairs       {} (+ {} self pairs)",
            s.reciprocal_pairs, s.self_pairs
        )?;
        writeln!(out, "isotropy classes       {}", s.isotropy_classes)?;
        writeln!(
            out,
            "occlusion substitutes  {} (lamp–camera separation < {}°, θi changed)",
            s.occlusion_substitutes, s.min_separation_deg
        )?;
        if !s.unreachable.is_empty() {
            writeln!(out, "UNREACHABLE entries    {}", s.unreachable.len())?;
        }
        writeln!(
            out,
            "\nDrift from reciprocal pairs alone (no probes, no isotropy classes), 7 s per capture:\nstandard errors per 1 % of pair noise, the {} free per-direction non-reciprocities fitted",
            s.directions.saturating_sub(1)
        )?;
        writeln!(
            out,
            "  order                    rate [%/h]   step at 10 / 25 / 50 / 75 / 90 % of the run [%]"
        )?;
        let cell = |v: Option<f64>| v.map_or("  –   ".to_string(), |x| format!("{x:6.3}"));
        for o in &s.drift_from_pairs {
            let steps: Vec<String> = o.pairs.step_se_pct.iter().map(|(_, v)| cell(*v)).collect();
            writeln!(
                out,
                "  {:<24} {:>10}   {}{}",
                o.order,
                o.pairs
                    .rate_se_pct_per_h
                    .map_or("not seen".to_string(), |x| format!("{x:.4}")),
                steps.join(" "),
                if o.configurable {
                    ""
                } else {
                    "  (not a config order)"
                }
            )?;
        }
        print_probe_plan(&s.probes, &cfg.probes, out)?;
    }

    Ok(ExitCode::SUCCESS)
}

/// `plan`'s drift-probe section: the target, every cadence tried, and the recommendation or why
/// there is none.
fn print_probe_plan(
    p: &ProbePlanSummary,
    spec: &crate::detect::probes::ProbeSpec,
    out: &mut impl Write,
) -> Result<()> {
    let t = &p.target;
    let pose = match spec.entry {
        Some(e) => format!("plan entry {e}"),
        None => format!(
            "a pose the daemon chooses after {} captures, plan entry {} standing in",
            p.session.probes_from, p.session.anchor
        ),
    };
    writeln!(
        out,
        "\nDrift probes: a re-capture every N captures of {pose}; {} s {}; probe scatter {} %{}",
        p.session.seconds_per_probe,
        if p.sentinel {
            "per round (the lamp probe, then a joint-3 sentinel: the sample is anisotropic)"
        } else {
            "each"
        },
        p.session.scatter_pct,
        p.session.colour.as_ref().map_or(String::new(), |c| format!(
            ", chromaticity scatter {} % (ln X/Y, ln Z/Y; a {} K lamp)",
            c.scatter_pct, c.lamp_cct_k
        ))
    )?;
    let colour_target = match &p.session.colour {
        Some(c) if t.colour_k_per_h != 0.0 => format!(
            ", a {:+} K/h colour drift before {:.0} % of the run (colour-drift: tolerance {} K/h, z = {})",
            t.colour_k_per_h,
            100.0 * t.colour_by_fraction,
            c.tolerance_k_per_h,
            c.z
        ),
        _ => String::new(),
    };
    writeln!(
        out,
        "target: a {} %/h decay flagged before {:.0} % of the run and a {:+} % step within {} captures{colour_target}, each in {:.0} % of runs; at most {:.0} false alarms in 100 runs ({} simulated runs per cadence through the daemon's probe detector: z = {}, step_sigmas = {}, step_pct = {})",
        t.decay_pct_per_h,
        100.0 * t.decay_by_fraction,
        t.step_pct,
        t.step_within_captures,
        100.0 * t.power,
        100.0 * t.false_alarms_per_run,
        crate::detect::probe_plan::RUNS,
        spec.z,
        spec.step_sigmas,
        spec.step_pct
    )?;
    writeln!(
        out,
        "  every   probes   run time +   false alarms/run   decay in time (median at)   step in time (median delay)   colour in time (median at)"
    )?;
    let row = |c: &CadenceFigures| {
        let colour = c
            .colour_in_time
            .map_or("     –              ".to_string(), |x| {
                format!(
                    "{:>5.0} % ({:>5})",
                    100.0 * x,
                    c.colour_median_fraction
                        .map_or("–".to_string(), |f| format!("{:.0} %", 100.0 * f))
                )
            });
        format!(
            "  {:>5}   {:>6}   {:>4.2} h {:>4.1} %   {:>16.3}   {:>5.0} % ({:>5})            {:>5.0} % ({:>5})              {colour}           {}",
            c.every,
            c.probes_per_run,
            c.overhead_h,
            c.overhead_pct,
            c.false_alarms_per_run,
            100.0 * c.decay_in_time,
            c.decay_median_fraction
                .map_or("–".to_string(), |f| format!("{:.0} %", 100.0 * f)),
            100.0 * c.step_in_time,
            c.step_median_delay.map_or("–".to_string(), |d| format!("{d:.0}")),
            if c.meets { "meets" } else { "" }
        )
    };
    let tried = match &p.design {
        ProbePlan::Recommended { tried, .. } | ProbePlan::Unreachable { tried, .. } => tried,
    };
    for c in tried {
        writeln!(out, "{}", row(c))?;
    }
    match &p.design {
        ProbePlan::Recommended { cadence, .. } => writeln!(
            out,
            "recommended: [probes] every = {} (adds {:.2} h, {:.1} % of the run)",
            cadence.every, cadence.overhead_h, cadence.overhead_pct
        )?,
        ProbePlan::Unreachable { reason, .. } => {
            writeln!(out, "NO CADENCE MEETS THE TARGET: {reason}")?
        }
    }
    if let Some(c) = &p.configured {
        writeln!(out, "configured:\n{}", row(c))?;
    }
    if p.isotropic_sample {
        writeln!(
            out,
            "(an isotropic sample: its isotropy classes and light sweeps watch the lamp without probes, and the classes its colour, so the probes are designed for the luminance target only)"
        )?;
    } else {
        writeln!(
            out,
            "(an anisotropic sample: without probes nothing watches the lamp's rate or colour)"
        )?;
    }
    Ok(())
}

pub(super) fn alarms_command(args: AlarmsArgs, out: &mut impl Write) -> Result<ExitCode> {
    if args.json {
        for e in crate::checks::catalogue::catalogue() {
            writeln!(out, "{}", serde_json::to_string(&e)?)?;
        }
    } else {
        write!(out, "{}", crate::checks::catalogue::markdown())?;
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn export_command(args: ExportArgs, out: &mut impl Write) -> Result<ExitCode> {
    use super::export::{export_images, export_merl, export_table, load, ExportFormat};
    let ExportArgs {
        session,
        format,
        out: dest,
        sigma,
        fit_nodes,
        weight_nodes,
        across_layers,
        no_drift_correction,
        capture_root,
        threads,
    } = args;
    if sigma.is_some() && format != ExportFormat::Merl {
        return Err(UsageError("--sigma goes with --format merl".into()).into());
    }
    let default_nodes = (fit_nodes, weight_nodes) == (40, 40)
        && across_layers == super::export::LayerInterpolation::Brdf;
    if !default_nodes && format != ExportFormat::Merl {
        return Err(UsageError(
            "--fit-nodes, --weight-nodes and --across-layers go with --format merl".into(),
        )
        .into());
    }
    if capture_root.is_some() && format != ExportFormat::CorrectedImages {
        return Err(UsageError("--capture-root goes with --format corrected-images".into()).into());
    }
    let threads = threads
        .map(usize::from)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let data = load(&session, !no_drift_correction)
        .with_context(|| format!("cannot export {}", session.display()))?;
    let result = match format {
        ExportFormat::Merl => export_merl(
            &data,
            dest.as_deref(),
            sigma.as_deref(),
            (usize::from(fit_nodes), usize::from(weight_nodes)),
            across_layers,
            threads,
        ),
        ExportFormat::Table => export_table(&data, dest.as_deref()),
        ExportFormat::CorrectedImages => {
            export_images(&data, dest.as_deref(), capture_root.as_deref(), threads)
        }
    };
    let done = match result {
        Ok(d) => d,
        Err(e) => {
            if let Some(crate::export::ExportError::NothingToExport(why)) = e.downcast_ref() {
                eprintln!("goniowatch: nothing to export: {why}");
                return Ok(ExitCode::from(exit::EXIT_MEANINGLESS));
            }
            return Err(e);
        }
    };
    for l in &done.lines {
        writeln!(out, "{l}")?;
    }
    if done.meaningless {
        eprintln!("goniowatch: the export holds no usable value");
        return Ok(ExitCode::from(exit::EXIT_MEANINGLESS));
    }
    if done.failed {
        return Ok(ExitCode::from(exit::EXIT_RUNTIME));
    }
    Ok(ExitCode::SUCCESS)
}
