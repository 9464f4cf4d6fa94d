//! CPU time of the per-capture checks (the sans-IO core: geometry, colour, quality, pairs,
//! isotropy classes, the isotropy drift refits, substitutes' interpolated partners, the light
//! sweeps' back-fits, interpolant builds and joint fits) over a full
//! 6,561-capture UBO session in light-outer order, reported per window of the run so that the
//! cost at the end of the run is visible (issue 5's target: under 1 ms per capture at the end).
//! Synthetic reciprocal BRDF readings with a −1 %/h decay; no decoding, no I/O.
//!
//! Run: `cargo bench --bench checks`

use goniowatch::checks::{CaptureInput, CheckSpec, Checker, ColourSettings, Outcome};
use goniowatch::measure::averaging::CaptureStats;
use goniowatch::measure::colour::{RgbPrimaries, RgbToXyz, White};
use goniowatch::measure::geometry::Vec3;
use goniowatch::measure::kinematics::{Rig, RigSpec};
use goniowatch::measure::plan::SamplingPlan;
use goniowatch::measure::probes::ProbeSpec;
use std::time::Instant;

fn reading(wi: &Vec3, wo: &Vec3) -> [f64; 3] {
    let h = (wi + wo).normalize();
    let lobe = 0.6 * h.z.powi(40);
    [
        (0.40 + lobe) * wi.z,
        (0.34 + lobe) * wi.z,
        (0.25 + lobe) * wi.z,
    ]
}

fn main() {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(RigSpec::default()).expect("rig");
    let inputs: Vec<CaptureInput> = (0..plan.capture_count())
        .map(|idx| {
            let e = plan.entry(idx).expect("entry");
            let d = plan.directions();
            let pp = rig
                .plan_pose(d[e.light].spherical(), d[e.camera].spherical())
                .expect("pose");
            let r = [
                pp.pose.joints_deg[0],
                pp.pose.joints_deg[1],
                pp.pose.joints_deg[2],
                pp.pose.wagon_deg,
            ];
            let t = idx as f64 * 7.0;
            let g = (-0.01 * t / 3600.0).exp();
            CaptureInput {
                idx: idx as u64,
                entry: idx,
                file: String::new(),
                t,
                cmd: r,
                enc: r,
                substitute: pp.substitute.map(|s| s.1),
                probe: false,
                outcome: Outcome::Ok {
                    stats: CaptureStats {
                        mean_rgb: reading(&pp.used.omega_i, &pp.used.omega_o).map(|v| v * g),
                        pixels: 3_000_000,
                        nonfinite: 0,
                        negative: 0,
                        clipped: 0,
                        dark: 0,
                        max_value: 1.0,
                    },
                    width: 2000,
                    height: 1500,
                    size: 0,
                    sha256: String::new(),
                },
            }
        })
        .collect();
    println!("| captures | mean CPU per capture | slowest capture in the window |");
    println!("|---|---|---|");
    for rep in 0..3 {
        let mut ch = Checker::new(
            plan.clone(),
            rig.clone(),
            ColourSettings {
                to_xyz: RgbToXyz::new(RgbPrimaries::SrgbIec),
                rgb_scale: 100.0,
                white: White::d65_scaled(100.0).expect("white"),
                min_cos: 1e-3,
            },
            CheckSpec::default(),
            true,
            ProbeSpec::default(),
        );
        let mut times = Vec::with_capacity(inputs.len());
        for input in &inputs {
            let t0 = Instant::now();
            let out = ch.check(input);
            times.push(t0.elapsed().as_secs_f64());
            std::hint::black_box(out);
        }
        if rep < 2 {
            continue; // warm-up runs
        }
        for (a, b) in [
            (0, 500),
            (1500, 2000),
            (3000, 3500),
            (4500, 5000),
            (6061, 6561),
        ] {
            let w = &times[a..b];
            let mean = w.iter().sum::<f64>() / w.len() as f64;
            let max = w.iter().copied().fold(0.0, f64::max);
            println!("| {a}–{b} | {:.1} µs | {:.2} ms |", mean * 1e6, max * 1e3);
        }
        // the captures that completed a light direction carry the sweep test
        let sweep_caps: Vec<f64> = times.iter().skip(80).step_by(81).copied().collect();
        let other: Vec<f64> = times
            .iter()
            .enumerate()
            .filter(|(k, _)| k % 81 != 80)
            .map(|(_, t)| *t)
            .collect();
        let sw = ch.sweeps().expect("sweeps run on this session");
        println!(
            "\nlight sweeps: {} tested, interpolant built {} times; a sweep-completing capture {:.2} ms on average (max {:.1} ms), the others {:.1} µs",
            sw.tested,
            sw.last.as_ref().map(|r| r.model_builds).unwrap_or(0),
            1e3 * sweep_caps.iter().sum::<f64>() / sweep_caps.len() as f64,
            1e3 * sweep_caps.iter().copied().fold(0.0, f64::max),
            1e6 * other.iter().sum::<f64>() / other.len() as f64,
        );
        let e = ch.isotropy_drift().expect("estimate");
        println!(
            "\nfinal isotropy drift estimate {:+.3} ± {:.3} %/h (truth −1.000)",
            e.rate_pct_per_h, e.se_pct_per_h
        );
    }
}
