//! Numerical edge cases of the measurement core: NaN propagation and overflow in the colour
//! differences, the cancellation-free ΔH*ab, Shepard interpolation next to a node, direction
//! angles of tiny and huge vectors, and the column-scaled colour-transform fit.

use goniowatch::fixtures::Rng;
use goniowatch::measure::colour::*;
use goniowatch::measure::crossval::{fit_transform, ColourTransform, CrossValError};
use goniowatch::measure::geometry::*;
use goniowatch::measure::shepard::Shepard;

fn lab_at(l: f64, c: f64, h_rad: f64) -> Lab {
    Lab::new(l, c * h_rad.cos(), c * h_rad.sin())
}

// ---------------------------------------------------------------------------------------------
// Colour differences
// ---------------------------------------------------------------------------------------------

#[test]
fn a_nan_colour_difference_is_nan_never_a_perfect_match() {
    let good = [
        Lab::new(50.0, 20.0, -10.0),
        Lab::new(50.0, 0.0, 0.0),
        Lab::new(0.0, 0.0, 0.0),
    ];
    for base in good {
        for pos in 0..3 {
            let mut v = [base.l, base.a, base.b];
            v[pos] = f64::NAN;
            let bad = Lab::new(v[0], v[1], v[2]);
            for other in good {
                for (x, y) in [(bad, other), (other, bad), (bad, bad)] {
                    assert!(ciede2000(x, y).is_nan(), "ciede2000({x:?}, {y:?})");
                    assert!(delta_h76(x, y).is_nan(), "delta_h76({x:?}, {y:?})");
                    assert!(delta_e76(x, y).is_nan(), "delta_e76({x:?}, {y:?})");
                }
            }
        }
    }
    let (a, b) = (good[0], Lab::new(60.0, 5.0, 5.0));
    for k in [
        [f64::NAN, 1.0, 1.0],
        [1.0, f64::NAN, 1.0],
        [1.0, 1.0, f64::NAN],
    ] {
        assert!(ciede2000_weighted(a, b, k[0], k[1], k[2]).is_nan(), "{k:?}");
    }
    // through the per-pair summary as well
    let w = White::d65_scaled(100.0).unwrap();
    let d = colour_difference([f64::NAN, 20.0, 30.0], [20.0, 20.0, 30.0], w);
    assert!(
        d.de2000.is_nan() && d.dh.is_nan() && d.de76.is_nan(),
        "{d:?}"
    );
}

#[test]
fn ciede2000_stays_finite_and_scale_free_at_huge_chroma() {
    // Scaling both colours' a, b by λ: for λ far beyond 25 the weights tend to their limits
    // (G → 0, R_C → 2, S_C and S_H ∝ C̄′), so the difference tends to a finite limit.
    let pairs = [
        ((50.0, 0.3, 0.4), (55.0, 0.35, 0.38)),
        ((50.0, 1.0, 0.0), (50.0, 0.0, 1.0)),
        ((20.0, -0.6, 0.2), (70.0, 0.5, -0.5)),
        ((50.0, 0.01, 1.0), (50.0, 0.0, 1.0)), // h̄′ near 275°, where R_T matters most
    ];
    for ((l1, a1, b1), (l2, a2, b2)) in pairs {
        let at = |s: f64| ciede2000(Lab::new(l1, a1 * s, b1 * s), Lab::new(l2, a2 * s, b2 * s));
        let limit = at(1e20);
        assert!(limit.is_finite() && limit > 0.0, "{limit}");
        for s in [1e40, 1e44, 1e45, 1e60, 1e100, 1e150, 1e200, 1e300] {
            let d = at(s);
            assert!(
                (d - limit).abs() <= 1e-12 * limit,
                "λ = {s:e}: {d} vs the limit {limit}"
            );
        }
    }
    // the same colour at huge chroma is no difference at all
    let big = Lab::new(50.0, 3e200, -4e200);
    assert_eq!(ciede2000(big, big), 0.0);
}

#[test]
fn delta_h_of_identical_colours_is_exactly_zero() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for _ in 0..10_000 {
        let c = Lab::new(
            rng.range(0.0, 100.0),
            rng.range(-128.0, 128.0),
            rng.range(-128.0, 128.0),
        );
        assert_eq!(delta_h76(c, c), 0.0, "{c:?}");
    }
    for c in [
        Lab::new(50.0, 37.1, -12.3),
        Lab::new(50.0, 1e-300, 1e-300),
        Lab::new(50.0, 0.0, 0.0),
        Lab::new(50.0, -0.0, 5.0),
    ] {
        assert_eq!(delta_h76(c, c), 0.0, "{c:?}");
    }
}

#[test]
fn delta_h_never_exceeds_delta_e() {
    // ΔE² = ΔL² + ΔC² + ΔH², so |ΔH| ≤ ΔE; pairs at every distance from 1e-12 to 10 units,
    // moved in hue only, in chroma only, or in all three coordinates.
    let mut rng = Rng(2_463_534_242);
    let mut worst: f64 = 0.0;
    for i in 0..100_000 {
        let a = Lab::new(
            rng.range(0.0, 100.0),
            rng.range(-128.0, 128.0),
            rng.range(-128.0, 128.0),
        );
        let scale = 10f64.powf(rng.range(-12.0, 1.0));
        let b = match i % 3 {
            0 => {
                let h = a.b.atan2(a.a) + scale * rng.range(-1.0, 1.0) / a.chroma().max(1.0);
                lab_at(a.l, a.chroma(), h)
            }
            1 => {
                let k = 1.0 + scale * rng.range(-1.0, 1.0) / a.chroma().max(1.0);
                Lab::new(a.l, a.a * k, a.b * k)
            }
            _ => Lab::new(
                a.l + scale * rng.range(-1.0, 1.0),
                a.a + scale * rng.range(-1.0, 1.0),
                a.b + scale * rng.range(-1.0, 1.0),
            ),
        };
        let (dh, de) = (delta_h76(a, b), delta_e76(a, b));
        assert!(dh.is_finite(), "{a:?} {b:?}");
        assert!(
            dh.abs() <= de * (1.0 + 1e-13),
            "pair {i}: ΔH {dh:e} > ΔE {de:e}"
        );
        if de > 0.0 {
            worst = worst.max(dh.abs() / de);
        }
    }
    assert!(worst <= 1.0 + 1e-13, "{worst}");
}

#[test]
fn a_tiny_hue_difference_is_resolved() {
    // Two colours of chroma C at hue angles h and h + δ: ΔH = 2C·sin(δ/2), here ≈ 8e-8.
    for (c, h) in [
        (50.0, 0.7),
        (50.0, 2.9),
        (120.0, 4.0),
        (3.0, 5.5),
        (50.0, 0.0),
    ] {
        let delta: f64 = 8e-8 / c;
        let want = 2.0 * c * (delta / 2.0).sin();
        let (x, y) = (lab_at(60.0, c, h), lab_at(60.0, c, h + delta));
        let dh = delta_h76(x, y);
        assert!(
            (dh - want).abs() <= 1e-6 * want,
            "C {c}, h {h}: {dh:e} vs {want:e}"
        );
        // the sign follows the rotation from the first colour to the second
        assert!((delta_h76(y, x) + want).abs() <= 1e-6 * want);
    }
    // opposite hues: the chord is the whole diameter 2√(C₁C₂), in either order
    let (p, q) = (
        lab_at(50.0, 10.0, 1.0),
        lab_at(50.0, 40.0, 1.0 + std::f64::consts::PI),
    );
    assert!((delta_h76(p, q).abs() - 40.0).abs() < 1e-9);
    assert!((delta_h76(q, p).abs() - 40.0).abs() < 1e-9);
    // exactly opposite on an axis, where the rotation's sign is that of +180°
    let (e, w) = (Lab::new(50.0, 10.0, 0.0), Lab::new(50.0, -10.0, 0.0));
    assert!((delta_h76(e, w) - 20.0).abs() < 1e-12);
    assert!((delta_h76(w, e) - 20.0).abs() < 1e-12);
    // one neutral colour: no hue difference
    assert_eq!(delta_h76(Lab::new(50.0, 0.0, 0.0), e), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Shepard next to a node
// ---------------------------------------------------------------------------------------------

/// A 9×9 grid on the unit square, 1 at the origin and 0 elsewhere (a spike the neighbouring
/// nodal functions disagree about, so a dropped node shows).
fn spike_2d() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut x, mut y, mut f) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..9 {
        for i in 0..9 {
            x.push(i as f64 / 8.0);
            y.push(j as f64 / 8.0);
            f.push(if i == 0 && j == 0 { 1.0 } else { 0.0 });
        }
    }
    (x, y, f)
}

fn check_next_to_nodes(name: &str, s: &Shepard, nodes: &[([f64; 3], f64)], dims: usize) {
    for &(p, fk) in nodes {
        for off in [0.0, 1e-300, -1e-300, 1e-160, -1e-160, 1e-120, 1e-105] {
            for axis in 0..dims {
                let mut q = p;
                q[axis] += off;
                let (v, spread) = s.value_with_spread(&q[..dims]).unwrap();
                assert!(
                    (v - fk).abs() <= 1e-12,
                    "{name}: node {p:?} offset {off:e} on axis {axis}: {v} vs {fk}"
                );
                assert!(spread.abs() <= 1e-12, "{name}: spread {spread} at {q:?}");
            }
        }
        // continuity: a small ordinary offset gives nearly the nodal value
        let mut q = p;
        q[0] += 1e-6;
        let (v, spread) = s.value_with_spread(&q[..dims]).unwrap();
        assert!((v - fk).abs() < 1e-4, "{name}: {v} vs {fk} at 1e-6");
        assert!(spread < 1e-3, "{name}: spread {spread} at 1e-6");
    }
}

#[test]
fn shepard_is_exact_at_and_next_to_a_node_2d() {
    let (x, y, f) = spike_2d();
    let nodes = [([0.0, 0.0, 0.0], 1.0), ([0.0, 0.5, 0.0], 0.0)];
    let q = Shepard::quadratic_2d(&x, &y, &f, 13, 19).unwrap();
    check_next_to_nodes("QSHEP2D", &q, &nodes, 2);
    let c = Shepard::cubic_2d(&x, &y, &f, 17, 30).unwrap();
    check_next_to_nodes("CSHEP2D", &c, &nodes, 2);
}

#[test]
fn shepard_is_exact_at_and_next_to_a_node_3d() {
    let (mut x, mut y, mut z, mut f) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for k in 0..5 {
        for j in 0..5 {
            for i in 0..5 {
                x.push(i as f64 / 4.0);
                y.push(j as f64 / 4.0);
                z.push(k as f64 / 4.0);
                f.push(if i + j + k == 0 { 1.0 } else { 0.0 });
            }
        }
    }
    let s = Shepard::quadratic_3d(&x, &y, &z, &f, 17, 32).unwrap();
    let nodes = [([0.0, 0.0, 0.0], 1.0), ([0.0, 0.5, 0.0], 0.0)];
    check_next_to_nodes("QSHEP3D", &s, &nodes, 3);
}

// ---------------------------------------------------------------------------------------------
// Directions of tiny and huge vectors
// ---------------------------------------------------------------------------------------------

fn ordinary_directions() -> Vec<Vec3> {
    vec![
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.3, -0.2, 0.9),
        Vec3::new(-0.5, 0.1, -0.8),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(1e-9, 0.0, 1.0),
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(2.0, -3.0, 1e-7),
    ]
}

const SCALES: [f64; 8] = [
    1e-200, 1e-300, 1e-310, 5e-320, 1e-160, 1e160, 1e300, 1.7e308,
];

#[test]
fn spherical_angles_do_not_depend_on_the_vector_length() {
    let s = Spherical::from_vector(&Vec3::new(1e-200, 1e-200, 0.0));
    assert!((s.theta_deg() - 90.0).abs() < 1e-12, "{s:?}");
    assert!((s.phi_deg() - 45.0).abs() < 1e-12, "{s:?}");
    for v in ordinary_directions() {
        let want = Spherical::from_vector(&v);
        let unit = Spherical::from_vector(&v.normalize());
        assert!((unit.theta - want.theta).abs() < 1e-15 && (unit.phi - want.phi).abs() < 1e-15);
        for k in SCALES {
            let got = Spherical::from_vector(&(v / v.amax() * k));
            // a component the scaling pushes below the subnormal range is lost: compare against
            // the direction that is left
            let kept = (v / v.amax() * k) / k;
            let want = Spherical::from_vector(&kept);
            assert!(
                (got.theta - want.theta).abs() < 1e-14
                    && (wrap_2pi(got.phi - want.phi + 1.0) - 1.0).abs() < 1e-14,
                "{v:?} × {k:e}: {got:?} vs {want:?}"
            );
        }
        // a power-of-two scaling that loses no bits changes nothing at all
        for e in [-900, -600, -300, 300, 600, 900] {
            let k = 2f64.powi(e);
            if (v * k) / k == v {
                assert_eq!(Spherical::from_vector(&(v * k)), want, "{v:?} × 2^{e}");
                assert_eq!(sphere_to_square(&(v * k)), sphere_to_square(&v));
            }
        }
    }
}

#[test]
fn spherical_angles_of_the_zero_and_non_finite_vectors() {
    for z in [
        Vec3::zeros(),
        Vec3::new(0.0, 0.0, -0.0),
        Vec3::new(-0.0, -0.0, -0.0),
    ] {
        assert_eq!(
            Spherical::from_vector(&z),
            Spherical {
                theta: 0.0,
                phi: 0.0
            }
        );
        assert_eq!(sphere_to_square(&z), (0.5, 0.5));
    }
    for bad in [
        Vec3::new(f64::NAN, 0.0, 1.0),
        Vec3::new(0.0, 0.0, f64::INFINITY),
        Vec3::new(f64::NEG_INFINITY, 1.0, 0.0),
    ] {
        let s = Spherical::from_vector(&bad);
        assert!(s.theta.is_nan() && s.phi.is_nan(), "{bad:?}: {s:?}");
        let (u, v) = sphere_to_square(&bad);
        assert!(u.is_nan() && v.is_nan(), "{bad:?}");
    }
}

#[test]
fn the_square_map_does_not_depend_on_the_vector_length() {
    assert_eq!(sphere_to_square(&Vec3::new(0.0, 0.0, 1e-300)), (0.5, 0.5));
    assert_eq!(sphere_to_square(&Vec3::new(0.0, 0.0, -1e-300)), (0.0, 0.0));
    for v in ordinary_directions() {
        let want = sphere_to_square(&v.normalize());
        for k in SCALES {
            let w = v / v.amax() * k;
            let kept = sphere_to_square(&(w / k));
            let got = sphere_to_square(&w);
            assert!(
                (got.0 - kept.0).abs() < 1e-14 && (got.1 - kept.1).abs() < 1e-14,
                "{v:?} × {k:e}: {got:?} vs {kept:?}"
            );
        }
        let got = sphere_to_square(&(v * 3.0));
        assert!((got.0 - want.0).abs() < 1e-15 && (got.1 - want.1).abs() < 1e-15);
    }
}

#[test]
fn rotations_and_angles_between_tiny_and_huge_vectors() {
    for v in ordinary_directions() {
        let r = rotation_pole_to(&v);
        for k in [1e-200, 1e-300, 1e300] {
            let rk = rotation_pole_to(&(v * k));
            assert!((rk - r).norm() < 1e-14, "{v:?} × {k:e}");
        }
        for u in ordinary_directions() {
            let want = angle_between(&u, &v);
            for (ku, kv) in [(1e-200, 1e-200), (1e-300, 1e200), (1e300, 1e-300)] {
                let got = angle_between(&(u * ku), &(v * kv));
                assert!((got - want).abs() < 1e-14, "{u:?} {v:?}: {got} vs {want}");
            }
        }
    }
    assert_eq!(
        rotation_pole_to(&Vec3::zeros()),
        nalgebra::Matrix3::identity()
    );
}

// ---------------------------------------------------------------------------------------------
// The colour transform fit with badly scaled channels
// ---------------------------------------------------------------------------------------------

fn chromatic_colours(n: usize, seed: u64) -> Vec<Xyz> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|_| {
            let l = rng.range(5.0, 95.0);
            [
                l * rng.range(0.7, 1.2),
                l * rng.range(0.8, 1.2),
                l * rng.range(0.6, 1.4),
            ]
        })
        .collect()
}

const T0: [[f64; 3]; 3] = [
    [3.207, -1.406, -1.144],
    [3.404, -1.486, -1.218],
    [3.461, -1.578, -1.196],
];

fn apply(t: &[[f64; 3]; 3], v: Xyz) -> Xyz {
    [0, 1, 2].map(|k| t[k][0] * v[0] + t[k][1] * v[1] + t[k][2] * v[2])
}

#[test]
fn badly_scaled_channels_are_fitted_not_flagged() {
    // an instrument whose channels read on very different scales: v = diag(s)·v₀ and the
    // transform that undoes it is T = T₀·diag(1/s)
    let v0 = chromatic_colours(300, 11);
    let w: Vec<Xyz> = v0.iter().map(|x| apply(&T0, *x)).collect();
    let plain = fit_transform(&v0, &w).unwrap();
    assert!(!plain.ill_conditioned, "{plain:?}");
    for s in [[1.0, 1.0, 1e-3], [1e6, 1e6, 1e-6], [1e-6, 1.0, 1e6]] {
        let v: Vec<Xyz> = v0.iter().map(|x| [0, 1, 2].map(|c| x[c] * s[c])).collect();
        let fit = fit_transform(&v, &w).unwrap_or_else(|e| panic!("scales {s:?}: {e}"));
        for r in 0..3 {
            for c in 0..3 {
                let want = T0[r][c] / s[c];
                assert!(
                    ((fit.t[r][c] - want) / want).abs() < 1e-4,
                    "scales {s:?}: T[{r}][{c}] = {} vs {want}",
                    fit.t[r][c]
                );
            }
        }
        assert!(!fit.ill_conditioned, "scales {s:?}: {fit:?}");
        // the raw condition number still tells how badly scaled the data are
        assert!(fit.condition > plain.condition, "{fit:?}");
        assert!(
            (fit.condition_scaled / plain.condition_scaled - 1.0).abs() < 1e-6,
            "{fit:?} vs {plain:?}"
        );
    }
}

#[test]
fn rank_deficient_colours_are_still_refused() {
    let v0 = chromatic_colours(100, 12);
    let w: Vec<Xyz> = v0.iter().map(|x| apply(&T0, *x)).collect();
    // two identical channels, the same at another scale, and a dead channel
    let same: Vec<Xyz> = v0.iter().map(|x| [x[0], x[0], x[2]]).collect();
    let scaled: Vec<Xyz> = v0.iter().map(|x| [x[0], x[1], 1e-6 * x[0]]).collect();
    let dead: Vec<Xyz> = v0.iter().map(|x| [x[0], 0.0, x[2]]).collect();
    for (name, v) in [
        ("identical", same),
        ("proportional", scaled),
        ("zero", dead),
    ] {
        match fit_transform(&v, &w) {
            Err(CrossValError::Singular(k)) => assert!(!(k < 1e12), "{name}: {k}"),
            other => panic!("{name}: {other:?}"),
        }
    }
}

#[test]
fn the_transform_keeps_its_json_keys_and_reads_older_files() {
    let v0 = chromatic_colours(50, 13);
    let w: Vec<Xyz> = v0.iter().map(|x| apply(&T0, *x)).collect();
    let fit = fit_transform(&v0, &w).unwrap();
    let json = serde_json::to_value(fit).unwrap();
    for key in [
        "t",
        "condition",
        "condition_scaled",
        "rms_residual",
        "ill_conditioned",
    ] {
        assert!(json.get(key).is_some(), "{key} missing from {json}");
    }
    let back: ColourTransform = serde_json::from_value(json.clone()).unwrap();
    assert_eq!(back, fit);
    // a file written before the scaled condition number existed: the flag was decided on the
    // raw one, so that is what the scaled one reads as
    let mut old = json;
    old.as_object_mut().unwrap().remove("condition_scaled");
    let back: ColourTransform = serde_json::from_value(old).unwrap();
    assert_eq!(back.condition_scaled, fit.condition);
    assert_eq!(back.t, fit.t);
}
