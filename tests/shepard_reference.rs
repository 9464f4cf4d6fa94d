//! Renka's published CSHEP2D error table (TOMS 790 test driver) and exactness on a cubic.

mod common;
use common::{csv_rows, reference};
use goniowatch::measure::shepard::{Shepard, ShepardError};

/// A constant as Renka's Fortran has it: a single-precision literal in a double expression.
fn single(v: f32) -> f64 {
    v as f64
}

/// Renka's test functions TSTFN1, K = 1..10 (tests/reference/renka_test_functions.txt), with the
/// driver's single-precision literals (0.2, 5.4, 20/3, 0.04, 0.15) kept as they are.
fn tstfn(k: usize, x: f64, y: f64) -> f64 {
    match k {
        1 => {
            0.75 * (-((9.0 * x - 2.0).powi(2) + (9.0 * y - 2.0).powi(2)) / 4.0).exp()
                + 0.75 * (-(9.0 * x + 1.0).powi(2) / 49.0 - (9.0 * y + 1.0) / 10.0).exp()
                + 0.5 * (-((9.0 * x - 7.0).powi(2) + (9.0 * y - 3.0).powi(2)) / 4.0).exp()
                - single(0.2) * (-(9.0 * x - 4.0).powi(2) - (9.0 * y - 7.0).powi(2)).exp()
        }
        2 => ((9.0 * (y - x)).tanh() + 1.0) / 9.0,
        3 => (1.25 + (single(5.4) * y).cos()) / (6.0 + 6.0 * (3.0 * x - 1.0).powi(2)),
        4 => (-5.0625 * ((x - 0.5).powi(2) + (y - 0.5).powi(2))).exp() / 3.0,
        5 => (-20.25 * ((x - 0.5).powi(2) + (y - 0.5).powi(2))).exp() / 3.0,
        6 => {
            let t = 64.0 - 81.0 * ((x - 0.5).powi(2) + (y - 0.5).powi(2));
            if t >= 0.0 {
                t.sqrt() / 9.0 - 0.5
            } else {
                0.0
            }
        }
        7 => 2.0 * (10.0 * x).cos() * (10.0 * y).sin() + (10.0 * x * y).sin(),
        8 => {
            let t3 = (-0.5 * (5.0 - 10.0 * x).powi(2)).exp();
            let t4 = (-0.5 * (5.0 - 10.0 * y).powi(2)).exp();
            t3 + 0.75 * t4 * (1.0 + t3)
        }
        9 => {
            let t1 = ((10.0 - 20.0 * x) / 3.0).exp();
            let t2 = ((10.0 - 20.0 * y) / 3.0).exp();
            let t3 = 1.0 / (1.0 + t1);
            let t4 = 1.0 / (1.0 + t2);
            (single((20.0f32 / 3.0f32).powi(3)) * t1 * t2).powi(2)
                * (t3 * t4).powi(5)
                * (t1 - 2.0 * t3)
                * (t2 - 2.0 * t4)
        }
        10 => {
            let t = ((80.0 * x - 40.0).powi(2) + (90.0 * y - 45.0).powi(2)).sqrt();
            (-single(0.04) * t).exp() * (single(0.15) * t).cos()
        }
        _ => unreachable!(),
    }
}

/// A node set as Renka's TESTDT stores it: single-precision DATA literals in double arrays.
fn nodeset(set: usize) -> (Vec<f64>, Vec<f64>) {
    let rows = csv_rows("renka_nodesets.csv");
    let pts: Vec<&Vec<f64>> = rows.iter().filter(|r| r[0] as usize == set).collect();
    (
        pts.iter().map(|r| r[2] as f32 as f64).collect(),
        pts.iter().map(|r| r[3] as f32 as f64).collect(),
    )
}

/// Round-to-printed comparison: |ours − published| within half a unit of the last printed digit.
fn printed_eq(ours: f64, published_text: &str) -> bool {
    let decimals = published_text
        .split('.')
        .nth(1)
        .map(|d| d.len())
        .unwrap_or(0) as i32;
    let published: f64 = published_text.parse().unwrap();
    (ours - published).abs() <= 0.5 * 10f64.powi(-decimals) * (1.0 + 1e-9) + 1e-15
}

#[test]
fn renka_published_error_table() {
    let text = std::fs::read_to_string(reference("cshep2d_renka_errors_published.csv")).unwrap();
    let mut checked = 0;
    let mut mismatches = Vec::new();
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("nodeset"))
    {
        let c: Vec<&str> = line.split(',').collect();
        let (set, nc, nw, k) = (
            c[0].parse().unwrap(),
            c[2].parse().unwrap(),
            c[3].parse().unwrap(),
            c[5].parse().unwrap(),
        );
        let (x, y) = nodeset(set);
        let f: Vec<f64> = x.iter().zip(&y).map(|(&x, &y)| tstfn(k, x, y)).collect();
        let cs = Shepard::cubic_2d(&x, &y, &f, nc, nw).unwrap();
        let (mut emax, mut esum, mut sse, mut fs) = (0.0f64, 0.0, 0.0, Vec::new());
        for j in 0..33 {
            for i in 0..33 {
                let (px, py) = (i as f64 / 32.0, j as f64 / 32.0);
                // Renka's driver: a point outside every radius evaluates to 0
                let v = match cs.value(&[px, py]) {
                    Ok(v) => v,
                    Err(ShepardError::Outside { .. }) => 0.0,
                    Err(e) => panic!("{e}"),
                };
                let ft = tstfn(k, px, py);
                let e = (v - ft).abs();
                emax = emax.max(e);
                esum += e;
                sse += e * e;
                fs.push(ft);
            }
        }
        let mean_f = fs.iter().sum::<f64>() / fs.len() as f64;
        let ssm: f64 = fs.iter().map(|v| (v - mean_f).powi(2)).sum();
        let (mean, ratio) = (esum / 1089.0, sse / ssm);
        if !(printed_eq(emax, c[6]) && printed_eq(mean, c[7]) && printed_eq(ratio, c[8])) {
            mismatches.push(format!(
                "set {set} f{k}: ours {emax:.8} {mean:.9} {ratio:.10} vs published {} {} {}",
                c[6], c[7], c[8]
            ));
        }
        checked += 1;
    }
    assert_eq!(checked, 50);
    assert!(
        mismatches.is_empty(),
        "{} of 50 rows differ:\n{}",
        mismatches.len(),
        mismatches.join("\n")
    );
}

#[test]
fn reproduces_a_cubic_to_rounding() {
    // TOMS 790 CS2TEST: 10×10 grid (i−1)/9, NC 17, NW 30, F = ((x + 2y)/3)³, 20×20 evaluation grid
    let (mut x, mut y, mut f) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..10 {
        for i in 0..10 {
            let (px, py) = (i as f64 / 9.0, j as f64 / 9.0);
            x.push(px);
            y.push(py);
            f.push(((px + 2.0 * py) / 3.0).powi(3));
        }
    }
    let cs = Shepard::cubic_2d(&x, &y, &f, 17, 30).unwrap();
    let mut emax: f64 = 0.0;
    for j in 0..20 {
        for i in 0..20 {
            let (px, py) = (i as f64 / 19.0, j as f64 / 19.0);
            emax = emax.max((cs.value(&[px, py]).unwrap() - ((px + 2.0 * py) / 3.0).powi(3)).abs());
        }
    }
    assert!(emax < 1e-14, "{emax}");
}

#[test]
fn bad_node_sets_are_typed_errors() {
    let x: Vec<f64> = (0..12).map(|i| i as f64).collect();
    let y: Vec<f64> = (0..12).map(|i| (i * 7 % 5) as f64).collect();
    let f = vec![1.0; 12];
    assert_eq!(
        Shepard::cubic_2d(&x[..9], &y[..9], &f[..9], 9, 5).unwrap_err(),
        ShepardError::TooFewNodes(9)
    );
    assert!(matches!(
        Shepard::cubic_2d(&x, &y, &f, 8, 5),
        Err(ShepardError::BadParameters { .. })
    ));
    let mut xd = x.clone();
    let mut yd = y.clone();
    xd[3] = xd[7];
    yd[3] = yd[7];
    assert_eq!(
        Shepard::cubic_2d(&xd, &yd, &f, 9, 5).unwrap_err(),
        ShepardError::DuplicateNodes(3, 7)
    );
    // all nodes on one line: no unique cubic
    let yl = vec![0.5; 12];
    assert!(matches!(
        Shepard::cubic_2d(&x, &yl, &f, 9, 5),
        Err(ShepardError::Collinear(_))
    ));
    let mut fnan = f.clone();
    fnan[2] = f64::NAN;
    assert_eq!(
        Shepard::cubic_2d(&x, &y, &fnan, 9, 5).unwrap_err(),
        ShepardError::NotFinite(2)
    );
    // far away: no value, not a silent 0
    let (gx, gy): (Vec<f64>, Vec<f64>) = (0..25).map(|i| ((i % 5) as f64, (i / 5) as f64)).unzip();
    let cs = Shepard::cubic_2d(&gx, &gy, &[1.0; 25], 11, 10).unwrap();
    assert_eq!(cs.value(&[2.2, 1.7]), Ok(1.0));
    assert!(matches!(
        cs.value(&[1e6, 1e6]),
        Err(ShepardError::Outside { .. })
    ));
}

#[test]
fn quadratic_2d_reproduces_a_quadratic() {
    // TOMS 660 QS2TEST: 6×6 grid x = (i−1)/5, y = (6−j)/5, NQ 13, NW 19, F = ((x + 2y)/3)²
    let (mut x, mut y, mut f) = (Vec::new(), Vec::new(), Vec::new());
    for j in 1..=6 {
        for i in 1..=6 {
            let (px, py) = ((i - 1) as f64 / 5.0, (6 - j) as f64 / 5.0);
            x.push(px);
            y.push(py);
            f.push(((px + 2.0 * py) / 3.0).powi(2));
        }
    }
    let q = Shepard::quadratic_2d(&x, &y, &f, 13, 19).unwrap();
    let mut emax: f64 = 0.0;
    for j in 0..10 {
        for i in 0..10 {
            let (px, py) = (i as f64 / 9.0, j as f64 / 9.0);
            emax = emax.max((q.value(&[px, py]).unwrap() - ((px + 2.0 * py) / 3.0).powi(2)).abs());
        }
    }
    assert!(emax < 1e-14, "{emax}");
}

#[test]
fn quadratic_3d_reproduces_a_quadratic() {
    // TOMS 661 QS3TEST: 4×4×4 grid (i−1)/3, NQ 17, NW 32, F = ((x + 2y + 3z)/6)², 5×5×5 points
    let (mut x, mut y, mut z, mut f) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for k in 0..4 {
        for j in 0..4 {
            for i in 0..4 {
                let (px, py, pz) = (i as f64 / 3.0, j as f64 / 3.0, k as f64 / 3.0);
                x.push(px);
                y.push(py);
                z.push(pz);
                f.push(((px + 2.0 * py + 3.0 * pz) / 6.0).powi(2));
            }
        }
    }
    let q = Shepard::quadratic_3d(&x, &y, &z, &f, 17, 32).unwrap();
    let mut emax: f64 = 0.0;
    for k in 0..5 {
        for j in 0..5 {
            for i in 0..5 {
                let (px, py, pz) = (i as f64 / 4.0, j as f64 / 4.0, k as f64 / 4.0);
                let want = ((px + 2.0 * py + 3.0 * pz) / 6.0).powi(2);
                emax = emax.max((q.value(&[px, py, pz]).unwrap() - want).abs());
            }
        }
    }
    assert!(emax < 1e-14, "{emax}");
}

#[test]
fn near_duplicate_and_coplanar_nodes() {
    // two nodes 1e-13 apart are duplicates (their data difference is rounding noise) ...
    let (mut x, mut y): (Vec<f64>, Vec<f64>) = (0..36)
        .map(|i| ((i % 6) as f64 / 5.0, (i / 6) as f64 / 5.0))
        .unzip();
    x[7] = x[8] - 1e-13;
    y[7] = y[8];
    let f: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a + b).collect();
    assert_eq!(
        Shepard::quadratic_2d(&x, &y, &f, 13, 19).unwrap_err(),
        ShepardError::DuplicateNodes(7, 8)
    );
    // ... two nodes 1e-6 apart are not: the fit stays accurate on a linear function
    x[7] = x[8] - 1e-6;
    let f: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a + b).collect();
    let q = Shepard::quadratic_2d(&x, &y, &f, 13, 19).unwrap();
    let v = q.value(&[0.5, 0.5]).unwrap();
    assert!((v - 1.0).abs() < 1e-6, "{v}");
    // all nodes in one plane: no unique 3-D quadratic
    let (mut x3, mut y3, mut z3) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..5 {
        for i in 0..5 {
            x3.push(i as f64);
            y3.push(j as f64);
            z3.push(0.0);
        }
    }
    let f3 = vec![1.0; 25];
    assert!(matches!(
        Shepard::quadratic_3d(&x3, &y3, &z3, &f3, 17, 20),
        Err(ShepardError::Collinear(_))
    ));
    assert!(matches!(
        Shepard::quadratic_2d(&x[..5], &y[..5], &f[..5], 5, 4),
        Err(ShepardError::TooFewNodes(5))
    ));
}
