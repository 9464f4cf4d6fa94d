//! Rig kinematics over the whole UBO plan: round trips, poles, occlusion substitutes; the plan's
//! pair and class structure checked by brute force.

use goniowatch::measure::geometry::{angle_between, azimuth_difference_deg, Spherical};
use goniowatch::measure::kinematics::*;
use goniowatch::measure::plan::*;
use std::collections::HashSet;

/// The incidence with these angles (degrees).
fn incidence(theta_i_deg: f64, phi_i_deg: f64, theta_o_deg: f64, phi_o_deg: f64) -> Incidence {
    Incidence::from_angles(&Angles {
        theta_i_deg,
        phi_i_deg,
        theta_o_deg,
        phi_o_deg,
    })
}

fn rig(min_sep: f64) -> Rig {
    Rig::new(RigSpec {
        min_separation_deg: min_sep,
        ..RigSpec::default()
    })
    .unwrap()
}

#[test]
fn round_trip_over_all_6561_plan_entries() {
    let plan = SamplingPlan::ubo();
    let dirs = plan.directions();
    let mut spec = RigSpec::default();
    // a rig with non-trivial calibration must round-trip just the same
    spec.joints = [
        AxisCalibration {
            offset_deg: 12.5,
            sign: 1.0,
        },
        AxisCalibration {
            offset_deg: -3.0,
            sign: -1.0,
        },
        AxisCalibration {
            offset_deg: 0.25,
            sign: 1.0,
        },
    ];
    spec.wagon = AxisCalibration {
        offset_deg: 90.0,
        sign: -1.0,
    };
    let rig = Rig::new(spec).unwrap();
    let mut substitutes = 0;
    for i in 0..plan.capture_count() {
        let e = plan.entry(i).unwrap();
        let (pi, po) = (dirs[e.light].spherical(), dirs[e.camera].spherical());
        let planned = rig.plan_pose(pi, po).unwrap();
        let back = rig.forward(&planned.pose).unwrap();
        assert!(
            (back.omega_i - planned.used.omega_i).norm() < 1e-12,
            "entry {i}"
        );
        assert!(
            (back.omega_o - planned.used.omega_o).norm() < 1e-12,
            "entry {i}"
        );
        let a = back.angles();
        assert!((a.theta_o_deg - dirs[e.camera].theta_deg).abs() < 1e-9);
        if dirs[e.camera].theta_deg > 0.0 {
            assert!(azimuth_difference_deg(a.phi_o_deg, dirs[e.camera].phi_deg) < 1e-9);
        } else {
            // φ is undefined at the pole and reported as 0
            assert_eq!(a.phi_o_deg, 0.0);
        }
        match planned.substitute {
            None => {
                assert!((a.theta_i_deg - dirs[e.light].theta_deg).abs() < 1e-9);
                if dirs[e.light].theta_deg > 0.0 {
                    assert!(azimuth_difference_deg(a.phi_i_deg, dirs[e.light].phi_deg) < 1e-9);
                }
            }
            Some((planned_t, used_t)) => {
                substitutes += 1;
                assert!((planned_t - dirs[e.light].theta_deg).abs() < 1e-12);
                assert!((a.theta_i_deg - used_t).abs() < 1e-9);
                // the substitute sits exactly at the rig's minimum separation
                assert!(
                    (back.separation_deg() - 12.0).abs() < 1e-6,
                    "entry {i}: {}",
                    back.separation_deg()
                );
            }
        }
    }
    assert_eq!(
        substitutes, 81,
        "with a 12° minimum only the light = camera entries are occluded"
    );
}

#[test]
fn substitutes_are_the_nearest_feasible_theta() {
    // a larger minimum separation also occludes neighbouring directions (≈14.5–15° apart)
    let rig = rig(16.0);
    let plan = SamplingPlan::ubo();
    let dirs = plan.directions();
    let mut n = 0;
    for i in 0..plan.capture_count() {
        let e = plan.entry(i).unwrap();
        let (pi, po) = (dirs[e.light].spherical(), dirs[e.camera].spherical());
        let planned = rig.plan_pose(pi, po).unwrap();
        let sep = planned.used.separation_deg();
        assert!(sep >= 16.0 - 1e-6, "entry {i}: {sep}");
        if let Some((p, u)) = planned.substitute {
            n += 1;
            // no θ closer to the plan along the same meridian is feasible
            for k in 1..100 {
                let t = p + (u - p) * k as f64 / 100.0;
                let wi = Spherical::from_deg(t, dirs[e.light].phi_deg).to_vector();
                let s = angle_between(&wi, &po.to_vector()).to_degrees();
                assert!(s < 16.0 + 1e-6, "entry {i}: θ={t} already feasible ({s}°)");
            }
            assert!(u >= 0.0 && u <= 85.0);
        }
    }
    assert!(n > 81, "{n}");
}

#[test]
fn poles_and_occlusion_errors() {
    let rig = rig(12.0);
    // both directions at the pole: occluded, substitute moves θi to exactly 12°
    let pole = Spherical::from_deg(0.0, 0.0);
    let p = rig.plan_pose(pole, pole).unwrap();
    let (planned, used) = p.substitute.unwrap();
    assert_eq!(planned, 0.0);
    assert!((used - 12.0).abs() < 1e-6);
    // inverse refuses occluded and below-horizon inputs with typed errors
    let inc = incidence(30.0, 0.0, 30.0, 5.0);
    assert!(matches!(
        rig.inverse(&inc),
        Err(KinematicsError::Occluded { .. })
    ));
    let inc = incidence(95.0, 0.0, 30.0, 90.0);
    assert!(matches!(
        rig.inverse(&inc),
        Err(KinematicsError::BelowHorizon { .. })
    ));
    let inc = incidence(90.0, 0.0, 30.0, 90.0);
    assert!(matches!(
        rig.inverse(&inc),
        Err(KinematicsError::BelowHorizon { .. })
    ));
    // grazing but above the horizon still works, and the pole of ωo is handled
    let inc = incidence(89.9, 10.0, 0.0, 0.0);
    let pose = rig.inverse(&inc).unwrap();
    let back = rig.forward(&pose).unwrap();
    assert!(
        (back.omega_i - inc.omega_i).norm() < 1e-12 && (back.omega_o - inc.omega_o).norm() < 1e-12
    );
    // NaN in a pose is a typed error, not a NaN direction
    assert_eq!(
        rig.forward(&Pose {
            joints_deg: [f64::NAN, 0.0, 0.0],
            wagon_deg: 30.0
        }),
        Err(KinematicsError::NotFinite)
    );
    // a near-vertical incidence with no feasible substitute below the limit
    let tight = Rig::new(RigSpec {
        min_separation_deg: 30.0,
        max_substitute_theta_deg: 20.0,
        ..RigSpec::default()
    })
    .unwrap();
    let r = tight.plan_pose(
        Spherical::from_deg(10.0, 0.0),
        Spherical::from_deg(10.0, 0.0),
    );
    assert!(
        matches!(r, Err(KinematicsError::NoSubstitute { .. })),
        "{r:?}"
    );
}

#[test]
fn a_joint_offset_moves_the_true_directions() {
    // the basis of positioning detection: a reading that is off by 1° on one joint changes ω
    let rig = rig(12.0);
    let inc = incidence(45.0, 20.0, 30.0, 200.0);
    let pose = rig.inverse(&inc).unwrap();
    for j in 0..3 {
        let mut off = pose;
        off.joints_deg[j] += 1.0;
        let moved = rig.forward(&off).unwrap();
        let d = angle_between(&moved.omega_i, &inc.omega_i)
            .to_degrees()
            .max(angle_between(&moved.omega_o, &inc.omega_o).to_degrees());
        assert!(d > 0.1 && d <= 1.0 + 1e-9, "joint {j}: {d}");
    }
}

#[test]
fn pairs_and_classes_by_brute_force() {
    let plan = SamplingPlan::ubo();
    let dirs = plan.directions();
    // reciprocal pairs: every unordered {l, c} with l ≠ c exactly once
    let pairs = plan.reciprocal_pairs();
    let set: HashSet<_> = pairs.iter().collect();
    assert_eq!(set.len(), 3240);
    for &(a, b) in &pairs {
        let (ea, eb) = (plan.entry(a).unwrap(), plan.entry(b).unwrap());
        assert_eq!((ea.light, ea.camera), (eb.camera, eb.light));
        assert_ne!(ea.light, ea.camera);
    }
    // isotropy classes: recount with an independent key (quantised floats)
    let mut keys = HashSet::new();
    for i in 0..plan.capture_count() {
        let e = plan.entry(i).unwrap();
        let (l, c) = (dirs[e.light], dirs[e.camera]);
        let dphi = if l.theta_deg == 0.0 || c.theta_deg == 0.0 {
            0.0
        } else {
            let d = (l.phi_deg - c.phi_deg).rem_euclid(360.0);
            d.min(360.0 - d)
        };
        let (lo, hi) = if l.theta_deg <= c.theta_deg {
            (l.theta_deg, c.theta_deg)
        } else {
            (c.theta_deg, l.theta_deg)
        };
        keys.insert((
            (lo * 1e6) as i64,
            (hi * 1e6) as i64,
            (dphi * 1e6).round() as i64,
        ));
    }
    assert_eq!(plan.isotropy_classes().len(), keys.len());
    let total: usize = plan.isotropy_classes().values().map(|v| v.len()).sum();
    assert_eq!(total, 6561);
}
