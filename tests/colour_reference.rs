//! Colour against published references: Sharma's CIEDE2000 pairs, the CIE 1931 / D65 tables,
//! and the numerically awkward cases (near-black, zero chroma, hue wrap-around).

mod common;
use common::csv_rows;
use goniowatch::fixtures::Rng;
use goniowatch::measure::colour::*;

#[test]
fn ciede2000_sharma_all_34_pairs_both_orders() {
    let rows = csv_rows("ciede2000_sharma.csv");
    assert_eq!(rows.len(), 34);
    for (i, r) in rows.iter().enumerate() {
        let a = Lab::new(r[0], r[1], r[2]);
        let b = Lab::new(r[3], r[4], r[5]);
        let want = r[6];
        let d1 = ciede2000(a, b);
        let d2 = ciede2000(b, a);
        assert!((d1 - want).abs() < 1e-4, "pair {}: {d1} vs {want}", i + 1);
        assert!(
            (d2 - want).abs() < 1e-4,
            "pair {} reversed: {d2} vs {want}",
            i + 1
        );
    }
}

#[test]
fn ciede2000_is_symmetric_and_zero_on_identity() {
    let mut rng = Rng(7);
    for _ in 0..20_000 {
        let a = Lab::new(
            rng.range(0.0, 100.0),
            rng.range(-128.0, 128.0),
            rng.range(-128.0, 128.0),
        );
        let b = Lab::new(
            rng.range(0.0, 100.0),
            rng.range(-128.0, 128.0),
            rng.range(-128.0, 128.0),
        );
        let (d1, d2) = (ciede2000(a, b), ciede2000(b, a));
        assert!(d1.is_finite() && d1 >= 0.0);
        assert!(
            (d1 - d2).abs() <= 1e-10 * d1.max(1.0),
            "{a:?} {b:?}: {d1} vs {d2}"
        );
        assert_eq!(ciede2000(a, a), 0.0);
        assert!((delta_e76(a, b) - delta_e76(b, a)).abs() < 1e-12);
        assert!((delta_h76(a, b) + delta_h76(b, a)).abs() < 1e-9);
        // ΔE² = ΔL² + ΔC² + ΔH² for CIE 1976
        let (dl, dc, dh) = (b.l - a.l, delta_c76(a, b), delta_h76(a, b));
        let de = delta_e76(a, b);
        assert!(((dl * dl + dc * dc + dh * dh).sqrt() - de).abs() < 1e-9 * de.max(1.0));
    }
}

#[test]
fn ciede2000_zero_chroma_branches() {
    // C'1·C'2 = 0: Δh' = 0 and h̄' = h'1 + h'2 (Sharma eq. 14's first case)
    let grey = Lab::new(50.0, 0.0, 0.0);
    let grey2 = Lab::new(60.0, 0.0, 0.0);
    let d = ciede2000(grey, grey2);
    // only the lightness term remains: ΔL'/S_L
    let l50: f64 = (55.0f64 - 50.0).powi(2);
    let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    assert!((d - 10.0 / sl).abs() < 1e-12);
    // one neutral, one chromatic: finite, symmetric
    let red = Lab::new(50.0, 30.0, 0.0);
    assert!((ciede2000(grey, red) - ciede2000(red, grey)).abs() < 1e-12);
    assert!(ciede2000(grey, red).is_finite());
}

#[test]
fn hue_wrap_around_at_0_and_360() {
    let c = 20.0;
    let at = |h: f64| Lab::new(50.0, c * h.to_radians().cos(), c * h.to_radians().sin());
    // two colours straddling h = 0 are as close as the same hue step elsewhere on the circle
    let straddle = ciede2000(at(359.5), at(0.5));
    let plain = ciede2000(at(10.0), at(11.0));
    assert!(straddle < 0.5, "{straddle}");
    assert!(
        (straddle / plain - 1.0).abs() < 0.2,
        "{straddle} vs {plain}"
    );
    // exactly 180° apart (|h1 - h2| = 180 branch) in both orders, and the mean-hue branches
    let opp = ciede2000(at(90.0), at(270.0));
    assert!((opp - ciede2000(at(270.0), at(90.0))).abs() < 1e-12);
    assert!(opp > 10.0);
    for (h1, h2) in [
        (350.0, 20.0),
        (20.0, 350.0),
        (200.0, 10.0),
        (10.0, 200.0),
        (0.0, 180.0),
        (180.0, 0.0),
    ] {
        let d = ciede2000(at(h1), at(h2));
        assert!(d.is_finite() && (d - ciede2000(at(h2), at(h1))).abs() < 1e-12);
    }
    // hue angle of a colour just below the positive a axis wraps to just under 360
    assert!((Lab::new(50.0, 10.0, -1e-9).hue_deg() - 360.0).abs() < 1e-6);
    assert_eq!(Lab::new(50.0, 0.0, 0.0).hue_deg(), 0.0);
}

#[test]
fn lab_is_continuous_at_the_knee_and_finite_near_black() {
    let w = White::d65_scaled(100.0).unwrap();
    let knee = (6.0f64 / 29.0).powi(3) * 100.0;
    let below = xyz_to_lab([95.047, knee * (1.0 - 1e-12), 108.883], w);
    let above = xyz_to_lab([95.047, knee * (1.0 + 1e-12), 108.883], w);
    assert!((below.l - above.l).abs() < 1e-9);
    assert!(
        (xyz_to_lab([0.0, knee, 0.0], w).l - 8.0).abs() < 1e-12,
        "L* = 8 at the knee"
    );
    // slope continuity: the linear segment's slope equals the cube root's at the knee
    let h = knee * 1e-6;
    let s_lo = (xyz_to_lab([0.0, knee, 0.0], w).l - xyz_to_lab([0.0, knee - h, 0.0], w).l) / h;
    let s_hi = (xyz_to_lab([0.0, knee + h, 0.0], w).l - xyz_to_lab([0.0, knee, 0.0], w).l) / h;
    assert!((s_lo / s_hi - 1.0).abs() < 1e-4);
    // near black, zero and slightly negative values stay finite and ordered
    let zero = xyz_to_lab([0.0, 0.0, 0.0], w);
    assert_eq!((zero.l, zero.a, zero.b), (0.0, 0.0, 0.0));
    let tiny = xyz_to_lab([1e-9, 1e-9, 1e-9], w);
    assert!(tiny.l > 0.0 && tiny.l < 1e-5);
    let neg = xyz_to_lab([-1e-3, -1e-3, -1e-3], w);
    assert!(neg.l < 0.0 && neg.l.is_finite());
    let d = colour_difference([1e-6, 1e-6, 1e-6], [2e-6, 2e-6, 2e-6], w);
    assert!(d.de76 < 1e-3 && d.de2000 < 1e-3 && d.dh.is_finite());
}

#[test]
fn d65_white_from_the_cie_tables() {
    // CIE 15:2004 / ASTM E308: D65, 2° observer: (95.047, 100.000, 108.883)
    let full = bands(380.0, 5.0, 81);
    let s = SpectralToXyz::d65(&full).unwrap();
    let w = s.white();
    assert!((w[1] - 100.0).abs() < 1e-12);
    assert!((w[0] - 95.047).abs() < 0.01, "{w:?}");
    assert!((w[2] - 108.883).abs() < 0.01, "{w:?}");
    // reflectance 1 everywhere is the white
    let xyz = s.convert(&vec![1.0; 81]).unwrap();
    for c in 0..3 {
        assert!((xyz[c] - w[c]).abs() < 1e-9);
    }
    // the 30 bands of the Integra data (400–690 nm): the white is D65-like
    let s30 = SpectralToXyz::d65(&bands(400.0, 10.0, 30)).unwrap();
    let w30 = s30.white();
    assert!((w30[1] - 100.0).abs() < 1e-12);
    assert!(
        (w30[0] / 95.047 - 1.0).abs() < 0.02 && (w30[2] / 108.883 - 1.0).abs() < 0.02,
        "{w30:?}"
    );
    // wrong lengths and bad band sets are typed errors
    assert_eq!(
        s30.convert(&[1.0; 29]),
        Err(ColourError::SpectrumLength {
            expected: 30,
            got: 29
        })
    );
    assert!(matches!(
        SpectralToXyz::d65(&[400.0, 400.0]),
        Err(ColourError::BandsNotIncreasing { .. })
    ));
    assert!(matches!(
        SpectralToXyz::d65(&[300.0]),
        Err(ColourError::BandOutOfRange { .. })
    ));
    assert_eq!(SpectralToXyz::d65(&[]), Err(ColourError::NoBands));
}

#[test]
fn ten_nm_table_agrees_with_the_interpolated_five_nm_table() {
    let ten = parse_observer_table(
        &std::fs::read_to_string(common::reference("cmf1931_d65_10nm.csv")).unwrap(),
    )
    .unwrap();
    let wl: Vec<f64> = ten.iter().map(|r| r.wavelength).collect();
    let a = SpectralToXyz::with_table(&wl, &ten).unwrap();
    let b = SpectralToXyz::d65(&wl).unwrap();
    assert_eq!(a.white(), b.white());
    // a smooth reflectance gives the same XYZ from either table
    let refl: Vec<f64> = wl
        .iter()
        .map(|l| 0.2 + 0.6 * ((l - 400.0) / 300.0))
        .collect();
    assert_eq!(a.convert(&refl).unwrap(), b.convert(&refl).unwrap());
}

#[test]
fn spectral_and_rgb_paths_agree_on_white() {
    // sRGB (1,1,1) scaled to Y = 100 is the D65 white within the IEC matrix's rounding
    let xyz = RgbToXyz::new(RgbPrimaries::SrgbIec).convert([100.0, 100.0, 100.0]);
    let d65 = White::d65_scaled(100.0).unwrap().xyz();
    for c in 0..3 {
        assert!((xyz[c] - d65[c]).abs() < 0.01, "{xyz:?} vs {d65:?}");
    }
    // the paper's slip: 0.4142 would put X of the white 0.18 off
    assert_eq!(RgbToXyz::new(RgbPrimaries::SrgbIec).matrix()[0][0], 0.4124);
}
