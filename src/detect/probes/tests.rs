use super::*;

fn run(rate_pct_h: f64, step: Option<(f64, f64)>, noise: f64, seed: u64) -> Vec<(f64, DriftEvent)> {
    let mut s = crate::fixtures::Lcg(seed);
    let mut g = move || (s.uniform() - 0.5) * 2.0 * noise;
    let gain = |t: f64| {
        let mut v = (1.0 - rate_pct_h / 100.0 * t).max(1e-6);
        if let Some((t0, f)) = step {
            if t >= t0 {
                v *= 1.0 + f;
            }
        }
        v
    };
    let mut p = ProbeDrift::new(ProbeSpec {
        every: crate::detect::probes::ProbeEvery::Captures(100),
        ..ProbeSpec::default()
    });
    let y0 = 40.0 * gain(0.1) * (1.0 + g());
    let mut ev = Vec::new();
    // a probe every 100 captures of 7 s: every 0.194 h over 12.75 h
    let mut t = 0.3;
    while t < 12.75 {
        for e in p.add(
            (t * 1000.0) as u64,
            0.1,
            y0,
            t,
            40.0 * gain(t) * (1.0 + g()),
        ) {
            ev.push((t, e));
        }
        t += 100.0 * 7.0 / 3600.0;
    }
    ev
}

#[test]
fn a_flicker_that_starts_late_in_a_long_steady_segment_is_found() {
    let mut p = ProbeDrift::new(ProbeSpec {
        every: crate::detect::probes::ProbeEvery::Captures(100),
        ..ProbeSpec::default()
    });
    let mut rng = crate::measure::stats::SplitMix64(5);
    let mut found = None;
    // 40 steady probes (0.1 %), then 2 % flicker from probe 40 on
    for k in 0..60u64 {
        let sd = if k < 40 { 0.001 } else { 0.02 };
        let y = 40.0 * (1.0 + sd * rng.gauss());
        for e in p.add(k, 0.0, 40.0, 0.2 + 0.2 * k as f64, y) {
            if let DriftEvent::Unstable { from_idx, .. } = e {
                found.get_or_insert((k, from_idx));
            }
        }
    }
    let (k, from_idx) = found.expect("flicker found");
    assert!((44..=50).contains(&k), "{k}");
    assert!(from_idx >= 36 && from_idx <= k, "{from_idx}");
}

#[test]
fn a_flickering_lamp_is_unstable_and_a_steady_one_or_a_step_is_not() {
    let unstable = |ev: &[(f64, DriftEvent)]| {
        ev.iter()
            .filter(|(_, e)| matches!(e, DriftEvent::Unstable { .. }))
            .count()
    };
    // uniform noise of ± 0.3 % (0.17 % SD) against a 0.3 % design: quiet, with a decay or a
    // step as well
    for seed in 1..=20 {
        assert_eq!(unstable(&run(0.0, None, 0.003, seed)), 0, "seed {seed}");
        assert_eq!(unstable(&run(1.0, None, 0.003, seed)), 0, "seed {seed}");
        assert_eq!(
            unstable(&run(0.0, Some((6.0, -0.03)), 0.003, seed)),
            0,
            "seed {seed}"
        );
    }
    // ± 2 % (1.2 % SD, four times the design): unstable once, with the measured scatter
    for seed in 1..=5 {
        let ev = run(0.0, None, 0.02, seed);
        assert_eq!(unstable(&ev), 1, "seed {seed}: {ev:?}");
        let (t, e) = ev
            .iter()
            .find(|(_, e)| matches!(e, DriftEvent::Unstable { .. }))
            .unwrap();
        let DriftEvent::Unstable {
            scatter,
            design,
            probes,
            ..
        } = *e
        else {
            unreachable!()
        };
        assert!(scatter > 2.0 * design && scatter < 0.03, "{scatter}");
        assert_eq!(probes, UNSTABLE_WINDOW);
        // found within the first 3.5 h of probes every 100 captures (at the first full window,
        // 1.7 h, in 4 of these 5 runs: both scales must agree, and one of them can be low in a
        // window by chance)
        assert!(*t < 3.5, "{t}");
    }
}

#[test]
fn decay_of_1_percent_per_hour_is_found_early() {
    let ev = run(1.0, None, 0.002, 1);
    let (t, e) = ev
        .iter()
        .find(|(_, e)| matches!(e, DriftEvent::RateSignificant(_)))
        .unwrap();
    assert!(*t < 2.0, "alarm at {t} h");
    if let DriftEvent::RateSignificant(est) = e {
        assert!(est.rate_pct_per_h < -0.5, "{est:?}");
    }
}

#[test]
fn no_alarm_without_drift() {
    for seed in 0..20 {
        assert!(run(0.0, None, 0.002, seed).is_empty(), "seed {seed}");
    }
}

/// One sweep of a lamp at `light` over the UBO directions, on a BRDF `f(ωi, ωo)`.
fn sweep(
    light: usize,
    f: impl Fn(&Vec3, &Vec3) -> f64,
) -> (Vec<PoseSample>, Vec<crate::measure::plan::PlanDirection>) {
    let plan = crate::measure::plan::SamplingPlan::ubo();
    let dirs = plan.directions().to_vec();
    let wi = dirs[light].spherical().to_vector();
    let samples = dirs
        .iter()
        .enumerate()
        .map(|(c, d)| {
            let wo = d.spherical().to_vector();
            PoseSample {
                entry: light * dirs.len() + c,
                light,
                camera: c,
                omega_i: wi,
                omega_o: wo,
                y: f(&wi, &wo) * wi.z,
            }
        })
        .collect();
    (samples, dirs)
}

#[test]
fn a_lambertian_sample_is_probed_off_grazing_and_off_the_mirror() {
    let (s, _) = sweep(0, |_, _| 0.3);
    let p = choose_probe_pose(&s).unwrap();
    assert_eq!(p.theta_i_deg, 0.0);
    assert!(
        p.theta_o_deg <= 45.0 + 1e-9 && p.specular_distance_deg >= 25.0,
        "{p:?}"
    );
    // every qualifying capture is equally bright and flat: the first one wins
    assert!(p.sensitivity_pct_per_deg < 1e-9, "{p:?}");
    assert_eq!(p, choose_probe_pose(&s).unwrap(), "deterministic");
}

#[test]
fn a_glossy_sample_is_probed_where_it_is_bright_but_not_on_the_lobe_flank() {
    // a smooth base, brighter towards the normal, and a narrow lobe about the mirror
    // direction of the pole light: the θo = 30° captures are the brightest that qualify, but
    // their θo = 15° neighbours are on the lobe
    let brdf = |wi: &Vec3, wo: &Vec3| {
        let a = angle_between(&mirror(wi), wo).to_degrees();
        0.2 * (1.0 + 0.3 * wo.z) + 50.0 * (-(a / 8.0).powi(2)).exp()
    };
    let (s, _) = sweep(0, brdf);
    let p = choose_probe_pose(&s).unwrap();
    assert!((p.theta_o_deg - 45.0).abs() < 1e-9, "{p:?}");
    assert!(
        p.sensitivity_pct_per_deg <= PROBE_QUIET_PCT_PER_DEG,
        "{p:?}"
    );
    let flank: Vec<_> = s
        .iter()
        .filter(|x| (x.omega_o.z.acos().to_degrees() - 30.0).abs() < 1e-6)
        .collect();
    assert_eq!(flank.len(), 12);
    assert!(
        flank.iter().all(|x| x.y > p.luminance),
        "the flank is brighter, and refused"
    );
}

#[test]
fn nothing_qualifies_without_neighbours_or_off_grazing_captures() {
    let (s, _) = sweep(0, |_, _| 0.3);
    assert!(
        choose_probe_pose(&s[..2]).is_none(),
        "too few to measure a slope"
    );
    // a lamp at 75° is grazing
    let plan = crate::measure::plan::SamplingPlan::ubo();
    let grazing = plan
        .directions()
        .iter()
        .position(|d| d.theta_deg == 75.0)
        .unwrap();
    let (s, _) = sweep(grazing, |_, _| 0.3);
    assert!(choose_probe_pose(&s).is_none());
    let mut bad = sweep(0, |_, _| 0.3).0;
    for x in &mut bad {
        x.y = f64::NAN;
    }
    assert!(choose_probe_pose(&bad).is_none());
}

#[test]
fn a_three_percent_step_is_caught_at_the_next_probe() {
    let ev = run(0.0, Some((6.4, -0.03)), 0.002, 3);
    assert_eq!(ev.len(), 1, "{ev:?}");
    let (t, e) = &ev[0];
    assert!(*t >= 6.4 && *t < 6.4 + 0.2, "{t}");
    assert!(matches!(e, DriftEvent::Step { direction: -1, .. }));
}

/// A level shift smaller than a step alarm (a slipped wagon moving a probe pose whose luminance
/// turns with the view by 0.9 %) is one change, not scatter: no `lamp-unstable`. The robust scale
/// of the residuals about the segment's line alone reaches 0.5–0.7 % over the windows that
/// straddle it (beyond twice the 0.3 % design in about half of these seeds).
#[test]
fn a_level_shift_below_a_step_is_not_instability() {
    for seed in 1..=20u64 {
        let mut p = ProbeDrift::new(ProbeSpec {
            every: crate::detect::probes::ProbeEvery::Captures(100),
            ..ProbeSpec::default()
        });
        let mut rng = crate::measure::stats::SplitMix64(seed);
        let mut events = Vec::new();
        for k in 0..40u64 {
            let level = if k < 20 { 0.0 } else { -0.009 };
            let y = 40.0 * (level + 0.001 * rng.gauss()).exp();
            events.extend(p.add(k, 0.0, 40.0, 0.2 + 0.2 * k as f64, y));
        }
        assert!(
            !events
                .iter()
                .any(|e| matches!(e, DriftEvent::Unstable { .. })),
            "seed {seed}: {events:?}"
        );
        // the scatter measured is the noise's, not the shift's
        let scatter = p.scatter().unwrap();
        assert!(scatter < 0.003, "seed {seed}: {scatter}");
    }
}

/// A flicker is not a run of steps: a segment whose residual SD already exceeds what
/// `lamp-unstable` allows raises no step however far a probe departs (its few residuals can
/// under-scale the flicker by chance), while a steady lamp's step is still caught.
#[test]
fn a_flickering_segment_raises_no_step() {
    let steps = |ev: &[(f64, DriftEvent)]| {
        ev.iter()
            .filter(|(_, e)| matches!(e, DriftEvent::Step { .. }))
            .count()
    };
    // ± 6 % uniform (3.5 % SD, over ten times the design): no step in 40 runs
    for seed in 1..=40 {
        let ev = run(0.0, None, 0.06, seed);
        assert_eq!(steps(&ev), 0, "seed {seed}: {ev:?}");
    }
    // the spec's own figures: a probe 10 % off a segment scattering by 1 % is no step
    let mut p = ProbeDrift::new(ProbeSpec::default());
    let mut rng = crate::measure::stats::SplitMix64(3);
    for k in 0..6u64 {
        let y = 40.0 * (1.0 + 0.01 * rng.gauss());
        assert!(p.add(k, 0.0, 40.0, 0.2 + 0.2 * k as f64, y).is_empty());
    }
    let ev = p.add(6, 0.0, 40.0, 1.4, 44.0);
    assert!(
        !ev.iter().any(|e| matches!(e, DriftEvent::Step { .. })),
        "{ev:?}"
    );
    // a steady lamp's −3 % step is caught
    let ev = run(0.0, Some((6.0, -0.03)), 0.003, 1);
    assert_eq!(steps(&ev), 1, "{ev:?}");
}
