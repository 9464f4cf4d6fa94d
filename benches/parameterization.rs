//! Benchmark for the paper's claim (Section 5.3): interpolating a glossy BRDF in the extended
//! concentric map aligned with the mirror direction beats plain (θ, φ) coordinates.
//!
//! For incidence θi ∈ {15, 30, 45, 60}° (φi = 0), the 81 UBO outgoing directions carry the
//! measured quantity f_r · cos θi of the simulator's glossy "walkway" BRDF (Lambert + GGX with
//! Smith masking and Schlick Fresnel, α = 0.15). A cubic Shepard interpolant (NC 17, NW 30) is
//! built over (a) (θo/90°, φo/360°) and (b) the mirror-aligned square (x, y); both are evaluated
//! on 20,000 random directions with θo ≤ 75°, and near the mirror direction (within 15°).
//!
//! Run: `cargo bench --bench parameterization`

use goniowatch::measure::geometry::{MirrorAlignedMap, Spherical, Vec3};
use goniowatch::measure::plan::SamplingPlan;
use goniowatch::measure::shepard::Shepard;

const F0: f64 = 0.045;

/// (name, diffuse albedo, specular weight, GGX α): the simulator's walkway and pinkwall presets.
const MATERIALS: [(&str, f64, f64, f64); 2] = [
    ("walkway", 0.36, 0.10, 0.15),
    ("pinkwall", 0.54, 0.12, 0.08),
];

fn brdf(m: (f64, f64, f64), wi: &Vec3, wo: &Vec3) -> f64 {
    let (albedo, ks, alpha) = m;
    let (ci, co) = (wi.z, wo.z);
    if ci <= 0.0 || co <= 0.0 {
        return 0.0;
    }
    let h = (wi + wo).normalize();
    let a2 = alpha * alpha;
    let d = a2 / (std::f64::consts::PI * (h.z * h.z * (a2 - 1.0) + 1.0).powi(2));
    let g1 = |c: f64| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
    let f = F0 + (1.0 - F0) * (1.0 - h.dot(wi)).powi(5);
    albedo / std::f64::consts::PI + ks * d * g1(ci) * g1(co) * f / (4.0 * ci * co)
}

fn main() {
    let plan = SamplingPlan::ubo();
    let dirs: Vec<Vec3> = plan
        .directions()
        .iter()
        .map(|d| d.spherical().to_vector())
        .collect();
    let mut seed = 7u64;
    let mut u = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    // random directions, uniform on the cap θ ≤ 75°
    let cmin = 75f64.to_radians().cos();
    let tests: Vec<Vec3> = (0..20_000)
        .map(|_| {
            let z = cmin + (1.0 - cmin) * u();
            let phi = 2.0 * std::f64::consts::PI * u();
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect();
    println!("| material | θi | parameterization | RMS rel. error (all) | max rel. error (all) | RMS rel. error near mirror | outside radii |");
    println!("|---|---|---|---|---|---|---|");
    for (mname, albedo, ks, alpha) in MATERIALS {
        for theta_i in [15.0, 30.0, 45.0, 60.0] {
            let wi = Spherical::from_deg(theta_i, 0.0).to_vector();
            let value = |wo: &Vec3| brdf((albedo, ks, alpha), &wi, wo) * wi.z;
            let f: Vec<f64> = dirs.iter().map(&value).collect();
            let map = MirrorAlignedMap::new(&wi);
            let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
            type Coord = Box<dyn Fn(&Vec3) -> [f64; 2]>;
            let coords: [(&str, Coord); 2] = [
                (
                    "(θ, φ)",
                    Box::new(|w: &Vec3| {
                        let s = Spherical::from_vector(w);
                        [s.theta_deg() / 90.0, s.phi_deg() / 360.0]
                    }),
                ),
                (
                    "mirror-aligned square",
                    Box::new(move |w: &Vec3| {
                        let (x, y) = map.square(w);
                        [x, y]
                    }),
                ),
            ];
            for (name, coord) in coords.iter() {
                let pts: Vec<[f64; 2]> = dirs.iter().map(coord).collect();
                let (x, y): (Vec<f64>, Vec<f64>) = pts.iter().map(|p| (p[0], p[1])).unzip();
                let s = match Shepard::cubic_2d(&x, &y, &f, 17, 30) {
                    Ok(s) => s,
                    Err(e) => {
                        println!("| {mname} | {theta_i} | {name} | error: {e} | | | |");
                        continue;
                    }
                };
                let (mut se, mut n, mut emax, mut se_near, mut n_near, mut outside) =
                    (0.0, 0usize, 0.0f64, 0.0, 0usize, 0usize);
                for w in &tests {
                    let truth = value(w);
                    let c = coord(w);
                    match s.value(&c) {
                        Ok(v) => {
                            let e = (v - truth) / truth.max(1e-9);
                            se += e * e;
                            n += 1;
                            emax = emax.max(e.abs());
                            if w.dot(&mirror).acos().to_degrees() < 15.0 {
                                se_near += e * e;
                                n_near += 1;
                            }
                        }
                        Err(_) => outside += 1,
                    }
                }
                println!(
                    "| {mname} | {theta_i}° | {name} | {:.3} | {:.2} | {:.3} | {outside} |",
                    (se / n.max(1) as f64).sqrt(),
                    emax,
                    (se_near / n_near.max(1) as f64).sqrt()
                );
            }
        }
    }
}
