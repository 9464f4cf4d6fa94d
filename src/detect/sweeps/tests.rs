use super::joints::change_point;
use super::level::{HELD_MAX, PRIOR_MIN_SWEEPS, PRIOR_SAFETY};
use super::model::{amplitude_t, pattern_fit, ATTRIBUTION_Z};
use super::*;

#[test]
fn the_change_point_starts_the_shifted_tail() {
    // a CUSUM run that began on two small excursions before the shift
    assert_eq!(change_point(&[0.2, 0.05, 0.7, 0.9], 1.0), Some(2));
    assert_eq!(change_point(&[-0.2, -0.05, -0.7, -0.9], -1.0), Some(2));
    // a shift held from the start keeps every value; one late outlier alone is not a tail
    assert_eq!(change_point(&[1.0, 1.1, 0.9, 1.0], 1.0), Some(0));
    assert_eq!(change_point(&[0.9, 1.0, 1.0, 1.3], 1.0), Some(0));
    // the other sign's tail is not taken
    assert_eq!(change_point(&[0.8, 0.9, -0.1], -1.0), Some(2));
    assert_eq!(change_point(&[], 1.0), None);
    assert_eq!(change_point(&[f64::NAN, 1.0], 1.0), Some(1));
}

#[test]
fn scale_history_holds_back_a_developing_run() {
    let mut h = ScaleHistory::default();
    for v in [0.1, -0.2, 0.15] {
        h.record(v, false, false);
    }
    let before = h.scale();
    // a run under way: held, the scale is unchanged
    h.record(3.0, true, false);
    h.record(3.5, true, false);
    assert_eq!(h.len(), 3);
    assert_eq!(h.scale(), before);
    // the run ends in an alarm: the held values are dropped
    h.record(4.0, false, true);
    assert_eq!(h.len(), 3);
    // a run that dies out joins the history
    h.record(0.3, true, false);
    h.record(-0.1, false, false);
    assert_eq!(h.len(), 5);
    // a lasting new normal joins after HELD_MAX
    for _ in 0..HELD_MAX + 1 {
        h.record(1.0, true, false);
    }
    assert!(h.len() > 5);
}

/// A monitor whose completed sweeps carry the given smooth fits of joint 1 (offset, its
/// standard error, mean sensitivity in ln Y per degree), one sweep of 81 captures each in
/// θi layer `layer`; joint 2's fits are steady at zero.
fn with_smooth_fits(fits: &[(i64, f64, f64, f64)]) -> SweepMonitor {
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig, fits.len());
    for (k, &(layer, b, se, s)) in fits.iter().enumerate() {
        m.sweep_starts.push(SweepSpan {
            offsets: [0.0; 2],
            smooth: [(b, se), (0.01 * (k % 3) as f64, 0.05)],
            smooth_s: [s, 0.002],
            ..span(k, layer)
        });
    }
    m
}

/// Light `k`'s sweep of 81 captures in θi layer `layer`, one after the other from capture 0,
/// with no fits.
fn span(k: usize, layer: i64) -> SweepSpan {
    let first_idx = 81 * k as u64;
    SweepSpan {
        light: k,
        first_idx,
        last_idx: first_idx + 80,
        first_t: 7.0 * first_idx as f64,
        layer,
        offsets: [f64::NAN; 2],
        offset_se: [f64::NAN; 2],
        smooth: [(f64::NAN, f64::NAN); 2],
        smooth_s: [f64::NAN; 2],
        wagon_offset: (f64::NAN, f64::NAN),
        level_se: f64::NAN,
        pattern: None,
    }
}

#[test]
fn a_level_change_that_a_joints_pattern_explains_is_the_tilts_and_a_lamp_step_is_not() {
    // 10 in-control sweeps at θi = 60° (joint 1's offset 0 ± 0.05°), then 3 that read +0.8°:
    // a tilt of +0.8° with a mean sensitivity of −1 %/° lowers the level by 0.8 %
    let earlier: Vec<(i64, f64, f64, f64)> = (0..10)
        .map(|k| (60_000, 0.05 * ((k % 5) as f64 - 2.0) / 2.0, 0.07, -0.01))
        .collect();
    let tilted = |b: f64| {
        let mut v = earlier.clone();
        v.extend([(60_000, b, 0.07, -0.01); 3]);
        with_smooth_fits(&v)
    };
    let since = 81 * 10;
    let m = tilted(0.8);
    let x = m.attribute_level(60_000, -0.008, since).unwrap();
    assert_eq!(x.joint, 0);
    assert!((x.mean - 0.8).abs() < 0.05, "{x:?}");
    assert!(x.statistic >= ATTRIBUTION_Z && x.attributed_level == Some(-0.008));
    // judged without the crossing's first sweep (it may hold a lamp step part-way), and
    // placed at the first sweep judged: the retake list starts a sweep before it
    assert_eq!(x.since, since + 81 + 80);
    // the same sweeps with a rising level: the tilt would lower it, so it is the lamp's
    assert!(m.attribute_level(60_000, 0.008, since).is_none());
    // a lamp step leaves the pattern where it was
    assert!(tilted(0.02)
        .attribute_level(60_000, -0.015, since)
        .is_none());
    // a lamp step part-way through the crossing's first sweep puts a pattern into that
    // sweep alone: the lamp's
    let mut v = earlier.clone();
    v.extend([(60_000, 0.8, 0.07, -0.01), (60_000, 0.01, 0.07, -0.01)]);
    assert!(with_smooth_fits(&v)
        .attribute_level(60_000, -0.008, since)
        .is_none());
    // a departure below the joint tolerance is not a slip however significant
    assert!(tilted(0.2).attribute_level(60_000, -0.002, since).is_none());
    // a layer whose pattern swings by ±0.6° from sweep to sweep (a square footprint at
    // grazing light) takes a level for the tilt's only well beyond that swing
    let swinging: Vec<(i64, f64, f64, f64)> = (0..10)
        .map(|k| (75_000, 0.6 * (k as f64 * 1.3).sin(), 0.07, -0.05))
        .chain([(75_000, 0.8, 0.07, -0.05); 3])
        .collect();
    assert!(with_smooth_fits(&swinging)
        .attribute_level(75_000, -0.04, since)
        .is_none());
    // too few earlier sweeps with a usable fit (a layer the model does not know yet, and
    // nothing before it): nothing is attributed
    let loose: Vec<(i64, f64, f64, f64)> = (0..10)
        .map(|_| (60_000, 0.0, 0.9, -0.01))
        .chain([(60_000, 0.8, 0.07, -0.01); 3])
        .collect();
    assert!(with_smooth_fits(&loose)
        .attribute_level(60_000, -0.008, since)
        .is_none());
}

#[test]
fn bad_luminance_unknown_lights_and_empty_sweeps_give_nothing() {
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig, 81);
    for (k, y) in [f64::NAN, f64::INFINITY, 0.0, -1.0, 1e-300]
        .iter()
        .enumerate()
    {
        m.add(SweepCapture {
            idx: k as u64,
            t: 7.0 * k as f64,
            entry: k,
            light: 0,
            camera: k,
            class: (0, 0, k as i64),
            layer: 0,
            omega_i: Vec3::new(0.0, 0.0, 1.0),
            omega_o: Vec3::new(0.0, 0.0, 1.0),
            cmd: [0.0; 4],
            wagon_dir: 0.0,
            y: *y,
            mount: [0.0; 4],
        });
    }
    // only the positive finite value is kept
    assert_eq!(m.captures.len(), 1);
    let o = m.light_complete(0, true, None, None);
    assert!(o.record.is_none() && o.findings.is_empty() && o.step_at_s.is_none());
    // a light the plan does not have, and a light with no capture at all
    let o = m.light_complete(500, true, None, None);
    assert!(o.record.is_none() && o.findings.is_empty());
    let o = m.light_complete(7, true, None, None);
    assert!(o.record.is_none() && o.findings.is_empty());
    assert_eq!(m.summary().tested, 0);
}

#[test]
fn an_amplitude_is_judged_along_its_own_direction_and_a_degenerate_one_lends_no_phase() {
    // coefficients (const, cos, sin) = (1, 3, 4): amplitude 5 along (0.6, 0.8)
    let b = DVector::from_vec(vec![1.0, 3.0, 4.0]);
    let cov = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 0.25, 4.0]));
    // variance along (0.6, 0.8): 0.36·0.25 + 0.64·4 = 2.65
    assert!((amplitude_t(&b, &cov, 1) - 5.0 / 2.65f64.sqrt()).abs() < 1e-12);
    let zero = DVector::from_vec(vec![1.0, 0.0, 0.0]);
    assert_eq!(amplitude_t(&zero, &cov, 1), 0.0);
    // an exact fit (no variance) or a broken one has no phase to lend
    assert_eq!(amplitude_t(&b, &DMatrix::zeros(3, 3), 1), 0.0);
    let nan = DMatrix::from_element(3, 3, f64::NAN);
    assert_eq!(amplitude_t(&b, &nan, 1), 0.0);
    // too few lights for the model: no pattern
    assert!(pattern_fit(&[0.0, 1.0, 2.0], &[0.0; 3], &[4.0], None, 0.5).is_none());
}

/// A fresh monitor on the default rig and plan size, for the lent-scale tests.
fn monitor() -> SweepMonitor {
    SweepMonitor::new(
        SweepSpec::default(),
        Rig::new(Default::default()).unwrap(),
        81,
    )
}

/// A scale history of `n` values ±v (robust scale v · 1.4826).
fn history(v: f64, n: usize) -> ScaleHistory {
    ScaleHistory {
        values: [v, -v].repeat(n.div_ceil(2))[..n].to_vec(),
        held: Vec::new(),
    }
}

/// The lent scale: the nearest lower layer with enough sweeps, grown by tan²θi; none from
/// the pole's layer or from a layer with too few sweeps.
#[test]
fn a_layer_borrows_the_scale_of_the_nearest_lower_layer_grown_by_tan_squared() {
    let mut m = monitor();
    m.level_history.insert(0, history(0.001, 10));
    assert_eq!(m.prior_level_scale(15_000, true), None);
    m.level_history
        .insert(30_000, history(0.002, PRIOR_MIN_SWEEPS - 1));
    assert_eq!(m.prior_level_scale(45_000, true), None);
    m.level_history
        .insert(15_000, history(0.002, PRIOR_MIN_SWEEPS));
    let tan2 = |d: f64| d.to_radians().tan().powi(2);
    let want = 0.002 * crate::measure::stats::MAD_TO_SIGMA * tan2(45.0) / tan2(15.0) * PRIOR_SAFETY;
    let got = m.prior_level_scale(45_000, true).unwrap();
    assert!((got / want - 1.0).abs() < 1e-9, "{got} {want}");
    // a layer lends only upwards
    assert_eq!(m.prior_level_scale(15_000, true), None);
}

/// A layer that has no pattern model yet judges its raw levels, which carry the light-side
/// pattern's whole swing, by the lower layer's raw levels, not by its residuals about its
/// model: the pattern a lower layer's model takes out is still in the new layer's levels.
#[test]
fn a_layer_without_a_pattern_model_borrows_the_raw_levels_scale() {
    let mut m = monitor();
    // the θi = 60° layer: residuals of 0.05 % about its model, raw levels swinging 1 %
    m.level_history.insert(60_000, history(0.0005, 12));
    m.raw_level_history.insert(60_000, history(0.01, 12));
    let modelled = m.prior_level_scale(75_000, true).unwrap();
    let unmodelled = m.prior_level_scale(75_000, false).unwrap();
    assert!(
        (unmodelled / modelled - 20.0).abs() < 1e-9,
        "{unmodelled} {modelled}"
    );
}

/// The lent scale grows towards grazing as the session's own lower layers do, up to the
/// footprint's tan² law: flat layers lend their scale as it is, layers growing as tan θi lend
/// it grown so, and faster growth is capped at tan².
#[test]
fn the_lent_scale_grows_as_the_lower_layers_do_up_to_tan_squared() {
    let tan = |d: f64| d.to_radians().tan();
    let lent = |s30: f64, s45: f64| {
        let mut m = monitor();
        m.raw_level_history
            .insert(30_000, history(s30, PRIOR_MIN_SWEEPS));
        m.raw_level_history
            .insert(45_000, history(s45, PRIOR_MIN_SWEEPS));
        m.prior_level_scale(60_000, false).unwrap()
            / (s45 * crate::measure::stats::MAD_TO_SIGMA * PRIOR_SAFETY)
    };
    let close = |a: f64, b: f64| (a / b - 1.0).abs() < 1e-9;
    assert!(close(lent(0.004, 0.004), 1.0));
    let linear = lent(0.004, 0.004 * tan(45.0) / tan(30.0));
    assert!(close(linear, tan(60.0) / tan(45.0)), "{linear}");
    let steep = lent(0.001, 0.02);
    assert!(close(steep, (tan(60.0) / tan(45.0)).powi(2)), "{steep}");
    // shrinking layers lend their scale unshrunk
    assert!(close(lent(0.01, 0.002), 1.0));
}

#[test]
fn thresholds_follow_the_false_alarm_budget() {
    let rig = Rig::new(Default::default()).unwrap();
    let m = SweepMonitor::new(SweepSpec::default(), rig.clone(), 81);
    let (hl, hj) = m.thresholds();
    assert!(hj > hl && hl > 2.0, "{hl} {hj}");
    let strict = SweepMonitor::new(
        SweepSpec {
            false_alarm_runs: 200.0,
            ..SweepSpec::default()
        },
        rig,
        81,
    );
    assert!(strict.thresholds().0 > hl);
}

/// A monitor whose completed sweeps, one of 81 captures each, carry joint 2's detection fits
/// (θi layer, offset, standard error; NaN for an untested sweep), and whose joint-2 history
/// scatters by 0.05°.
fn monitor_with_joint2(fits: &[(i64, f64, f64)]) -> SweepMonitor {
    let rig = Rig::new(Default::default()).unwrap();
    let mut m = SweepMonitor::new(SweepSpec::default(), rig, fits.len());
    for v in [0.05, -0.05, 0.05, -0.05, 0.05, -0.05] {
        m.joint_history[1].record(v, false, false);
    }
    for (k, &(layer, b, se)) in fits.iter().enumerate() {
        m.sweep_starts.push(SweepSpan {
            offsets: [0.0, b],
            offset_se: [0.02, se],
            ..span(k, layer)
        });
    }
    m
}

/// A joint-2 crossing whose CUSUM run began with the sweep ending at `since`.
fn crossing_since(since: u64, mean: f64) -> JointCrossing {
    JointCrossing {
        joint: 1,
        statistic: 4.0,
        mean,
        mean_se: 0.1,
        sweeps: 2,
        since,
        estimate_sweeps: 2,
        run_mean: mean,
        attributed_level: None,
    }
}

#[test]
fn a_joint_pattern_is_a_change_within_its_layer_only_against_sweeps_that_bound_it() {
    let (l60, l75) = (60_000, 75_000);
    let nan = f64::NAN;
    // the layer's untested first sweeps, then two clean ones, then the run: shown
    let m = monitor_with_joint2(&[
        (l60, 0.0, 0.03),
        (l75, nan, nan),
        (l75, nan, nan),
        (l75, 0.02, 0.05),
        (l75, -0.03, 0.05),
        (l75, 1.0, 0.08),
        (l75, 0.9, 0.08),
    ]);
    let c = m.layer_change(&crossing_since(5 * 81 + 80, 0.95), l75);
    assert_eq!(c.sweeps_before, 2, "{c:?}");
    let (before, se) = c.before.unwrap();
    assert!(before.abs() < 0.02 && se > 0.04 && se < 0.08, "{c:?}");
    assert!(c.change_z.unwrap() > 8.0 && c.shown(0.95), "{c:?}");
    // the other sign is not shown by it
    assert!(!c.shown(-0.95));
    // a run from the layer's first tested sweep: nothing before it in the layer (the sweep
    // of the layer below does not count), not shown
    let c = m.layer_change(&crossing_since(3 * 81 + 80, 0.5), l75);
    assert_eq!(
        (c.sweeps_before, c.before, c.change_z),
        (0, None, None),
        "{c:?}"
    );
    assert!(!c.shown(0.5));
    // one imprecise sweep before the run cannot bound it: 0.8° of change at 2.7 SE
    let m = monitor_with_joint2(&[
        (l75, nan, nan),
        (l75, 0.2, 0.3),
        (l75, 1.0, 0.08),
        (l75, 1.0, 0.08),
    ]);
    let c = m.layer_change(&crossing_since(2 * 81 + 80, 1.0), l75);
    let z = c.change_z.unwrap();
    assert!(z > 2.0 && z < LAYER_CHANGE_Z && !c.shown(1.0), "{c:?}");
}

#[test]
fn the_layer_below_accounts_for_a_level_only_the_same_way_clearly_and_grown_far_enough() {
    let below = |departure: f64, se: f64| PatternBelow {
        below_deg: 60.0,
        departure,
        se,
        growth: 4.64,
    };
    // −0.5 % ± 0.1 grown ×4.64 reaches −2.3 %: a −2 % run down is accounted for
    assert!(below(-0.005, 0.001).explains(false, -0.02));
    // not a run up, nor one larger than the grown departure
    assert!(!below(-0.005, 0.001).explains(true, 0.02));
    assert!(!below(-0.005, 0.001).explains(false, -0.025));
    // nor a departure within 3 standard errors of none
    assert!(!below(-0.005, 0.002).explains(false, -0.01));
    // nor anything from an exactly flat layer below
    assert!(!below(0.0, 0.0).explains(false, -0.01));
}
