//! The cosine re-correction and pair scoring at grazing angles, near black and with bad values.

use goniowatch::measure::colour::White;
use goniowatch::measure::reciprocity::*;

fn white() -> White {
    White::d65_scaled(100.0).unwrap()
}

#[test]
fn grazing_angles_never_divide_by_zero() {
    let x = [20.0, 21.0, 22.0];
    // 75° (the plan's largest) and 89.9° are still comparable and finite
    for t in [75.0, 89.9] {
        let r = pair_residual(x, 0.0, x, t, white(), DEFAULT_MIN_COS).unwrap();
        assert!(
            r.xyz1.iter().chain(&r.xyz2).all(|v| v.is_finite()),
            "{t}: {r:?}"
        );
        assert!(r.diff.de76.is_finite() && r.diff.de2000.is_finite());
    }
    // exactly 90° (cos = 6e-17) and beyond are refused with a typed error
    for t in [90.0, 89.95, 95.0] {
        let e = pair_residual(x, 30.0, x, t, white(), DEFAULT_MIN_COS).unwrap_err();
        assert!(matches!(e, PairError::Grazing { .. }), "{t}: {e}");
    }
    // the factor √(c2/c1) is symmetric: swapping the pair swaps the results
    let a = recorrect(
        [1.0, 2.0, 3.0],
        10.0,
        [4.0, 5.0, 6.0],
        80.0,
        DEFAULT_MIN_COS,
    )
    .unwrap();
    let b = recorrect(
        [4.0, 5.0, 6.0],
        80.0,
        [1.0, 2.0, 3.0],
        10.0,
        DEFAULT_MIN_COS,
    )
    .unwrap();
    assert_eq!(a.0, b.1);
    assert_eq!(a.1, b.0);
}

#[test]
fn near_black_pairs_score_small_finite_differences() {
    let r = pair_residual(
        [1e-9, 1e-9, 1e-9],
        30.0,
        [2e-9, 2e-9, 2e-9],
        45.0,
        white(),
        DEFAULT_MIN_COS,
    )
    .unwrap();
    assert!(
        r.diff.de76 < 1e-4
            && r.diff.de2000 < 1e-4
            && r.diff.dh.is_finite()
            && r.diff.dc.is_finite()
    );
    let zero = pair_residual([0.0; 3], 30.0, [0.0; 3], 45.0, white(), DEFAULT_MIN_COS).unwrap();
    assert_eq!(zero.diff.de76, 0.0);
    assert_eq!(zero.diff.de2000, 0.0);
}

#[test]
fn non_finite_colours_are_refused() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let e = pair_residual(
            [bad, 1.0, 1.0],
            30.0,
            [1.0; 3],
            30.0,
            white(),
            DEFAULT_MIN_COS,
        )
        .unwrap_err();
        assert!(matches!(e, PairError::NotFinite(_)));
    }
}

#[test]
fn table2_quantities_for_a_known_pair() {
    // a 10 % brighter partner: |ΔY| = 10 % of Y after re-correction at equal angles
    let r = pair_residual(
        [40.0, 50.0, 60.0],
        45.0,
        [44.0, 55.0, 66.0],
        45.0,
        white(),
        DEFAULT_MIN_COS,
    )
    .unwrap();
    assert!((r.diff.abs_dxyz[1] - 5.0).abs() < 1e-12);
    assert!(r.diff.de76 > 3.0 && r.diff.de76 < 6.0, "{}", r.diff.de76);
    // a pure scale barely changes hue
    assert!(r.diff.dh < 0.2 * r.diff.de76);
}
