//! Whole synthetic sessions through the monitor: a smooth isotropic BRDF on the UBO plan, a
//! per-light footprint effect, 1 % capture noise, and one fault from `onset`.
use super::model_tests::{brdf, plan_pose};
use super::*;
use crate::measure::geometry::azimuth_difference_deg;
use crate::measure::plan::SamplingPlan;

#[derive(Clone, Copy)]
enum Fault {
    None,
    /// (joint index 0-based, degrees)
    Joint(usize, f64),
    /// gain factor
    Step(f64),
    /// a lamp whose gain has an SD of its own every capture (ln units), until this capture
    Flicker(f64, usize),
    /// A stationary effect of the geometry that follows the pose: the captures of every light
    /// from this one on look as if the joint (0-based) were off by the degrees, whenever they
    /// are taken (a re-capture of an earlier light's pose shows nothing). The onset is unused.
    LightPattern(usize, f64, usize),
    /// The wagon lags this many degrees behind its commanded angle against its last direction
    /// of motion.
    WagonBacklash(f64),
    /// The wagon stands this many degrees off its commanded angle.
    WagonOffset(f64),
    /// A stationary light-side pattern on one side of the turn (a holder's jaw shading the
    /// sample): every light's level moves by −size·tan θi·max(0, cos(φi − 180°))², whenever
    /// it is taken; with a gain factor from the onset as well (a lamp step under it). The
    /// footprint's noise per light is 0.2 % with it.
    Shadow(f64, Option<f64>),
}

/// The joints named as slipped, with the sweep each was named at.
fn slips(findings: &[SweepFinding]) -> impl Iterator<Item = (&SweepAt, &JointSlip)> {
    findings.iter().filter_map(|f| match f {
        SweepFinding::JointSlip { at, slip } => Some((at, slip)),
        _ => None,
    })
}

/// The gain steps: the sweep each was found at, its run, and whether it went up.
fn gain_steps(findings: &[SweepFinding]) -> impl Iterator<Item = (&SweepAt, &LevelRun, bool)> {
    findings.iter().filter_map(|f| match f {
        SweepFinding::GainStep { at, run, up, .. } => Some((at, run, *up)),
        _ => None,
    })
}

/// A deterministic standard normal draw (splitmix64 + Box–Muller).
fn normal(seed: u64, k: u64) -> f64 {
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let a = mix(seed.wrapping_mul(1_000_003).wrapping_add(2 * k));
    let b = mix(a ^ 0x5555);
    let u1 = ((a >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = ((b >> 11) as f64) / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Runs the session up to (and including) light sweep `last_light`; returns the records
/// and the findings, in order.
fn run(
    fault: Fault,
    onset: usize,
    last_light: usize,
    seed: u64,
    level_test: bool,
) -> (Vec<SweepRecord>, Vec<SweepFinding>) {
    run_outlined(fault, onset, last_light, seed, level_test, (0.0, 0.0))
}

/// `run` on a sample whose outline shapes the lamp's footprint: every light's level moves
/// by `outline`·tan²θi·(cos 4φi + 0.4 cos 2φi), a square's quarter-turn pattern with a
/// rectangle's half-turn one (1.8 % and 0.7 % at θi = 75° for 0.0013).
fn run_outlined(
    fault: Fault,
    onset: usize,
    last_light: usize,
    seed: u64,
    level_test: bool,
    outline: (f64, f64),
) -> (Vec<SweepRecord>, Vec<SweepFinding>) {
    let (_, records, findings) = simulate(fault, onset, last_light, seed, level_test, outline);
    (records, findings)
}

/// `run_outlined`, and the monitor as the session left it.
fn simulate(
    fault: Fault,
    onset: usize,
    last_light: usize,
    seed: u64,
    level_test: bool,
    outline: (f64, f64),
) -> (SweepMonitor, Vec<SweepRecord>, Vec<SweepFinding>) {
    simulate_with(fault, onset, last_light, seed, level_test, outline, None)
}

/// `simulate` on a rig that takes probes: with `recapture` (the SD of one re-capture's ln ratio
/// to its original), the monitor's re-captures are taken right after the sweep that asked for them, with
/// the rig as it is then.
fn simulate_with(
    fault: Fault,
    onset: usize,
    last_light: usize,
    seed: u64,
    level_test: bool,
    (outline, second): (f64, f64),
    recapture: Option<f64>,
) -> (SweepMonitor, Vec<SweepRecord>, Vec<SweepFinding>) {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig.clone(), plan.direction_count());
    m.set_recapture(recapture.map(|sd| RecaptureNoise {
        capture_sd: sd / std::f64::consts::SQRT_2,
        y_ref: None,
    }));
    let dirs = plan.directions().to_vec();
    // the wagon's last commanded direction of motion at each plan entry (the plan's order)
    let mut wagon_dirs = Vec::with_capacity(plan.capture_count());
    let (mut prev, mut dir) = (None::<f64>, 0.0);
    for e in 0..plan.capture_count() {
        let pe = plan.entry(e).unwrap();
        if let Some((_, pose)) = plan_pose(&rig, &dirs[pe.light], &dirs[pe.camera]) {
            if let Some(w) = prev.filter(|w| *w != pose.wagon_deg) {
                dir = (pose.wagon_deg - w).signum();
            }
            prev = Some(pose.wagon_deg);
        }
        wagon_dirs.push(dir);
    }
    // plan entry `e` taken at capture `at` (the fault's state and the noise are the time's),
    // the wagon last moving in direction `dir` (a re-capture's; the plan order's when None)
    let render = |e: usize, at: usize, dir: Option<f64>| {
        let pe = plan.entry(e).unwrap();
        let (l, c) = (dirs[pe.light], dirs[pe.camera]);
        let (inc, pose) = plan_pose(&rig, &l, &c)?;
        let mut actual = pose;
        let mut gain = 1.0;
        if at >= onset {
            match fault {
                Fault::None | Fault::LightPattern(..) | Fault::Shadow(_, None) => {}
                Fault::Shadow(_, Some(g)) => gain = g,
                Fault::Joint(j, d) => actual.joints_deg[j] += d,
                Fault::WagonBacklash(b) => actual.wagon_deg -= b * dir.unwrap_or(wagon_dirs[e]),
                Fault::WagonOffset(d) => actual.wagon_deg += d,
                Fault::Step(g) => gain = g,
                Fault::Flicker(sd, until) if at < until => {
                    gain = (sd * normal(seed ^ 0xF11C, at as u64)).exp();
                }
                Fault::Flicker(..) => {}
            }
        }
        if let Fault::LightPattern(j, d, from) = fault {
            if pe.light >= from {
                actual.joints_deg[j] += d;
            }
        }
        let seen = rig.forward(&actual).ok()?;
        if seen.omega_i.z <= 0.0 || seen.omega_o.z <= 0.0 {
            return None;
        }
        let (ti, pi) = (l.theta_deg.to_radians(), l.phi_deg.to_radians());
        let shape =
            outline * ti.tan().powi(2) * ((4.0 * pi).cos() + second * (2.0 * pi - 1.0).cos());
        let shadow = match fault {
            Fault::Shadow(size, _) => {
                -size * ti.tan() * (pi - std::f64::consts::PI).cos().max(0.0).powi(2)
            }
            _ => 0.0,
        };
        // the footprint's own noise per light: 0.5 %, 0.2 % under a shadow (a pattern is told
        // from per-light noise only where it stands out of it)
        let per_light = if matches!(fault, Fault::Shadow(..)) {
            0.002
        } else {
            0.005
        };
        let footprint = per_light * normal(seed ^ 0xF00D, pe.light as u64) + shape + shadow;
        // a re-capture's noise is its own
        let k = if at == e {
            e as u64
        } else {
            (1 << 40) + ((at as u64) << 16) + e as u64
        };
        let y = brdf(&seen.omega_i, &seen.omega_o)
            * seen.omega_i.z
            * gain
            * (footprint + 0.01 * normal(seed, k)).exp();
        Some((pe, l, c, inc, pose, y))
    };
    let (mut records, mut findings) = (Vec::new(), Vec::new());
    let mut current: Option<usize> = None;
    let (mut last_w, mut wagon_dir) = (None::<f64>, 0.0);
    for e in 0..plan.capture_count() {
        let pe = plan.entry(e).unwrap();
        if current != Some(pe.light) {
            if let Some(done) = current {
                let o = m.light_complete(done, level_test, None, None);
                records.extend(o.record);
                findings.extend(o.findings);
                if let Some(entries) = m.recapture_wanted() {
                    m.handle_recapture_asked();
                    // the rig takes them back to back: each approached from the one before
                    let (mut w, mut dir) = (last_w, wagon_dir);
                    for entry in entries {
                        let pe = plan.entry(entry).unwrap();
                        if let Some((_, pose)) = plan_pose(&rig, &dirs[pe.light], &dirs[pe.camera])
                        {
                            if let Some(before) = w.filter(|v| *v != pose.wagon_deg) {
                                dir = (pose.wagon_deg - before).signum();
                            }
                            w = Some(pose.wagon_deg);
                        }
                        if let Some((.., y)) = render(entry, e, Some(dir)) {
                            findings.extend(m.handle_recapture(entry, y, dir).findings);
                        }
                    }
                }
                if done == last_light {
                    break;
                }
            }
            current = Some(pe.light);
        }
        findings.extend(m.handle_regular_capture().findings);
        // with probes (no level test), the probes' lamp-unstable stands over a flicker from
        // capture `PROBES_SEE_FLICKER_AT` on (where the matrix's probes every 75 raise it)
        if let (Fault::Flicker(_, until), false) = (fault, level_test) {
            m.set_probes_unstable(e >= PROBES_SEE_FLICKER_AT && e < until);
        }
        let Some((pe, l, c, inc, pose, y)) = render(e, e, None) else {
            continue;
        };
        if let Some(w) = last_w.filter(|w| *w != pose.wagon_deg) {
            wagon_dir = (pose.wagon_deg - w).signum();
        }
        last_w = Some(pose.wagon_deg);
        let dphi = if l.theta_deg == 0.0 || c.theta_deg == 0.0 {
            0.0
        } else {
            azimuth_difference_deg(l.phi_deg, c.phi_deg)
        };
        let class = (
            (l.theta_deg * 1000.0).round() as i64,
            (c.theta_deg * 1000.0).round() as i64,
            (dphi * 1000.0).round() as i64,
        );
        m.add(SweepCapture {
            idx: e as u64,
            t: 7.0 * e as f64,
            entry: e,
            light: pe.light,
            camera: pe.camera,
            class,
            layer: class.0,
            omega_i: inc.omega_i,
            omega_o: inc.omega_o,
            cmd: [
                pose.joints_deg[0],
                pose.joints_deg[1],
                pose.joints_deg[2],
                pose.wagon_deg,
            ],
            wagon_dir,
            y,
            mount: [0.0; 4],
        });
    }
    (m, records, findings)
}

/// Mid-run, inside light sweep 46 (the θi = 60° layer's tenth).
const ONSET: usize = 46 * 81 + 40;
/// Eight sweeps after the onset.
const LAST: usize = 54;

#[test]
fn a_fault_free_session_raises_nothing() {
    for seed in [1, 2] {
        let (records, findings) = run(Fault::None, usize::MAX, LAST, seed, true);
        assert!(findings.is_empty(), "seed {seed}: {findings:?}");
        assert!(records.len() > 40, "{}", records.len());
        // the joint fits are tested once enough sweeps are behind them
        assert!(records.last().unwrap().joints.iter().all(|f| f.z.is_some()));
    }
}

/// The first positioning alarm names the offset joint with the offset's sign. A joint-1
/// tilt also changes cos θi for the whole sweep, so it may show first as a level change,
/// which the joint's pattern then claims.
#[test]
fn a_joint_offset_from_mid_run_names_that_joint() {
    for (joint, deg, onset) in [
        (1usize, 2.0, ONSET),
        (1, -1.0, ONSET),
        (0, 2.0, ONSET),
        (0, 2.0, 40 * 81 + 40),
    ] {
        let (_, findings) = run(Fault::Joint(joint, deg), onset, LAST, 1, true);
        let (at, first) = slips(&findings).next().unwrap_or_else(|| {
            panic!(
                "joint {} {deg}° from {onset}: no joint named in {findings:?}",
                joint + 1
            )
        });
        assert_eq!(first.joint, joint + 1, "{first:?}");
        // the size, from the smooth model's sensitivities, within ±30 % of the truth
        let est = first.offset_deg;
        assert!((est / deg - 1.0).abs() <= 0.3, "estimate {est} for {deg}");
        // the estimate comes from the sweeps that show the slip, and says how many; the
        // CUSUM run's own mean is kept
        let used = first.estimate_sweeps;
        assert!(used >= 1 && used <= first.sweeps, "{first:?}");
        assert!(first.run_mean_deg * deg > 0.0);
        let named_at = at.last_idx;
        assert!(
            named_at as usize >= onset && (named_at as usize) < onset + 4 * 81,
            "{named_at}"
        );
        // the captures it can have affected begin with the sweep before the one that began
        // the CUSUM run: the onset is in it
        let from_idx = first.from_idx;
        assert!(from_idx as usize <= onset, "{from_idx} {onset}");
        assert!(from_idx as usize + 2 * 81 > onset, "{from_idx} {onset}");
        // a tilt is no lamp step: a level change that follows the slip in its layer is the
        // slip's, and a gain step found after the slip began but before the joint was named
        // is withdrawn when it is
        let withdrawn: Vec<u64> = findings
            .iter()
            .filter_map(|f| match f {
                SweepFinding::GainStepWithdrawn { step_idx, .. } => Some(*step_idx),
                _ => None,
            })
            .collect();
        for (step_at, _, _) in gain_steps(&findings) {
            let idx = step_at.last_idx;
            assert!(idx < named_at, "{findings:?}");
            assert_eq!(idx >= from_idx, withdrawn.contains(&idx), "{findings:?}");
        }
        if joint == 0 && onset == ONSET {
            // this session's tilt moves the level before the interpolant's pattern names the
            // joint: the level crossing is attributed to the joint, and no gain step is found
            assert!(first.attributed_level_pct.unwrap() * deg < 0.0, "{first:?}");
            assert!(
                !findings.iter().any(|f| matches!(
                    f,
                    SweepFinding::GainStep { .. } | SweepFinding::GainStepWithdrawn { .. }
                )),
                "{findings:?}"
            );
        }
        for f in &findings {
            if let SweepFinding::LevelAfterSlip {
                at: level_at,
                joint: named,
                slip_from_idx,
                ..
            } = f
            {
                assert!(level_at.last_idx > named_at, "{f:?}");
                assert_eq!((*named, *slip_from_idx), (joint + 1, from_idx), "{f:?}");
            }
        }
    }
}

/// The wagon named in a session's findings: the sweep and what it found.
fn wagon(findings: &[SweepFinding]) -> Vec<(&SweepAt, &WagonBacklash)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::WagonBacklash { at, backlash } => Some((at, backlash)),
            _ => None,
        })
        .collect()
}

/// A lag of the wagon against its direction of motion is named as the wagon's, once, with
/// its size within ±30 % and no joint named before it; a joint's offset is never taken for it.
#[test]
fn a_wagon_lag_from_mid_run_names_the_wagon_and_a_joint_offset_does_not() {
    for (lag, onset) in [(1.0, ONSET), (0.6, 40 * 81 + 40)] {
        let (_, findings) = run(Fault::WagonBacklash(lag), onset, LAST + 6, 1, true);
        let named = wagon(&findings);
        assert_eq!(named.len(), 1, "lag {lag}° from {onset}: {findings:?}");
        let (at, w) = named[0];
        assert!(
            at.last_idx as usize >= onset && (at.last_idx as usize) < onset + 6 * 81,
            "{at:?}"
        );
        assert!((w.backlash_deg / lag - 1.0).abs() <= 0.3, "{w:?}");
        assert!(w.se_deg > 0.0 && w.estimate_sweeps >= 1, "{w:?}");
        assert!(
            w.from_idx as usize <= onset && w.from_idx as usize + 2 * 81 > onset,
            "{w:?}"
        );
        assert!(
            slips(&findings).all(|(s, _)| s.last_idx > at.last_idx),
            "{findings:?}"
        );
    }
    for (joint, deg) in [(0usize, 2.0), (1, 2.0), (1, -1.0)] {
        let (_, findings) = run(Fault::Joint(joint, deg), ONSET, LAST + 6, 1, true);
        assert!(
            wagon(&findings).is_empty(),
            "joint {}: {findings:?}",
            joint + 1
        );
    }
    let (_, findings) = run(Fault::None, usize::MAX, LAST + 6, 2, true);
    assert!(wagon(&findings).is_empty(), "{findings:?}");
}

/// The wagon's offsets the re-captured pair named, with the sweep each was named at.
fn wagon_offsets(findings: &[SweepFinding]) -> Vec<(&SweepAt, &WagonOffset)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::WagonOffset { at, offset } => Some((at, offset)),
            _ => None,
        })
        .collect()
}

/// On a probe-taking rig the re-captured pair names a wagon offset from mid-run as the wagon,
/// with its sign and about its size, within 600 captures; a joint-1 slip, which moves the pair
/// as much, is not named as the wagon (the sweeps see its light side); a fault-free session and
/// a lamp step raise nothing from it. The pair costs under 1 % of the run.
#[test]
fn a_wagon_offset_is_named_from_a_re_captured_pair_and_a_joint_1_slip_is_not() {
    let noise = Some(0.004);
    for deg in [1.0, -1.0] {
        let (m, _, findings) = simulate_with(
            Fault::WagonOffset(deg),
            ONSET,
            LAST + 4,
            1,
            false,
            (0.0, 0.0),
            noise,
        );
        let named = wagon_offsets(&findings);
        assert_eq!(named.len(), 1, "{deg}°: {findings:?}");
        let (at, w) = named[0];
        assert!(
            (at.last_idx as usize) < ONSET + 600 && at.last_idx as usize > ONSET,
            "{at:?}"
        );
        assert!((w.offset_deg / deg - 1.0).abs() <= 0.3, "{w:?}");
        assert!(w.se_deg > 0.0 && w.readings >= 2, "{w:?}");
        assert!(
            (w.since_idx as usize) <= ONSET && (w.since_idx as usize) + 4 * 81 > ONSET,
            "{w:?}"
        );
        assert!(
            slips(&findings).all(|(_, s)| s.joint != 1),
            "{deg}°: {findings:?}"
        );
        let summary = m.summary().wagon_watch.unwrap();
        assert!(
            summary.entries.is_some() && summary.readings >= 8,
            "{summary:?}"
        );
    }
    for fault in [
        Fault::Joint(0, 1.0),
        Fault::Joint(0, -1.0),
        Fault::Step(0.97),
    ] {
        let (_, _, findings) = simulate_with(fault, ONSET, LAST + 4, 1, false, (0.0, 0.0), noise);
        assert!(wagon_offsets(&findings).is_empty(), "{findings:?}");
    }
    for seed in [2, 3] {
        let (m, _, findings) =
            simulate_with(Fault::None, usize::MAX, 80, seed, false, (0.0, 0.0), noise);
        assert!(wagon_offsets(&findings).is_empty(), "{findings:?}");
        // two captures a question: under 1 % of the UBO run
        let readings = m.summary().wagon_watch.unwrap().readings;
        assert!(readings >= 10 && 2 * readings < 66, "{readings}");
    }
    // without probes there is no watch
    let (m, _, findings) = simulate_with(
        Fault::WagonOffset(1.0),
        ONSET,
        LAST + 4,
        1,
        false,
        (0.0, 0.0),
        None,
    );
    assert!(wagon_offsets(&findings).is_empty() && m.summary().wagon_watch.is_none());
}

/// The slopes a slip's size is fitted with: on the noisy session, the smooth model's
/// follow the BRDF's (correlation and regression slope near 1, the wagon's too), where the
/// interpolant's, through one noisy node per class, do not.
#[test]
fn the_smooth_models_sensitivities_follow_the_brdf_where_the_interpolants_do_not() {
    let rig = Rig::new(Default::default()).unwrap();
    let truth = |cmd: &[f64; 4], axis: usize| {
        let f = |d: f64| {
            let mut p = Pose {
                joints_deg: [cmd[0], cmd[1], cmd[2]],
                wagon_deg: cmd[3],
            };
            if axis < 2 {
                p.joints_deg[axis] += d;
            } else {
                p.wagon_deg += d;
            }
            let inc = rig.forward(&p).unwrap();
            (brdf(&inc.omega_i, &inc.omega_o) * inc.omega_i.z).ln()
        };
        f(0.5) - f(-0.5)
    };
    // (correlation, regression slope of the truth on the model) per axis
    let score = |m: &SweepMonitor, model: Model, axis: usize| {
        let (mut num, mut den_m, mut den_t) = (0.0, 0.0, 0.0);
        for c in m.captures.iter().filter(|c| (41..=48).contains(&c.light)) {
            let Some(s) = m.sensitivities(&c.cmd, model) else {
                continue;
            };
            if !s[axis].is_finite() {
                continue;
            }
            let t = truth(&c.cmd, axis);
            num += s[axis] * t;
            den_m += s[axis] * s[axis];
            den_t += t * t;
        }
        (num / (den_m * den_t).sqrt(), num / den_m)
    };
    for seed in [1, 2] {
        let (m, _, _) = simulate(Fault::None, usize::MAX, 48, seed, true, (0.0, 0.0));
        for (model, axes) in [(Model::Smooth, 3), (Model::Interpolant, 2)] {
            for axis in 0..axes {
                let (corr, slope) = score(&m, model, axis);
                eprintln!(
                    "seed {seed} {model:?} axis {axis}: correlation {corr:.2}, slope {slope:.2}"
                );
            }
        }
        for axis in 0..3 {
            let (corr, slope) = score(&m, Model::Smooth, axis);
            assert!(corr > 0.95, "seed {seed} axis {axis}: {corr}");
            assert!(
                (0.9..1.1).contains(&slope),
                "seed {seed} axis {axis}: {slope}"
            );
        }
        for axis in 0..2 {
            let (corr, slope) = score(&m, Model::Interpolant, axis);
            assert!(
                corr < 0.6 && slope < 0.3,
                "seed {seed} axis {axis}: {corr} {slope}"
            );
        }
    }
}

#[test]
fn a_square_samples_footprint_at_grazing_light_is_the_layers_pattern_not_a_step() {
    // the last layer (θi = 75°, lights 57–80) swings by ±2.5 % with the light's azimuth
    let (records, findings) = run_outlined(Fault::None, usize::MAX, 80, 1, true, (0.0013, 0.4));
    assert!(gain_steps(&findings).next().is_none(), "{findings:?}");
    let late: Vec<&SweepRecord> = records.iter().filter(|r| r.light >= 70).collect();
    assert!(
        late.iter().any(|r| r.level_expected_pct.abs() > 1.0),
        "{late:?}"
    );
    // what is left is the per-light footprint noise of the session (0.5 % SD)
    let left: Vec<f64> = late
        .iter()
        .map(|r| r.level_pct - r.level_expected_pct)
        .collect();
    let rms = (left.iter().map(|v| v * v).sum::<f64>() / left.len() as f64).sqrt();
    assert!(rms < 0.8, "{left:?}");
    // a −3 % step inside that layer, after its pattern is learnt, is still a step
    let onset = 70 * 81 + 40;
    let (_, findings) = run_outlined(Fault::Step(0.97), onset, 76, 1, true, (0.0013, 0.4));
    let (at, _, _) = gain_steps(&findings)
        .next()
        .unwrap_or_else(|| panic!("no gain step in {findings:?}"));
    assert!(at.last_idx <= (74 * 81) as u64, "{at:?}");
}

#[test]
fn a_layer_takes_the_2nd_harmonics_phase_from_the_layer_below_until_it_can_fit_its_own() {
    // an oblong outline: the 2nd harmonic as large as the 4th, with the same phase in
    // every layer, clear in the θi = 60° layer (±0.9 % each) and swinging the level by
    // ±8 % at θi = 75°
    for seed in [1, 2, 3] {
        let (records, findings) =
            run_outlined(Fault::None, usize::MAX, 68, seed, true, (0.003, 1.0));
        // (the θi = 60° layer's own first lights, whose layer below lends nothing at this
        // outline, are not this test's subject)
        assert!(
            gain_steps(&findings).all(|(at, _, _)| at.last_idx < 57 * 81),
            "seed {seed}: {findings:?}"
        );
        // from the layer's 7th light to its 10th (its own 2nd harmonic), the prediction
        // follows the 2nd harmonic it cannot fit yet (the 4th alone is off by 5–8 % there)
        let early: Vec<f64> = records
            .iter()
            .filter(|r| (64..=66).contains(&r.light))
            .map(|r| r.level_pct - r.level_expected_pct)
            .collect();
        assert_eq!(early.len(), 3);
        assert!(
            early.iter().all(|e| e.abs() < 3.0),
            "seed {seed}: {early:?}"
        );
    }
    // the 2nd harmonic borrowed on the way does not blunt the layer's step test: a −3 %
    // step once the layer fits its own is caught (one inside the borrowing lights, on a
    // ±8 % swing, is not: the borrowed term's amplitude takes it up)
    let onset = 70 * 81 + 40;
    let (_, findings) = run_outlined(Fault::Step(0.97), onset, 76, 1, true, (0.003, 1.0));
    assert!(
        gain_steps(&findings).any(|(at, run, up)| {
            let i = at.last_idx as usize;
            i >= onset && i < onset + 5 * 81 && run.level_pct < 0.0 && !up
        }),
        "{findings:?}"
    );
}

/// A step in the second sweep of the θi = 45° layer (lights 19–36): too few of the layer's
/// own sweeps come before it for a scale of their own, so the layer is judged by the scale
/// of the layer below, and the step's sweeps do not set the scale they are judged by. (±5 %:
/// this session's 1 % capture noise gives levels several times the simulator's scatter;
/// judged by the layer's own first sweeps, the same steps raise nothing.)
#[test]
fn a_step_at_the_start_of_a_layer_is_judged_by_the_layer_below_and_caught() {
    let onset = 20 * 81 + 80;
    for (gain, sign) in [(0.95, -1.0), (1.05, 1.0)] {
        let (records, findings) = run(Fault::Step(gain), onset, 26, 1, true);
        let (step_at, run, _) = gain_steps(&findings)
            .next()
            .unwrap_or_else(|| panic!("{gain}: no gain step in {findings:?}"));
        let at = step_at.last_idx;
        assert!(at <= (onset + 300) as u64, "{gain}: at {at}");
        let pct = run.level_pct;
        assert!(sign * pct > 1.0, "{gain}: {pct}");
        // the layer's first sweeps with a level are tested, by the lent scale
        assert!(records.iter().any(|r| r.light == 20 && r.level_z.is_some()));
    }
}

#[test]
fn a_lamp_step_from_mid_run_is_a_gain_step() {
    let (_, findings) = run(Fault::Step(0.97), ONSET, LAST, 1, true);
    let (_, run, up) = gain_steps(&findings)
        .next()
        .unwrap_or_else(|| panic!("no gain step in {findings:?}"));
    // the level against the layer's pattern: the pattern, refitted on the sweeps after the
    // step, takes up part of it (the drift model fits the size from the pairs)
    let pct = run.level_pct;
    assert!((-4.0..-1.0).contains(&pct) && !up, "{pct}");
    assert!(slips(&findings).next().is_none(), "{findings:?}");
    // with probes the level test is left out: the same run finds no gain step
    let (records, findings) = self::run(Fault::Step(0.97), ONSET, LAST, 1, false);
    assert!(gain_steps(&findings).next().is_none(), "{findings:?}");
    assert!(records.iter().all(|r| r.level_z.is_none()));
}

/// The lamp-unstable findings: the sweep each came at and its scatter (%).
fn unstable(findings: &[SweepFinding]) -> Vec<(u64, f64)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::LampUnstable {
                at, scatter_pct, ..
            } => Some((at.last_idx, *scatter_pct)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_lamp_flickering_from_the_start_is_unstable_by_the_third_judged_sweep_and_steady_after() {
    // 3 % a capture from the first capture to the end of light sweep 30
    let until = 31 * 81;
    let (_, findings) = run(Fault::Flicker(0.03, until), 0, 48, 5, true);
    let raised = unstable(&findings);
    assert_eq!(raised.len(), 1, "{findings:?}");
    let (idx, pct) = raised[0];
    // judged from the 30° layer's fourth light on: its fifth ends at capture 971
    assert!(idx <= 1_000, "{idx}");
    assert!((2.0..6.0).contains(&pct), "{pct}");
    // steady again once the scatter is back under the limit / 1.5: the 45° layer's later
    // sweeps are judged against class effects that average its flickered captures, so here
    // at the 60° layer's third sweep (capture 3,239), whose classes hold none
    let steady: Vec<u64> = findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::LampSteady { at, .. } => Some(at.last_idx),
            _ => None,
        })
        .collect();
    assert_eq!(steady.len(), 1, "{findings:?}");
    assert!(
        steady[0] > until as u64 && steady[0] < until as u64 + 10 * 81,
        "{steady:?}"
    );
    // with probes the probes watch the lamp: the sweeps say nothing of it
    let (_, with_probes) = run(Fault::Flicker(0.03, until), 0, 48, 5, false);
    assert!(unstable(&with_probes).is_empty());
}

#[test]
fn a_steady_lamps_scatter_stays_under_the_limit_in_every_judged_layer() {
    let (records, findings) = run(Fault::None, usize::MAX, 56, 3, true);
    assert!(unstable(&findings).is_empty(), "{findings:?}");
    let judged: Vec<f64> = records
        .iter()
        .filter(|r| r.residual_sd > 0.0 && r.light < 57)
        .map(|r| 100.0 * r.residual_sd)
        .collect();
    assert!(judged.len() > 30, "{}", judged.len());
    assert!(judged.iter().all(|&v| v < 2.0), "{judged:?}");
}

/// The slips refuted by re-captures: the sweep, the joint (1-based) and the re-captures' offset.
fn refuted(findings: &[SweepFinding]) -> Vec<(u64, usize, f64)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::SlipRefuted {
                at, joint, reading, ..
            } => Some((at.last_idx, *joint, reading.offset_deg)),
            _ => None,
        })
        .collect()
}

/// A pattern that follows the pose as a slip's would, from a light on (a stationary effect of
/// the geometry), names a joint from the sweeps alone; on a rig that takes probes the
/// re-captures of two earlier poses refute it, and nothing is raised.
#[test]
fn a_stationary_pattern_that_looks_like_a_slip_is_refuted_by_re_captures() {
    let pattern = Fault::LightPattern(1, 2.0, 47);
    let (_, _, alone) = simulate(pattern, usize::MAX, LAST, 1, false, (0.0, 0.0));
    assert!(
        slips(&alone).any(|(_, s)| s.joint == 2 && s.recapture == Recapture::NoProbes),
        "{alone:?}"
    );
    let (m, _, checked) =
        simulate_with(pattern, usize::MAX, LAST, 1, false, (0.0, 0.0), Some(0.014));
    assert_eq!(slips(&checked).count(), 0, "{checked:?}");
    let r = refuted(&checked);
    assert!(
        !r.is_empty() && r.len() <= recapture::MAX_REFUTED_PER_LAYER,
        "{r:?}"
    );
    for (_, joint, offset) in &r {
        assert_eq!(*joint, 2);
        assert!(offset.abs() < 1.0, "{r:?}");
    }
    assert!(!m.recapture_pending());
}

/// A real slip moves the re-captured poses too: the slip is named, confirmed, with the
/// re-captures' offset near the slip's.
#[test]
fn a_real_slip_is_confirmed_by_its_re_captures() {
    for (joint, deg) in [(1usize, 2.0), (1, -2.0), (0, 2.0)] {
        let (_, _, findings) = simulate_with(
            Fault::Joint(joint, deg),
            ONSET,
            LAST,
            1,
            false,
            (0.0, 0.0),
            Some(0.014),
        );
        let named: Vec<_> = slips(&findings).collect();
        assert_eq!(named.len(), 1, "joint {joint} {deg}: {findings:?}");
        let s = named[0].1;
        assert_eq!(s.joint, joint + 1);
        match &s.recapture {
            Recapture::Confirmed(r) => {
                assert!(
                    r.offset_deg * deg > 0.0 && (r.offset_deg - deg).abs() < 1.0,
                    "{r:?}"
                );
            }
            other => panic!("joint {joint} {deg}: {other:?}"),
        }
        assert!(refuted(&findings).is_empty(), "{findings:?}");
    }
}

/// Re-captures that never come (a rig that stopped taking probes) leave the slip named from
/// the sweeps alone after `RECAPTURE_WAIT_CAPTURES` regular captures, and so does the run's end.
#[test]
fn a_slip_whose_re_captures_never_come_is_named_unconfirmed() {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig, plan.direction_count());
    m.set_recapture(Some(RecaptureNoise {
        capture_sd: 0.014 / std::f64::consts::SQRT_2,
        y_ref: None,
    }));
    let x = JointCrossing {
        joint: 1,
        statistic: 9.0,
        mean: 1.0,
        mean_se: 0.2,
        sweeps: 2,
        since: 100,
        estimate_sweeps: 2,
        run_mean: 1.0,
        attributed_level: None,
    };
    let at = SweepAt {
        light: 3,
        last_idx: 200,
        last_t: 1400.0,
        layer_mdeg: 30_000,
    };
    // no earlier sweep to re-capture: named at once
    assert_eq!(m.hold_for_recapture(at, &x, &[]), recapture::Hold::NotAsked);
    // held by hand: the wait runs out
    m.pending = Some(recapture::PendingSlip::for_test(at, x, &[5, 9]));
    assert_eq!(m.recapture_wanted(), Some(vec![5, 9]));
    m.handle_recapture_asked();
    assert_eq!(m.recapture_wanted(), None);
    assert!(m.awaits_recapture(5) && !m.awaits_recapture(6));
    for k in 1..recapture::RECAPTURE_WAIT_CAPTURES {
        assert!(m.handle_regular_capture().findings.is_empty(), "{k}");
    }
    let o = m.handle_regular_capture();
    let named: Vec<_> = slips(&o.findings).collect();
    assert_eq!(named.len(), 1);
    assert_eq!(
        named[0].1.recapture,
        Recapture::Unanswered {
            entries: vec![5, 9]
        }
    );
    assert!(!m.recapture_pending());
    // at the run's end
    m.pending = Some(recapture::PendingSlip::for_test(at, x, &[5, 9]));
    let o = m.handle_end();
    assert_eq!(slips(&o.findings).count(), 1);
    assert!(m.handle_end().findings.is_empty());
}

/// Once the wagon's lag is named, a slip's re-captures are read without it: each moved by the
/// way the wagon came to it (its original too when taken after the lag began), which is not the
/// joint's. For-test sets: originals at capture 0 approached from below, 4 %/° of wagon, the
/// joint's sensitivities ±2.5 %/°, the rising pose approached from below and the falling one from
/// above.
#[test]
fn a_named_lag_is_read_out_of_a_slips_re_captures() {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(Default::default()).unwrap();
    let x = JointCrossing {
        joint: 0,
        statistic: 9.0,
        mean: -1.0,
        mean_se: 0.2,
        sweeps: 2,
        since: 1000,
        estimate_sweeps: 2,
        run_mean: -1.0,
        attributed_level: None,
    };
    let at = SweepAt {
        light: 30,
        last_idx: 2000,
        last_t: 14_000.0,
        layer_mdeg: 45_000,
    };
    // the lag alone: −b·s·dir of each re-capture, the originals taken before it began
    let lag = 1.0;
    let answer = |m: &mut SweepMonitor| {
        m.pending = Some(recapture::PendingSlip::for_test(at, x, &[5, 9]));
        m.handle_recapture_asked();
        assert!(m
            .handle_recapture(5, (-lag * 0.04f64).exp(), 1.0)
            .findings
            .is_empty());
        m.handle_recapture(9, (lag * 0.04f64).exp(), -1.0).findings
    };
    let new = || {
        let mut m = SweepMonitor::new(SweepSpec::default(), rig.clone(), plan.direction_count());
        m.set_recapture(Some(RecaptureNoise {
            capture_sd: 0.004 / std::f64::consts::SQRT_2,
            y_ref: None,
        }));
        m
    };
    // not known: the lag reads as −1.6° of the joint and confirms the slip
    let findings = answer(&mut new());
    assert_eq!(slips(&findings).count(), 1, "{findings:?}");
    // known: nothing of the joint is left
    let mut m = new();
    m.named_lag = Some(recapture::NamedLag {
        backlash_deg: lag,
        from_idx: 500,
    });
    let findings = answer(&mut m);
    assert_eq!(slips(&findings).count(), 0, "{findings:?}");
    assert_eq!(refuted(&findings).len(), 1, "{findings:?}");
}

/// On a probe-taking rig a lag of the wagon from mid-run is named as the wagon's lag with its
/// size, once, and never as an offset, although the re-captured pair reads a lag as an offset of
/// either sign (each pose's lag follows the way the wagon came to it): on this synthetic session
/// the sweeps' lag test crosses before the pair's departure is attributed (on the simulated rig
/// it does not always: BENCHMARKS.md).
#[test]
fn a_wagon_lag_on_a_probe_taking_rig_is_named_as_the_lag() {
    for lag in [1.0, 0.8] {
        let (_, _, findings) = simulate_with(
            Fault::WagonBacklash(lag),
            ONSET,
            LAST + 4,
            1,
            false,
            (0.0, 0.0),
            Some(0.004),
        );
        assert!(wagon_offsets(&findings).is_empty(), "{lag}: {findings:?}");
        let named = wagon(&findings);
        assert_eq!(named.len(), 1, "{lag}: {findings:?}");
        let (at, w) = named[0];
        assert!((at.last_idx as usize) < ONSET + 600, "{at:?}");
        assert!((w.backlash_deg / lag - 1.0).abs() <= 0.3, "{w:?}");
        assert!(
            slips(&findings).all(|(s, _)| s.last_idx > at.last_idx),
            "{findings:?}"
        );
    }
}

/// A pattern that re-captures cannot check at its named size (here: re-captures so noisy that
/// no set of earlier poses would show it) is not named on a rig that takes probes: one
/// `SlipUnverifiable` for its layer, with the offset the re-captures could check, and nothing
/// is asked.
#[test]
fn a_pattern_too_small_for_the_re_captures_to_check_is_not_named() {
    let (m, _, findings) = simulate_with(
        Fault::LightPattern(1, 2.0, 47),
        usize::MAX,
        LAST,
        1,
        false,
        (0.0, 0.0),
        Some(0.2),
    );
    assert_eq!(slips(&findings).count(), 0, "{findings:?}");
    assert!(refuted(&findings).is_empty(), "{findings:?}");
    let unverifiable: Vec<_> = findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::SlipUnverifiable {
                at,
                joint,
                offset_deg,
                checkable_deg,
            } => Some((at.layer_mdeg, *joint, *offset_deg, *checkable_deg)),
            _ => None,
        })
        .collect();
    assert!(!unverifiable.is_empty(), "{findings:?}");
    let mut layers: Vec<i64> = unverifiable.iter().map(|u| u.0).collect();
    layers.dedup();
    assert_eq!(
        layers.len(),
        unverifiable.len(),
        "once a layer: {unverifiable:?}"
    );
    for (_, joint, offset, checkable) in &unverifiable {
        assert_eq!(*joint, 2);
        assert!(
            checkable.is_finite() && *checkable > offset.abs(),
            "{unverifiable:?}"
        );
    }
    assert!(!m.recapture_pending());
}

/// A real slip that four re-captures a side would not show at the named size asks for more
/// (up to eight a side) and is confirmed by them.
#[test]
fn a_real_slip_that_four_re_captures_a_side_cannot_show_asks_for_more() {
    let (_, _, findings) = simulate_with(
        Fault::Joint(1, 2.0),
        ONSET,
        LAST,
        1,
        false,
        (0.0, 0.0),
        Some(0.08),
    );
    let named: Vec<_> = slips(&findings).collect();
    assert_eq!(named.len(), 1, "{findings:?}");
    match &named[0].1.recapture {
        Recapture::Confirmed(r) => {
            assert!(r.entries.len() > 8, "{r:?}");
            assert!(r.offset_deg > 1.0 && r.offset_deg < 3.0, "{r:?}");
        }
        other => panic!("{other:?}"),
    }
}

/// The first capture at which the simulated probes' `lamp-unstable` stands over a flicker.
const PROBES_SEE_FLICKER_AT: usize = 607;

/// While the probes' `lamp-unstable` stands every capture has a gain of its own, and the
/// sweeps do not judge the pose: their joint fits are recorded untested and no positioning
/// finding is made; once the lamp is steady again they are judged again.
#[test]
fn the_pose_is_not_judged_from_the_sweeps_while_the_probes_see_the_lamp_unstable() {
    let until = 41 * 81;
    let (records, findings) = run(Fault::Flicker(0.03, until), 0, 56, 5, false);
    let (from, to) = (PROBES_SEE_FLICKER_AT as u64, until as u64);
    let between = |r: &&SweepRecord| r.idx >= from + 81 && r.idx < to;
    assert!(records.iter().filter(between).count() > 20);
    for r in records.iter().filter(between) {
        assert!(!r.joints.is_empty(), "the fits are recorded: {r:?}");
        assert!(r.joints.iter().all(|j| j.z.is_none()), "{r:?}");
    }
    assert!(
        records
            .iter()
            .any(|r| r.idx > to && r.joints.iter().any(|j| j.z.is_some())),
        "judged again once steady"
    );
    for f in &findings {
        let at = f.at().last_idx;
        assert!(
            at < from + 81
                || at > to
                || !matches!(
                    f,
                    SweepFinding::JointSlip { .. }
                        | SweepFinding::WagonBacklash { .. }
                        | SweepFinding::SlipUnverifiable { .. }
                ),
            "{f:?}"
        );
    }
}

/// The probes' `lamp-unstable` suspends the sweeps' pose tests too, and restarts their CUSUMs
/// when raised.
#[test]
fn the_probes_lamp_unstable_suspends_the_sweeps_pose_tests() {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig, plan.direction_count());
    m.joint_cusum[1].up = 2.5;
    m.wagon_cusum.up = 1.5;
    assert!(!m.lamp_unstable());
    m.set_probes_unstable(true);
    assert!(m.lamp_unstable());
    assert_eq!((m.joint_cusum[1].up, m.wagon_cusum.up), (0.0, 0.0));
    m.joint_cusum[0].up = 1.0;
    // still standing: nothing restarts
    m.set_probes_unstable(true);
    assert_eq!(m.joint_cusum[0].up, 1.0);
    m.set_probes_unstable(false);
    assert!(!m.lamp_unstable());
}

/// The `SlipUnresolved` findings: the layer (millidegrees), the joint and the layer change.
fn unresolved(findings: &[SweepFinding]) -> Vec<(i64, usize, LayerChange)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::SlipUnresolved {
                at, joint, change, ..
            } => Some((at.layer_mdeg, *joint, *change)),
            _ => None,
        })
        .collect()
}

/// The first light of the θi = 75° layer.
const LAYER_75: usize = 57;

/// A pattern that follows the pose as a slip's would, from the θi = 75° layer's tenth light on,
/// is a change within the layer: without re-captures it is named as the slip it looks like
/// (the sweeps alone cannot do better; re-captures refute it). A real slip at the layer's
/// first capture is confirmed by re-captures and named.
#[test]
fn a_change_within_a_layer_is_named_and_re_captures_confirm_a_slip_at_its_start() {
    let (_, _, mid) = simulate(
        Fault::LightPattern(1, 2.0, LAYER_75 + 9),
        usize::MAX,
        LAYER_75 + 16,
        1,
        false,
        (0.0, 0.0),
    );
    let named: Vec<_> = slips(&mid).collect();
    assert_eq!(named.len(), 1, "{mid:?}");
    assert_eq!(named[0].1.joint, 2);
    assert!(unresolved(&mid).is_empty(), "{mid:?}");

    let (_, _, checked) = simulate_with(
        Fault::Joint(1, 2.0),
        LAYER_75 * 81,
        LAYER_75 + 8,
        1,
        false,
        (0.0, 0.0),
        Some(0.014),
    );
    let named: Vec<_> = slips(&checked).collect();
    assert_eq!(named.len(), 1, "{checked:?}");
    assert_eq!(named[0].1.joint, 2);
    assert!(
        matches!(named[0].1.recapture, Recapture::Confirmed(_)),
        "{:?}",
        named[0].1
    );
    assert!(unresolved(&checked).is_empty(), "{checked:?}");
}

/// The `StepUnresolved` findings: the sweep each came at, its run and the layer below.
fn steps_unresolved(findings: &[SweepFinding]) -> Vec<(&SweepAt, &LevelRun, &PatternBelow)> {
    findings
        .iter()
        .filter_map(|f| match f {
            SweepFinding::StepUnresolved { at, run, below, .. } => Some((at, run, below)),
            _ => None,
        })
        .collect()
}

/// A holder's jaw shading the sample on one side of the turn: up to −3 % at θi = 75°, −1.4 %
/// at 60°, a shape the layers' harmonics do not hold (odd harmonics among them).
const SHADOW: f64 = 0.006;

#[test]
fn a_shadow_that_the_layers_harmonics_miss_is_unresolved_where_it_grows_never_a_step() {
    for seed in [1, 2, 3] {
        let (_, findings) = run(Fault::Shadow(SHADOW, None), usize::MAX, 80, seed, true);
        assert!(
            gain_steps(&findings).next().is_none(),
            "seed {seed}: {findings:?}"
        );
        let unresolved = steps_unresolved(&findings);
        // where the shadow grows past the tolerance: the θi = 75° layer, at the shadow's side
        assert!(
            unresolved
                .iter()
                .any(|(at, _, _)| at.layer_mdeg == 75_000 && (63..=75).contains(&at.light)),
            "seed {seed}: {findings:?}"
        );
        for (_, run, below) in unresolved {
            // the layer below departed the same way, clearly, and grown reaches the run
            let sign = run.level_pct.signum();
            assert!(
                sign * below.departure >= PATTERN_BELOW_Z * below.se,
                "{below:?}"
            );
            assert!(sign * below.departure * below.growth * 100.0 >= sign * run.level_pct);
        }
    }
}

#[test]
fn a_lamp_step_under_the_shadow_is_raised_once_the_level_stays_off_past_it() {
    // −3 % from inside the θi = 75° layer's shaded side: first as much the shadow's as the
    // lamp's, then raised, before the run ends, once the level stays off where the layer
    // below shows no shadow
    for onset in [66 * 81 + 40, 68 * 81 + 40] {
        let (_, findings) = run(Fault::Shadow(SHADOW, Some(0.97)), onset, 80, 1, true);
        let (step_at, step_run, up) = gain_steps(&findings)
            .find(|(at, _, _)| at.last_idx as usize >= onset)
            .unwrap_or_else(|| panic!("{onset}: no gain step in {findings:?}"));
        assert!(!up && step_run.level_pct < -1.0, "{step_run:?}");
        let unresolved: Vec<u64> = steps_unresolved(&findings)
            .iter()
            .map(|(at, _, _)| at.last_idx)
            .filter(|&i| i as usize >= onset)
            .collect();
        assert!(
            unresolved.first().is_some_and(|&i| i < step_at.last_idx),
            "{onset}: {findings:?}"
        );
    }
    // before the shaded side (φi < 90°), and without the shadow, the same step is raised
    // where it is, with no advisory
    for (fault, onset) in [
        (Fault::Shadow(SHADOW, Some(0.97)), 61 * 81 + 40),
        (Fault::Step(0.97), 66 * 81 + 40),
    ] {
        let (_, findings) = run(fault, onset, 80, 1, true);
        let (at, _, _) = gain_steps(&findings)
            .next()
            .unwrap_or_else(|| panic!("no gain step in {findings:?}"));
        assert!(
            (at.last_idx as usize) < onset + 4 * 81,
            "{at:?} {findings:?}"
        );
        assert!(steps_unresolved(&findings).is_empty(), "{findings:?}");
    }
}
