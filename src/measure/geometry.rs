//! Directions on the sample's hemisphere, the mirror direction, and the paper's extended
//! concentric square ↔ sphere map (Section 5.3), rotated so that the square's centre lands on the
//! mirror direction.
//!
//! Sample frame: z is the sample normal, θ is measured from +z, φ from +x towards +y.
//! Angles are radians in this module unless a name ends in `_deg`.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

pub type Vec3 = Vector3<f64>;

/// Below this sin θ a direction is treated as the pole and its azimuth as undefined (φ = 0).
pub(crate) const POLE_EPS: f64 = 1e-12;

/// A vector of any length prepared for angle computations.
enum Scaled {
    /// All components zero (of either sign).
    Zero,
    /// A NaN or infinite component: no direction.
    NotFinite,
    /// The same direction with its largest component in [2⁻²⁵⁰, 2²⁵⁰].
    Direction(Vec3),
}

/// `v` multiplied by powers of two until its largest component lies in [2⁻²⁵⁰, 2²⁵⁰], where
/// squares, norms and the products of two such vectors neither overflow nor underflow. A vector
/// already there is returned unchanged, and the scaling is exact, so ordinary vectors give
/// exactly the angles they always gave.
fn scaled(v: &Vec3) -> Scaled {
    const HI: f64 = f64::from_bits((1023 + 250) << 52); // 2^250
    const LO: f64 = f64::from_bits((1023 - 250) << 52); // 2^-250
    const DOWN: f64 = f64::from_bits((1023 - 300) << 52); // 2^-300
    const UP: f64 = f64::from_bits((1023 + 300) << 52); // 2^300
    if !v.iter().all(|c| c.is_finite()) {
        return Scaled::NotFinite;
    }
    let mut v = *v;
    let mut m = v.amax();
    if m == 0.0 {
        return Scaled::Zero;
    }
    // at most three steps each way: 2^1024 and 2^-1074 bound a finite non-zero component
    while m > HI {
        v *= DOWN;
        m *= DOWN;
    }
    while m < LO {
        v *= UP;
        m *= UP;
    }
    Scaled::Direction(v)
}

/// A direction in spherical angles (radians).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spherical {
    pub theta: f64,
    pub phi: f64,
}

impl Spherical {
    pub fn from_deg(theta_deg: f64, phi_deg: f64) -> Self {
        Spherical {
            theta: theta_deg.to_radians(),
            phi: phi_deg.to_radians(),
        }
    }
    pub fn theta_deg(&self) -> f64 {
        self.theta.to_degrees()
    }
    pub fn phi_deg(&self) -> f64 {
        self.phi.to_degrees()
    }
    pub fn to_vector(self) -> Vec3 {
        let (st, ct) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        Vec3::new(st * cp, st * sp, ct)
    }
    /// Angles of a vector of any length (it need not be normalised). θ uses atan2 so it is
    /// accurate at the pole and at grazing angles; φ ∈ [0, 2π), and 0 at the poles.
    ///
    /// Tiny and huge vectors (subnormal components up to `f64::MAX`) give the angles of their
    /// direction: the vector is scaled by a power of two first. The zero vector (of either sign
    /// in any component) is taken as the north pole, θ = φ = 0. A vector with a NaN or infinite
    /// component has no direction: θ = φ = NaN, which every range check refuses.
    pub fn from_vector(v: &Vec3) -> Self {
        let v = match scaled(v) {
            Scaled::Zero => {
                return Spherical {
                    theta: 0.0,
                    phi: 0.0,
                }
            }
            Scaled::NotFinite => {
                return Spherical {
                    theta: f64::NAN,
                    phi: f64::NAN,
                }
            }
            Scaled::Direction(v) => v,
        };
        let rho = v.x.hypot(v.y);
        let theta = rho.atan2(v.z);
        let norm = v.norm();
        let phi = if rho <= POLE_EPS * norm {
            0.0
        } else {
            wrap_2pi(v.y.atan2(v.x))
        };
        Spherical { theta, phi }
    }
}

/// Wrap an angle into [0, 2π).
pub fn wrap_2pi(a: f64) -> f64 {
    let r = a.rem_euclid(2.0 * PI);
    if r >= 2.0 * PI {
        0.0
    } else {
        r
    }
}

/// Wrap an angle in degrees into [0, 360).
pub(crate) fn wrap_360(a: f64) -> f64 {
    let r = a.rem_euclid(360.0);
    if r >= 360.0 {
        0.0
    } else {
        r
    }
}

/// |φ₁ − φ₂| wrapped into [0, 180] degrees.
pub fn azimuth_difference_deg(phi1_deg: f64, phi2_deg: f64) -> f64 {
    let d = wrap_360(phi1_deg - phi2_deg);
    if d > 180.0 {
        360.0 - d
    } else {
        d
    }
}

/// The ideal mirror direction of `omega` about the sample normal z: (−x, −y, z).
pub fn mirror(omega: &Vec3) -> Vec3 {
    Vec3::new(-omega.x, -omega.y, omega.z)
}

/// Angle between two vectors (radians), accurate for nearly parallel and antiparallel vectors,
/// for vectors of any length (each is scaled by a power of two first). 0 when either is the zero
/// vector; NaN when either has a NaN or infinite component.
pub fn angle_between(a: &Vec3, b: &Vec3) -> f64 {
    match (scaled(a), scaled(b)) {
        (Scaled::Direction(a), Scaled::Direction(b)) => a.cross(&b).norm().atan2(a.dot(&b)),
        (Scaled::NotFinite, _) | (_, Scaled::NotFinite) => f64::NAN,
        _ => 0.0,
    }
}

// ---------------------------------------------------------------------------------------------
// Concentric maps
// ---------------------------------------------------------------------------------------------

/// Shirley–Chiu concentric map from the unit square [0,1]² to the unit disc.
pub fn square_to_disc(u: f64, v: f64) -> (f64, f64) {
    let a = 2.0 * u - 1.0;
    let b = 2.0 * v - 1.0;
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
    };
    (r * phi.cos(), r * phi.sin())
}

/// Inverse of [`square_to_disc`] (as in pbrt-v4 and Mitsuba 3).
pub fn disc_to_square(x: f64, y: f64) -> (f64, f64) {
    let r = x.hypot(y);
    if r == 0.0 {
        return (0.5, 0.5);
    }
    let mut phi = y.atan2(x);
    if phi < -FRAC_PI_4 {
        phi += 2.0 * PI;
    }
    let (a, b) = if phi < FRAC_PI_4 {
        (r, phi * r / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        ((FRAC_PI_2 - phi) * r / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        (-r, (phi - PI) * -r / FRAC_PI_4)
    } else {
        ((3.0 * FRAC_PI_2 - phi) * -r / FRAC_PI_4, -r)
    };
    ((a + 1.0) / 2.0, (b + 1.0) / 2.0)
}

/// Equal-area map from the unit disc to the upper hemisphere: z = 1 − r², (x, y)·√(2 − r²).
pub fn disc_to_hemisphere(x: f64, y: f64) -> Vec3 {
    let r2 = x * x + y * y;
    let s = (2.0 - r2).max(0.0).sqrt();
    Vec3::new(x * s, y * s, 1.0 - r2)
}

/// The paper's extended concentric map from the unit square to the whole sphere: the square's
/// centre goes to the north pole, its edges to the south pole.
///
/// The paper's two stages (r_A < 1/√2: r_B = √2·r_A to the upper hemisphere; otherwise
/// r_B = √(2(1 − r_A²)) to the lower one, with the slip in the text corrected) collapse into one
/// closed form, z = 1 − 2r_A² and (x, y) scaled by 2√(1 − r_A²): the Lambert azimuthal
/// equal-area projection of the disc. The tests check the two agree.
pub fn square_to_sphere(u: f64, v: f64) -> Vec3 {
    let (x, y) = square_to_disc(u, v);
    let ra2 = (x * x + y * y).min(1.0);
    let s = 2.0 * (1.0 - ra2).sqrt();
    Vec3::new(x * s, y * s, 1.0 - 2.0 * ra2)
}

/// Inverse of [`square_to_sphere`] for the direction of a vector of any length (scaled by a
/// power of two first, so tiny and huge vectors map as their direction). The south pole (a
/// single point, the map's one discontinuity) maps to the square's corner (0, 0). The zero
/// vector maps to the centre (½, ½), the north pole as in [`Spherical::from_vector`]; a vector
/// with a NaN or infinite component to (NaN, NaN).
pub fn sphere_to_square(d: &Vec3) -> (f64, f64) {
    let d = match scaled(d) {
        Scaled::Zero => return (0.5, 0.5),
        Scaled::NotFinite => return (f64::NAN, f64::NAN),
        Scaled::Direction(d) => d,
    };
    let n = d.norm();
    let (x, y, z) = (d.x / n, d.y / n, d.z / n);
    let rho2 = x * x + y * y;
    // r_A² = (1 − z)/2, evaluated without cancellation near the north pole.
    let one_minus_z = if z > 0.0 { rho2 / (1.0 + z) } else { 1.0 - z };
    let ra = (one_minus_z / 2.0).clamp(0.0, 1.0).sqrt();
    let rho = rho2.sqrt();
    if rho == 0.0 {
        return if z > 0.0 { (0.5, 0.5) } else { (0.0, 0.0) };
    }
    disc_to_square(x / rho * ra, y / rho * ra)
}

/// The rotation that takes the north pole (0, 0, 1) to `target`.
///
/// For targets in the upper hemisphere (z ≥ 0, where every mirror direction lies) this is the
/// shortest-arc rotation, Rodrigues' formula with 1/(1 + cos) ∈ [½, 1]: exact at the north pole
/// and smooth over the whole upper hemisphere. For z < 0 it is the shortest-arc rotation to −t
/// composed with a half turn about x, so 1/(1 + cos) never exceeds 1 and the result stays
/// orthonormal to rounding even at and next to the south pole.
///
/// `target` may have any length (it is scaled by a power of two before it is normalised). The
/// zero vector is taken as the north pole (the identity, as in [`Spherical::from_vector`]); a
/// target with a NaN or infinite component gives a NaN matrix.
pub fn rotation_pole_to(target: &Vec3) -> Matrix3<f64> {
    let t = match scaled(target) {
        Scaled::Zero => return Matrix3::identity(),
        Scaled::NotFinite => return Matrix3::from_element(f64::NAN),
        Scaled::Direction(t) => t.normalize(),
    };
    if t.z >= 0.0 {
        shortest_arc_from_pole(&t)
    } else {
        let half_turn_x = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
        shortest_arc_from_pole(&(-t)) * half_turn_x
    }
}

/// Shortest-arc rotation z → t for a unit t with t.z ≥ 0.
fn shortest_arc_from_pole(t: &Vec3) -> Matrix3<f64> {
    let c = t.z;
    // k = z × t = (−t.y, t.x, 0); R = I + [k]× + [k]×² / (1 + c)
    let (kx, ky) = (-t.y, t.x);
    let k = Matrix3::new(0.0, 0.0, ky, 0.0, 0.0, -kx, -ky, kx, 0.0);
    Matrix3::identity() + k + k * k / (1.0 + c)
}

/// The paper's resampling parameterisation for one incoming direction: (x, y) ∈ [0,1]² where
/// (½, ½) is the mirror direction of ωᵢ and the square's edges are its antipode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MirrorAlignedMap {
    rot: Matrix3<f64>,
}

impl MirrorAlignedMap {
    pub fn new(omega_i: &Vec3) -> Self {
        MirrorAlignedMap {
            rot: rotation_pole_to(&mirror(omega_i)),
        }
    }
    /// Square → outgoing direction.
    pub fn direction(&self, x: f64, y: f64) -> Vec3 {
        self.rot * square_to_sphere(x, y)
    }
    /// Outgoing direction → square.
    pub fn square(&self, omega_o: &Vec3) -> (f64, f64) {
        sphere_to_square(&(self.rot.transpose() * omega_o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spherical_round_trip_and_poles() {
        for (t, p) in [
            (0.0, 0.0),
            (15.0, 60.0),
            (75.0, 345.0),
            (89.9, 180.0),
            (90.0, 270.0),
        ] {
            let s = Spherical::from_deg(t, p);
            let back = Spherical::from_vector(&s.to_vector());
            assert!((back.theta_deg() - t).abs() < 1e-12);
            if t > 0.0 {
                assert!((wrap_360(back.phi_deg() - p + 180.0) - 180.0).abs() < 1e-9);
            } else {
                assert_eq!(back.phi, 0.0);
            }
        }
    }

    #[test]
    fn azimuth_difference_wraps() {
        assert_eq!(azimuth_difference_deg(350.0, 10.0), 20.0);
        assert_eq!(azimuth_difference_deg(10.0, 350.0), 20.0);
        assert_eq!(azimuth_difference_deg(0.0, 180.0), 180.0);
        assert_eq!(azimuth_difference_deg(-90.0, 90.0), 180.0);
    }

    #[test]
    fn rotation_is_orthonormal_and_hits_target() {
        for t in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1e-9, 0.0, 1.0),
            Vec3::new(0.3, -0.2, 0.9),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1e-7, 1e-7, -1.0),
            Vec3::new(0.0, 0.0, -1.0),
        ] {
            let r = rotation_pole_to(&t);
            let should_be_i = r.transpose() * r;
            assert!((should_be_i - Matrix3::identity()).norm() < 1e-12);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            assert!((r * Vec3::z() - t.normalize()).norm() < 1e-12, "{t:?}");
        }
    }
}
