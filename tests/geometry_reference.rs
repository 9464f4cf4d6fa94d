//! Geometry against the renderers' concentric-map values, and the paper's extended
//! square ↔ sphere map: round trips, equal area, continuity, and the mirror alignment near poles.

mod common;
use common::csv_rows;
use goniowatch::fixtures::Rng;
use goniowatch::measure::geometry::*;
use std::f64::consts::FRAC_1_SQRT_2;

#[test]
fn concentric_anchors_from_pbrt_and_mitsuba() {
    let rows = csv_rows("concentric_anchors.csv");
    assert_eq!(rows.len(), 17);
    for r in rows {
        let (u, v) = (r[0], r[1]);
        let (x, y) = square_to_disc(u, v);
        assert!(
            (x - r[2]).abs() < 1e-11 && (y - r[3]).abs() < 1e-11,
            "({u},{v}) -> ({x},{y})"
        );
        assert!((x.hypot(y) - r[4]).abs() < 1e-11);
        let (iu, iv) = disc_to_square(r[2], r[3]);
        for (ref_u, ref_v) in [(r[5], r[6]), (r[7], r[8])] {
            assert!(
                (iu - ref_u).abs() < 1e-11 && (iv - ref_v).abs() < 1e-11,
                "inverse of ({u},{v}) = ({iu},{iv})"
            );
        }
        let h = disc_to_hemisphere(r[2], r[3]);
        assert!(
            (h.x - r[9]).abs() < 1e-11
                && (h.y - r[10]).abs() < 1e-11
                && (h.z - r[11]).abs() < 1e-11
        );
    }
}

/// The paper's two-stage description, written out literally (with the r_B slip corrected).
fn paper_square_to_sphere(u: f64, v: f64) -> Vec3 {
    let (x, y) = square_to_disc(u, v);
    let ra = x.hypot(y);
    if ra == 0.0 {
        return Vec3::new(0.0, 0.0, 1.0);
    }
    let (dx, dy) = (x / ra, y / ra);
    if ra < FRAC_1_SQRT_2 {
        let rb = 2f64.sqrt() * ra;
        let h = disc_to_hemisphere(dx * rb, dy * rb);
        h
    } else {
        let rb = (2.0 * (1.0 - ra * ra)).max(0.0).sqrt();
        let h = disc_to_hemisphere(dx * rb, dy * rb);
        Vec3::new(h.x, h.y, -h.z)
    }
}

#[test]
fn extended_map_equals_the_papers_two_stage_form_and_is_continuous() {
    let mut rng = Rng(1);
    for _ in 0..50_000 {
        let (u, v) = (rng.uniform(), rng.uniform());
        let a = square_to_sphere(u, v);
        let b = paper_square_to_sphere(u, v);
        assert!((a - b).norm() < 1e-12, "({u},{v})");
        assert!((a.norm() - 1.0).abs() < 1e-12);
    }
    // centre → north pole, every edge point → south pole, r_A = 1/√2 → equator
    assert!((square_to_sphere(0.5, 0.5) - Vec3::z()).norm() < 1e-15);
    for t in [0.0, 0.1, 0.5, 0.9, 1.0] {
        for (u, v) in [(t, 0.0), (t, 1.0), (0.0, t), (1.0, t)] {
            assert!(
                (square_to_sphere(u, v) + Vec3::z()).norm() < 1e-7,
                "({u},{v})"
            );
        }
    }
    let (u_eq, v_eq) = disc_to_square(FRAC_1_SQRT_2, 0.0);
    assert!(square_to_sphere(u_eq, v_eq).z.abs() < 1e-12);
    // continuity across the r_A = 1/√2 seam
    let below = square_to_sphere(disc_to_square(FRAC_1_SQRT_2 - 1e-9, 0.0).0, 0.5);
    let above = square_to_sphere(disc_to_square(FRAC_1_SQRT_2 + 1e-9, 0.0).0, 0.5);
    assert!((below - above).norm() < 1e-8);
}

#[test]
fn extended_map_round_trips() {
    let mut rng = Rng(2);
    for _ in 0..50_000 {
        // stay off the square's boundary, which maps to the single south-pole point
        let (u, v) = (rng.range(1e-6, 1.0 - 1e-6), rng.range(1e-6, 1.0 - 1e-6));
        let d = square_to_sphere(u, v);
        let (u2, v2) = sphere_to_square(&d);
        assert!(
            (u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9,
            "({u},{v}) -> ({u2},{v2})"
        );
    }
    // near the north pole the inverse has no cancellation
    let d = square_to_sphere(0.5 + 1e-9, 0.5);
    let (u2, _) = sphere_to_square(&d);
    assert!((u2 - (0.5 + 1e-9)).abs() < 1e-15);
}

#[test]
fn extended_map_is_equal_area() {
    // Jacobian: |∂d/∂u × ∂d/∂v| = 4π everywhere (sphere area over the unit square's area)
    let mut rng = Rng(3);
    let h = 1e-6;
    for _ in 0..5_000 {
        let (u, v) = (rng.range(0.01, 0.99), rng.range(0.01, 0.99));
        // skip the diagonals where the concentric map's wedges meet (measure zero)
        if ((u - 0.5).abs() - (v - 0.5).abs()).abs() < 1e-3 {
            continue;
        }
        let du = (square_to_sphere(u + h, v) - square_to_sphere(u - h, v)) / (2.0 * h);
        let dv = (square_to_sphere(u, v + h) - square_to_sphere(u, v - h)) / (2.0 * h);
        let area = du.cross(&dv).norm();
        assert!(
            (area / (4.0 * std::f64::consts::PI) - 1.0).abs() < 1e-4,
            "({u},{v}): {area}"
        );
    }
    // Monte Carlo (Archimedes): uniform points on the square give uniform z on [-1, 1]
    let mut rng = Rng(4);
    let n = 200_000;
    let mut bins = [0usize; 20];
    for _ in 0..n {
        let z = square_to_sphere(rng.uniform(), rng.uniform()).z;
        bins[(((z + 1.0) / 2.0 * 20.0) as usize).min(19)] += 1;
    }
    let expected = n as f64 / 20.0;
    for b in bins {
        assert!(
            (b as f64 - expected).abs() < 5.0 * expected.sqrt(),
            "{bins:?}"
        );
    }
}

#[test]
fn mirror_aligned_map_is_stable_at_and_near_both_poles() {
    // ωi at the pole (mirror at the north pole), near it, at grazing (mirror at the equator),
    // and a mirror direction forced near the south pole by the rotation helper
    for theta_deg in [0.0, 1e-10, 1e-6, 0.01, 15.0, 45.0, 75.0, 89.9, 90.0] {
        for phi_deg in [0.0, 37.0, 180.0, 359.999] {
            let wi = Spherical::from_deg(theta_deg, phi_deg).to_vector();
            let m = MirrorAlignedMap::new(&wi);
            let centre = m.direction(0.5, 0.5);
            assert!(
                (centre - mirror(&wi)).norm() < 1e-12,
                "θ={theta_deg} φ={phi_deg}"
            );
            let edge = m.direction(0.0, 0.3);
            assert!((edge + mirror(&wi)).norm() < 1e-7);
            let mut rng = Rng(5);
            for _ in 0..200 {
                let (x, y) = (rng.range(0.01, 0.99), rng.range(0.01, 0.99));
                let d = m.direction(x, y);
                assert!((d.norm() - 1.0).abs() < 1e-12);
                let (x2, y2) = m.square(&d);
                assert!((x - x2).abs() < 1e-9 && (y - y2).abs() < 1e-9);
            }
        }
    }
    // the map is continuous in ωi through the pole: nearby ωi give nearby maps
    let a = MirrorAlignedMap::new(&Spherical::from_deg(1e-7, 0.0).to_vector());
    let b = MirrorAlignedMap::new(&Spherical::from_deg(0.0, 0.0).to_vector());
    for (x, y) in [(0.2, 0.3), (0.7, 0.6), (0.5, 0.9)] {
        assert!((a.direction(x, y) - b.direction(x, y)).norm() < 1e-8);
    }
    // south pole: the rotation stays a proper rotation
    for z in [-1.0f64, -1.0 + 1e-13, -0.999999] {
        let t = Vec3::new((1.0 - z * z).max(0.0).sqrt(), 0.0, z);
        let r = rotation_pole_to(&t);
        assert!((r * Vec3::z() - t.normalize()).norm() < 1e-6);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn grazing_directions_keep_accurate_angles() {
    for t in [75.0, 89.9, 90.0] {
        let s = Spherical::from_deg(t, 123.0);
        let back = Spherical::from_vector(&s.to_vector());
        assert!((back.theta_deg() - t).abs() < 1e-12);
    }
    // angle_between is accurate for nearly parallel vectors (acos would lose it)
    let a = Spherical::from_deg(30.0, 10.0).to_vector();
    let b = Spherical::from_deg(30.0 + 1e-7, 10.0).to_vector();
    assert!((angle_between(&a, &b).to_degrees() - 1e-7).abs() < 1e-12);
}
