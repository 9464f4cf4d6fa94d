//! Benchmark for the paper's claim (Section 5.3): interpolating a glossy BRDF in the extended
//! concentric map aligned with the mirror direction beats plain (θ, φ) coordinates.
//!
//! For incidence θi ∈ {15, 30, 45, 60}° (φi = 0), the 81 UBO outgoing directions carry the
//! measured quantity f_r · cos θi of the simulator's glossy "walkway" BRDF (Lambert + GGX with
//! Smith masking and Schlick Fresnel, α = 0.15). A cubic Shepard interpolant (NC 17, NW 30) is
//! built over (a) (θo/90°, φo/360°) and (b) the mirror-aligned square (x, y); both are evaluated
//! on 20,000 random directions with θo ≤ 75°, and near the mirror direction (within 15°).
//!
//! Second table: across θi. The 6,561 UBO direction pairs of the same BRDFs
//! (an isotropic sample: f depends on θi, θo and φo − φi only) are interpolated at 5,000 random
//! pairs with θi, θo ≤ 75° and random azimuths by (a) QSHEP3D in plain (θi, θo, Δφ) (θi at
//! 0.001 per degree as in (b): at θi/90 the layers leave nodes with coplanar neighbours),
//! (b) QSHEP3D in the paper's (θi, x, y), (c) the layered resampler (a CSHEP2D slice per θi in
//! the mirror-aligned square, Lagrange across θi) on ln f and (d) on f. Error against the time
//! to build and to answer the 5,000 queries.
//!
//! Run: `cargo bench --bench parameterization`

use goniowatch::measure::geometry::{MirrorAlignedMap, Spherical, Vec3};
use goniowatch::measure::plan::SamplingPlan;
use goniowatch::measure::resample::{LayeredResampler, ResampleSpec, Resampler, Sample};
use goniowatch::measure::shepard::{Method, Shepard};
use std::collections::HashMap;
use std::time::Instant;

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
    let mut seed = goniowatch::fixtures::Lcg(7u64);
    let mut u = || seed.uniform();
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
    across_theta_i(&dirs, &mut u);
}

fn across_theta_i(dirs: &[Vec3], u: &mut impl FnMut() -> f64) {
    let cmin = 75f64.to_radians().cos();
    let mut rand_dir = || {
        let z = cmin + (1.0 - cmin) * u();
        let phi = 2.0 * std::f64::consts::PI * u();
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let queries: Vec<(Vec3, Vec3)> = (0..5000).map(|_| (rand_dir(), rand_dir())).collect();
    println!();
    println!("| material | method | RMS rel. error | 95th pct rel. error | max rel. error | outside | build [ms] | 5,000 queries [ms] |");
    println!("|---|---|---|---|---|---|---|---|");
    for (mname, albedo, ks, alpha) in MATERIALS {
        let f = |wi: &Vec3, wo: &Vec3| std::f64::consts::PI * brdf((albedo, ks, alpha), wi, wo);
        let samples: Vec<Sample> = dirs
            .iter()
            .flat_map(|wi| dirs.iter().map(move |wo| (*wi, *wo)))
            .map(|(wi, wo)| {
                let v = f(&wi, &wo);
                Sample {
                    omega_i: wi,
                    omega_o: wo,
                    value: [v, v, v],
                }
            })
            .collect();
        type Eval<'a> = Box<dyn Fn(&Vec3, &Vec3) -> Option<f64> + 'a>;
        let report = |name: &str, build_ms: f64, eval: Eval| {
            let t0 = Instant::now();
            let mut errs = Vec::new();
            let mut outside = 0;
            for (wi, wo) in &queries {
                match eval(wi, wo) {
                    Some(v) => {
                        let t = f(wi, wo);
                        errs.push(((v - t) / t).abs());
                    }
                    None => outside += 1,
                }
            }
            let q_ms = t0.elapsed().as_secs_f64() * 1e3;
            errs.sort_by(f64::total_cmp);
            let n = errs.len().max(1);
            let rms = (errs.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
            let p95 = errs.get(n * 95 / 100).copied().unwrap_or(f64::NAN);
            let max = errs.last().copied().unwrap_or(f64::NAN);
            println!("| {mname} | {name} | {rms:.3} | {p95:.3} | {max:.2} | {outside} | {build_ms:.0} | {q_ms:.0} |");
        };
        // (a) plain (θi, θo, Δφ), duplicates (isotropy classes) merged
        {
            let t0 = Instant::now();
            let key = |wi: &Vec3, wo: &Vec3| {
                let (si, so) = (Spherical::from_vector(wi), Spherical::from_vector(wo));
                let dphi = (so.phi_deg() - si.phi_deg()).rem_euclid(360.0);
                let dphi = if si.theta_deg() < 1e-9 || so.theta_deg() < 1e-9 {
                    0.0
                } else {
                    dphi
                };
                [si.theta_deg() * 1e-3, so.theta_deg() / 90.0, dphi / 360.0]
            };
            let mut merged: HashMap<[i64; 3], ([f64; 3], f64, usize)> = HashMap::new();
            for s in &samples {
                let p = key(&s.omega_i, &s.omega_o);
                let k = p.map(|c| (c * 1e6).round() as i64);
                let e = merged.entry(k).or_insert((p, 0.0, 0));
                e.1 += s.value[0];
                e.2 += 1;
            }
            let mut nodes: Vec<([f64; 3], f64)> = merged
                .into_values()
                .map(|(p, s, n)| (p, s / n as f64))
                .collect();
            nodes.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
            let p: Vec<[f64; 3]> = nodes.iter().map(|n| n.0).collect();
            let v: Vec<f64> = nodes.iter().map(|n| n.1).collect();
            match Shepard::fit(Method::Quadratic3, &p, &v, 17, 32) {
                Ok(sh) => {
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    report(
                        "QSHEP3D, plain (θi, θo, Δφ)",
                        ms,
                        Box::new(move |wi, wo| sh.value(&key(wi, wo)).ok()),
                    );
                }
                Err(e) => {
                    println!("| {mname} | QSHEP3D, plain (θi, θo, Δφ) | error: {e} | | | | | |")
                }
            }
        }
        // (b) the paper's (θi, x, y) in 3-D
        {
            let t0 = Instant::now();
            let spec = ResampleSpec {
                theta_per_deg: 1e-3,
                log_values: false,
                ..Default::default()
            };
            match Resampler::isotropic(&samples, &spec) {
                Ok(r) => {
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    report(
                        "QSHEP3D, (θi, x, y)",
                        ms,
                        Box::new(move |wi, wo| r.at(wi, wo).ok().map(|v| v.value[0])),
                    );
                }
                Err(e) => println!("| {mname} | QSHEP3D, (θi, x, y) | error: {e} | | | | | |"),
            }
        }
        // (c, d) layered slices in the mirror-aligned square
        for (name, log) in [
            ("layered CSHEP2D in (x, y), ln f", true),
            ("layered CSHEP2D in (x, y), f", false),
        ] {
            let t0 = Instant::now();
            let spec = ResampleSpec {
                log_values: log,
                ..Default::default()
            };
            match LayeredResampler::new(&samples, &spec) {
                Ok(r) => {
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    report(
                        name,
                        ms,
                        Box::new(move |wi, wo| r.at(wi, wo).ok().map(|v| v.value[0])),
                    );
                }
                Err(e) => println!("| {mname} | {name} | error: {e} | | | | | |"),
            }
        }
    }
}
