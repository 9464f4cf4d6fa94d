//! CPU time of the per-capture checks (the sans-IO core: geometry, colour, quality, pairs,
//! isotropy classes, the isotropy drift refits, substitutes' interpolated partners, the light
//! sweeps' back-fits, interpolant builds and joint fits) over a full
//! 6,561-capture UBO session in light-outer order, reported per window of the run so that the
//! cost at the end of the run is visible (the target: under 1 ms per capture at the end).
//! Synthetic reciprocal BRDF readings (`fixtures::ubo_session`) with a −1 %/h decay; no
//! decoding, no I/O.
//!
//! Run: `cargo bench --bench checks`

use goniowatch::fixtures::{ubo_checker, ubo_session};
use std::time::Instant;

fn main() {
    let inputs = ubo_session(usize::MAX, |t_h| (-0.01 * t_h).exp());
    println!("| captures | mean CPU per capture | slowest capture in the window |");
    println!("|---|---|---|");
    for rep in 0..3 {
        let mut ch = ubo_checker();
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
