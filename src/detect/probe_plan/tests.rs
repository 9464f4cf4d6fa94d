use super::*;

fn ubo(scatter_pct: f64) -> ProbeSession {
    ProbeSession {
        captures: 6561,
        seconds_per_capture: 7.0,
        seconds_per_probe: 7.0,
        anchor: 11,
        probes_from: 0,
        scatter_pct,
        colour: None,
    }
}

/// The UBO session whose probes also feed the colour check (a 3000 K lamp, the default
/// tolerance and z), with `colour_pct` chromaticity scatter.
fn ubo_colour(scatter_pct: f64, colour_pct: f64) -> ProbeSession {
    ProbeSession {
        colour: Some(ColourProbes {
            lamp_cct_k: 3000.0,
            tolerance_k_per_h: 5.0,
            z: 4.0,
            scatter_pct: colour_pct,
        }),
        ..ubo(scatter_pct)
    }
}

/// The design for the UBO session at this scatter, with the default settings and target.
fn default_design(scatter_pct: f64) -> ProbePlan {
    design(
        &ubo(scatter_pct),
        &ProbeSpec::default(),
        &DetectionTarget::default(),
    )
    .unwrap()
}

#[test]
fn a_quiet_probe_pose_gets_a_sparse_cadence_that_meets_the_default_target() {
    let plan = default_design(0.3);
    let ProbePlan::Recommended { cadence, tried } = plan else {
        panic!("{plan:?}");
    };
    // a step must be seen within 300 captures, so a probe at least every 300
    assert!(cadence.every <= 300, "{cadence:?}");
    assert!(cadence.false_alarms_per_run <= 0.05);
    assert!(cadence.decay_in_time >= 0.9 && cadence.step_in_time >= 0.9);
    // the sparsest that meets: every sparser candidate fails
    assert!(tried
        .iter()
        .take_while(|c| c.every > cadence.every)
        .all(|c| !c.meets));
    // what it costs: a probe per `every` captures of the same length
    assert!(
        (cadence.overhead_pct - 100.0 / cadence.every as f64).abs() < 0.1,
        "{cadence:?}"
    );
}

#[test]
fn a_noisy_probe_pose_cannot_meet_the_target_and_says_why() {
    let plan = default_design(2.0);
    let ProbePlan::Unreachable { reason, tried } = plan else {
        panic!("{plan:?}");
    };
    assert_eq!(tried.len(), CADENCES.len());
    assert!(reason.contains("no cadence"), "{reason}");
    assert!(reason.contains("step"), "{reason}");
    assert!(reason.contains("scatter (2 %)"), "{reason}");
}

#[test]
fn the_design_is_deterministic() {
    let a = cadence_figures(
        &ubo(0.3),
        &ProbeSpec::default(),
        &DetectionTarget::default(),
        100,
    );
    let b = cadence_figures(
        &ubo(0.3),
        &ProbeSpec::default(),
        &DetectionTarget::default(),
        100,
    );
    assert_eq!(a, b);
}

#[test]
fn denser_probes_flag_a_decay_earlier() {
    let t = DetectionTarget::default();
    let sparse = cadence_figures(&ubo(0.3), &ProbeSpec::default(), &t, 300);
    let dense = cadence_figures(&ubo(0.3), &ProbeSpec::default(), &t, 50);
    assert!(
        dense.decay_median_fraction.unwrap() < sparse.decay_median_fraction.unwrap(),
        "{dense:?} {sparse:?}"
    );
}

#[test]
fn the_colour_target_asks_for_denser_probes_and_names_itself_when_missed() {
    let spec = ProbeSpec::default();
    let t = DetectionTarget::default();
    // a probe every 200 meets the luminance target (the design without colour recommends
    // it) ...
    let luminance = cadence_figures(&ubo(0.3), &spec, &t, 200);
    assert!(
        luminance.meets && luminance.colour_in_time.is_none(),
        "{luminance:?}"
    );
    // ... but −20 K/h before 15 % of the run is judged from the colour fits' 4th probe on,
    // at 12 % of the run at best: most runs miss it
    let sparse = cadence_figures(&ubo_colour(0.3, 0.3), &spec, &t, 200);
    assert!(!sparse.meets, "{sparse:?}");
    assert!(sparse.colour_in_time.unwrap() < 0.5, "{sparse:?}");
    assert_eq!(
        (sparse.decay_in_time, sparse.step_in_time),
        (luminance.decay_in_time, luminance.step_in_time)
    );
    let dense = cadence_figures(&ubo_colour(0.3, 0.3), &spec, &t, 75);
    assert!(dense.meets, "{dense:?}");
    assert!(dense.colour_in_time.unwrap() >= 0.9);
    assert!(dense.colour_median_fraction.unwrap() <= 0.15);
    // the colour fits' scale floor keeps fault-free runs quiet: the colour check adds no
    // false alarm to the luminance checks' at this cadence
    let quiet = cadence_figures(&ubo(0.3), &spec, &t, 75);
    assert_eq!(dense.false_alarms_per_run, quiet.false_alarms_per_run);
    // the reason names the colour target when it is the part that fails
    let why = unreachable_reason(&ubo_colour(0.3, 0.3), &spec, &t, &[sparse]);
    assert!(why.contains("-20 K/h colour drift"), "{why}");
    assert!(
        !why.contains("step is flagged") && !why.contains("decay"),
        "{why}"
    );
    // no colour target: the same as no colour check
    let none = DetectionTarget {
        colour_k_per_h: 0.0,
        ..t
    };
    assert_eq!(
        cadence_figures(&ubo_colour(0.3, 0.3), &spec, &none, 200),
        cadence_figures(&ubo(0.3), &spec, &none, 200)
    );
}

#[test]
fn bad_inputs_are_refused_with_the_field() {
    let t = DetectionTarget::default();
    let spec = ProbeSpec::default();
    let mut s = ubo(0.0);
    assert!(matches!(
        design(&s, &spec, &t),
        Err(ProbePlanError::Invalid {
            field: "scatter_pct",
            ..
        })
    ));
    s.scatter_pct = f64::NAN;
    assert!(design(&s, &spec, &t).is_err());
    s = ubo(0.3);
    s.anchor = 7000;
    assert!(matches!(
        design(&s, &spec, &t),
        Err(ProbePlanError::Invalid {
            field: "probes.entry",
            ..
        })
    ));
    let bad = DetectionTarget { power: 0.0, ..t };
    assert!(matches!(
        design(&ubo(0.3), &spec, &bad),
        Err(ProbePlanError::Invalid { field: "power", .. })
    ));
    let bad = DetectionTarget {
        colour_k_per_h: f64::NAN,
        ..t
    };
    assert!(matches!(
        design(&ubo(0.3), &spec, &bad),
        Err(ProbePlanError::Invalid {
            field: "colour_k_per_h",
            ..
        })
    ));
    assert!(matches!(
        design(&ubo_colour(0.3, -1.0), &spec, &t),
        Err(ProbePlanError::Invalid {
            field: "colour.scatter_pct",
            ..
        })
    ));
}
