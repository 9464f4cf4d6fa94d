//! Benchmark: Renka's modified Shepard interpolants, error against run time. For node counts
//! N = 100, 1,000 and 6,561 (random nodes in the unit square, a fixed seed) and several NQ/NW
//! settings: build time, query time for a 33 × 33 grid, and the max and mean error on Franke's
//! exponential (Renka's F1) and the cosine peak (F10). Prints a Markdown table.
//!
//! Run: `cargo bench --bench shepard`

use goniowatch::measure::shepard::{Method, Shepard};
use std::time::Instant;

fn f1(x: f64, y: f64) -> f64 {
    0.75 * (-((9.0 * x - 2.0).powi(2) + (9.0 * y - 2.0).powi(2)) / 4.0).exp()
        + 0.75 * (-(9.0 * x + 1.0).powi(2) / 49.0 - (9.0 * y + 1.0) / 10.0).exp()
        + 0.5 * (-((9.0 * x - 7.0).powi(2) + (9.0 * y - 3.0).powi(2)) / 4.0).exp()
        - 0.2 * (-(9.0 * x - 4.0).powi(2) - (9.0 * y - 7.0).powi(2)).exp()
}

fn f10(x: f64, y: f64) -> f64 {
    let t = ((80.0 * x - 40.0).powi(2) + (90.0 * y - 45.0).powi(2)).sqrt();
    (-0.04 * t).exp() * (0.15 * t).cos()
}

fn nodes(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut s = goniowatch::fixtures::Lcg(seed);
    let mut u = || s.uniform();
    (0..n).map(|_| [u(), u(), 0.0]).collect()
}

fn main() {
    println!("| N | method | NQ | NW | build ms | 1,089 queries ms | µs/query | F1 max err | F1 mean err | F10 max err | F10 mean err |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for n in [100usize, 1000, 6561] {
        let p = nodes(n, 42);
        for (method, nq, nw) in [
            (Method::Quadratic2, 13, 19),
            (Method::Quadratic2, 9, 12),
            (Method::Cubic2, 17, 30),
            (Method::Cubic2, 11, 20),
            (Method::Cubic2, 25, 40),
        ] {
            let mut row = Vec::new();
            let (mut build_ms, mut query_ms) = (0.0, 0.0);
            for f in [f1 as fn(f64, f64) -> f64, f10] {
                let v: Vec<f64> = p.iter().map(|q| f(q[0], q[1])).collect();
                let t0 = Instant::now();
                let s = match Shepard::fit(method, &p, &v, nq, nw) {
                    Ok(s) => s,
                    Err(e) => {
                        row.push(format!("error: {e}"));
                        continue;
                    }
                };
                build_ms += t0.elapsed().as_secs_f64() * 1e3 / 2.0;
                let t0 = Instant::now();
                let (mut emax, mut esum, mut count) = (0.0f64, 0.0, 0usize);
                for j in 0..33 {
                    for i in 0..33 {
                        let (x, y) = (i as f64 / 32.0, j as f64 / 32.0);
                        if let Ok(val) = s.value(&[x, y]) {
                            let e = (val - f(x, y)).abs();
                            emax = emax.max(e);
                            esum += e;
                            count += 1;
                        }
                    }
                }
                query_ms += t0.elapsed().as_secs_f64() * 1e3 / 2.0;
                row.push(format!("{emax:.2e} | {:.2e}", esum / count.max(1) as f64));
            }
            println!(
                "| {n} | {method:?} | {nq} | {nw} | {build_ms:.2} | {query_ms:.2} | {:.2} | {} |",
                query_ms * 1e3 / 1089.0,
                row.join(" | ")
            );
        }
    }
}
