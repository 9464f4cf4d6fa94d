//! The end-of-run summary as the terminal shows it (`run` and `replay`).

use crate::engine::Summary;

/// Why a finished check's result means nothing, if it does not: most of its captures failed
/// or are missing, most are dark (the files are on another scale than the config's white), or
/// no reciprocal pair was scored (Table 2 would print zeros that look like a
/// perfect sample). `check` and watch mode then exit with a code of their own, never 0.
pub(crate) fn meaningless(s: &Summary) -> Option<String> {
    let c = &s.checked;
    if c.captures == 0 {
        return Some("no capture was checked".into());
    }
    if (c.failed + c.missing) * 2 > c.captures {
        return Some(format!(
            "{} of {} checked captures failed or are missing ({} failed, {} missing): the result describes too little of the set to be trusted; the alarms and manifest.jsonl say why each one failed",
            c.failed + c.missing,
            c.captures,
            c.failed,
            c.missing
        ));
    }
    let dark = s.dark_captures;
    if dark * 2 > c.captures {
        return Some(format!(
            "{dark} of {} checked captures are dark (at or below [checks] dark_y on the white's scale): the files hold values on another scale than the config's white. Leave [colour] rgb_scale out for check and watch mode to take the white from the data, or set it to the white's Y (100 by default) over the white standard's Y on the files' scale",
            c.captures
        ));
    }
    if s.table2.pairs == 0 {
        return Some(format!(
            "no reciprocal pair was scored ({} captures checked, {} ok): Table 2 is empty, not perfect. A pair needs both captures of a reciprocal geometry, each decoded and above the dark level ([checks] dark_y); if most captures raised `dark-capture`, the files hold values on another scale than the config's white ([colour] rgb_scale)",
            c.captures, c.ok
        ));
    }
    None
}

/// Print the end-of-run summary in the paper's Table 2 form.
pub(crate) fn print_summary(s: &Summary, out: &mut impl std::io::Write) -> std::io::Result<()> {
    print_counts(s, out)?;
    print_tables(s, out)?;
    print_lamp_and_pose(s, out)?;
    print_alarms_and_link(s, out)
}

/// What was captured, checked, left out and paired.
fn print_counts(s: &Summary, out: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(
        out,
        "session {}  rig {}",
        s.session.as_deref().unwrap_or("?"),
        s.rig.as_deref().unwrap_or("?")
    )?;
    writeln!(
        out,
        "captures: {} planned, {} announced, {} checked ({} ok, {} failed, {} missing, {} probes)",
        s.captures_planned,
        s.captures_announced,
        s.checked.captures,
        s.checked.ok,
        s.checked.failed,
        s.checked.missing,
        s.checked.probes
    )?;
    if s.finished && s.entries_not_captured > 0 {
        writeln!(
            out,
            "not captured: {} plan entries have no capture (retakes.csv lists them)",
            s.entries_not_captured
        )?;
    }
    if s.entries_with_duplicates > 0 {
        writeln!(
            out,
            "duplicates: {} plan entries have more than one file (one is checked; the duplicate-files alarms name the others)",
            s.entries_with_duplicates
        )?;
    }
    if !s.files_skipped.is_empty() {
        let by_kind: Vec<String> = s
            .files_skipped
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        writeln!(
            out,
            "files not placed: {} ({}; the report lists them with why)",
            s.files_skipped.values().sum::<u64>(),
            by_kind.join(", ")
        )?;
    }
    writeln!(
        out,
        "pairs: {} exact, {} need resampling, {} grazing; isotropy comparisons: {}",
        s.checked.pairs_exact,
        s.checked.pairs_needs_resampling,
        s.checked.pairs_grazing,
        s.checked.isotropy_comparisons
    )?;
    if s.checked.pose_off_plan + s.checked.encoder_mismatch > 0 {
        writeln!(
            out,
            "pose: {} captures off the plan, {} with encoders disagreeing with the commands ({} of them placed by the commanded pose)",
            s.checked.pose_off_plan, s.checked.encoder_mismatch, s.checked.placed_by_command
        )?;
    }
    Ok(())
}

/// Table 2 and its subsets.
fn print_tables(s: &Summary, out: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(out, "Table 2 (means over exact reciprocal pairs):")?;
    writeln!(
        out,
        "  |ΔX|     |ΔY|     |ΔZ|     ΔE*ab    ΔC*ab    ΔH*ab    ΔE00"
    )?;
    let t = &s.table2;
    writeln!(
        out,
        "  {:<8.3} {:<8.3} {:<8.3} {:<8.3} {:<8.3} {:<8.3} {:<8.3}",
        t.abs_dx, t.abs_dy, t.abs_dz, t.de76, t.dc, t.dh, t.de2000
    )?;
    if !s.by_command.is_empty() {
        subset_line(
            out,
            "  of which placed by the commanded pose (a steady encoder offset)",
            &s.by_command,
            "",
        )?;
    }
    if s.checked.pairs_interpolated + s.checked.pairs_unresolved > 0 {
        subset_line(
            out,
            "occlusion substitutes vs interpolated partners",
            &s.interpolated,
            &format!(" ({} unresolved)", s.checked.pairs_unresolved),
        )?;
    }
    if s.isotropy.pairs > 0 {
        subset_line(out, "isotropy (capture vs class mean)", &s.isotropy, "")?;
    }
    Ok(())
}

/// The lamp's drift and colour, the light sweeps, the probes, the sentinel and what cannot be observed.
fn print_lamp_and_pose(s: &Summary, out: &mut impl std::io::Write) -> std::io::Result<()> {
    if let Some(d) = &s.isotropy_drift {
        writeln!(
            out,
            "gain drift from isotropy classes: {:+.3} %/h ± {:.3} (standard error, {} comparisons)",
            d.rate_pct_per_h, d.se_pct_per_h, d.pairs
        )?;
        if s.checked.drift_left_out_slip > 0 {
            writeln!(
                out,
                "  {} comparisons after the named joint slip left out (the tilt moves the members of a class differently); the rate is the one learnt before it",
                s.checked.drift_left_out_slip
            )?;
        }
        if let Some(m) = &s.sample_off_centre {
            let ((cam, cam_az), (light, light_az)) = (m.camera_pct(), m.light_pct());
            writeln!(
                out,
                "  the sample sits off the rotation centre: {cam:.2} % per unit tan θo towards φ = {cam_az:.0}° (camera), {light:.2} % per unit tan θi towards φ = {light_az:.0}° (light), modelled"
            )?;
        }
        for st in &s.isotropy_steps {
            writeln!(
                out,
                "  with a gain step at {:.2} h of {:+.2} % ± {:.2} (found by the light sweeps)",
                st.t_h,
                100.0 * st.ln_size.exp_m1(),
                100.0 * st.se
            )?;
        }
    }
    for b in &s.observability.blind {
        writeln!(
            out,
            "not observable: {} ({}); to observe it: {}",
            b.what, b.why, b.remedy
        )?;
    }
    if let Some(c) = &s.colour_drift {
        writeln!(
            out,
            "lamp colour drift from {}: {:+.1} K/h ± {:.1} (standard error; ΔE00 {:.3}/h on a white; lamp at {:.0} K, {} observations)",
            c.source, c.k_per_h, c.se_k_per_h, c.de00_per_h, c.lamp_cct_k, c.observations
        )?;
    }
    if let Some(sw) = &s.sweeps {
        match &sw.last {
            Some(r) => {
                let joints: Vec<String> = r
                    .joints
                    .iter()
                    .map(|j| format!("joint {} {:+.2}° ± {:.2}", j.joint, j.offset_deg, j.se_deg))
                    .collect();
                writeln!(
                    out,
                    "light sweeps: {} tested; the last (light {}): {}{}{}",
                    sw.tested,
                    r.light,
                    sweep_level_words(r),
                    if joints.is_empty() { "" } else { ", " },
                    joints.join(", ")
                )?;
            }
            None => writeln!(out, "light sweeps: none tested yet")?,
        }
    }
    if let Some(d) = &s.probe_drift {
        writeln!(
            out,
            "gain drift from probes: {:+.3} %/h ± {:.3} (standard error, {} probes)",
            d.rate_pct_per_h, d.se_pct_per_h, d.pairs
        )?;
    }
    if let Some(p) = &s.probe_pose {
        writeln!(
            out,
            "probe pose (chosen): plan entry {}, θi {:.0}°, θo {:.0}°, {:.0}° from the mirror direction, {:.2} %/° to a pose error",
            p.entry, p.theta_i_deg, p.theta_o_deg, p.specular_distance_deg, p.sensitivity_pct_per_deg
        )?;
    }
    if let Some(j) = &s.joint3_sentinel {
        writeln!(
            out,
            "joint-3 sentinel: plan entry {} (θo {:.0}°, φo {:.0}°, {:+.2} %/° of joint 3), {} readings, latest {:+.2}° against the start",
            j.pose.entry, j.pose.theta_o_deg, j.pose.phi_o_deg, j.pose.sensitivity_pct_per_deg, j.readings, j.offset_deg
        )?;
    }
    Ok(())
}

/// The alarm counts and the link's counters.
fn print_alarms_and_link(s: &Summary, out: &mut impl std::io::Write) -> std::io::Result<()> {
    let alarms: Vec<String> = s.alarms.iter().map(|(k, v)| format!("{k} {v}")).collect();
    writeln!(
        out,
        "alarms: {}",
        if alarms.is_empty() {
            "none".into()
        } else {
            alarms.join(", ")
        }
    )?;
    let l = &s.link;
    writeln!(
        out,
        "link: {} lines, {} CRC errors, {} sequence gaps, {} reconnects, {} controller reboots, {} resyncs",
        l.lines,
        l.crc_errors,
        l.sequence_gaps,
        l.connects.saturating_sub(1),
        l.reboots,
        l.resyncs
    )?;
    Ok(())
}

/// One line for a subset of the pairs: its label, mean ΔE*ab and ΔE00, the count, and `tail`.
fn subset_line(
    out: &mut impl std::io::Write,
    label: &str,
    t: &crate::checks::Table2,
    tail: &str,
) -> std::io::Result<()> {
    writeln!(
        out,
        "{label}: ΔE*ab {:.3}  ΔE00 {:.3} over {}{tail}",
        t.de76, t.de2000, t.pairs
    )
}

/// A sweep's level as the level test judges it: against what its θi layer's light-side pattern
/// predicts, with the standard error of the sweep's mean, and the departure in units of the
/// layer's sweep-to-sweep scatter (the test's own measure). The standard error alone leaves out
/// the pattern and the scatter from sweep to sweep, which fault-free runs show.
pub(crate) fn sweep_level_words(r: &crate::detect::sweeps::SweepRecord) -> String {
    let departure = r.level_pct - r.level_expected_pct;
    let judged = match r.level_z {
        Some(z) => format!("{z:+.1} of the layer's sweep-to-sweep scatter"),
        None => "not judged yet: too few sweeps of its layer".to_string(),
    };
    format!(
        "level {:+.2} %, {:+.2} % ± {:.2} (standard error) off its layer's pattern ({judged})",
        r.level_pct, departure, r.level_se_pct
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::Table2;

    fn printed(s: &Summary) -> String {
        let mut out = Vec::new();
        print_summary(s, &mut out).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn pairs_placed_by_command_are_reported_apart_only_when_there_are_any() {
        let mut s = Summary::default();
        assert!(!printed(&s).contains("commanded pose"));
        s.by_command = Table2 {
            pairs: 7,
            de76: 0.69,
            de2000: 0.57,
            ..Table2::default()
        };
        let text = printed(&s);
        let line = text
            .lines()
            .find(|l| l.contains("placed by the commanded pose"))
            .unwrap_or_else(|| panic!("{text}"));
        assert!(
            line.contains("ΔE*ab 0.690") && line.contains("ΔE00 0.570") && line.ends_with("over 7"),
            "{line}"
        );
        // it follows Table 2's own line
        let t2 = text.find("Table 2").unwrap();
        assert!(text.find(line).unwrap() > t2);
    }

    /// The level is shown against its layer's pattern and the layer's scatter, the measure the
    /// level test uses, not with the standard error of its mean alone.
    #[test]
    fn a_sweeps_level_is_worded_against_its_layers_pattern_and_scatter() {
        let rec = |z: &str| -> crate::detect::sweeps::SweepRecord {
            serde_json::from_str(&format!(
                r#"{{"light":80,"idx":6560,"t":45913.0,"captures":80,"level_pct":-1.62,"level_expected_pct":-1.56,"level_se_pct":0.29,"level_z":{z},"level_cusum":0.0,"joints":[],"residual_sd":0.0,"thresholds":[3.2,3.5],"model_layers":5,"model_builds":30}}"#
            ))
            .unwrap()
        };
        let w = sweep_level_words(&rec("-0.12"));
        assert!(w.contains("level -1.62 %"), "{w}");
        assert!(
            w.contains("-0.06 % ± 0.29 (standard error) off its layer's pattern"),
            "{w}"
        );
        assert!(
            w.contains("-0.1 of the layer's sweep-to-sweep scatter"),
            "{w}"
        );
        let w = sweep_level_words(&rec("null"));
        assert!(w.contains("not judged yet"), "{w}");
    }
}
