//! Renka's modified cubic Shepard interpolation in 2-D (the method of ACM TOMS Algorithm 790,
//! CSHEP2D), written from the algorithm's description: groundwork for issue 6 (the quadratic
//! 2-D/3-D variants, the cell grid for the neighbour search and the resampling around it are
//! open).
//!
//! The interpolant is C(p) = Σ W_k(p) C_k(p) / Σ W_k(p) with
//! - nodal cubics C_k interpolating f_k, fitted by weighted least squares to the NC nearest nodes
//!   (row weights (R_c − d)/(R_c d), R_c just large enough to include them; columns scaled by the
//!   inverse RMS distance; a QR solve; an ill-conditioned fit takes more nodes, and at the limit
//!   of 40 is damped towards a quadratic);
//! - weights W_k = ((R_k − d)₊ / (R_k d))³ with R_k the distance that includes NW nodes.
//!
//! A point within no node's radius has no value (`ShepardError::Outside`), never a silent 0.

use nalgebra::{DMatrix, DVector};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum ShepardError {
    #[error("need at least 10 nodes, got {0}")]
    TooFewNodes(usize),
    #[error("nc must be 9..=min(40, n−1) and nw 1..=min(40, n−1) (nc {nc}, nw {nw}, n {n})")]
    BadParameters { nc: usize, nw: usize, n: usize },
    #[error("nodes {0} and {1} coincide")]
    DuplicateNodes(usize, usize),
    #[error("the nodes around node {0} are (nearly) collinear: no unique cubic fit")]
    Collinear(usize),
    #[error("node {0} has a non-finite coordinate or value")]
    NotFinite(usize),
    #[error("({x}, {y}) lies outside every node's radius of influence")]
    Outside { x: f64, y: f64 },
}

const LMAX: usize = 40;
const RTOL: f64 = 1e-5;
// Renka's Fortran writes these two as single-precision literals (`.01`, `1.1`) in double
// expressions; we keep their exact values so the published error table is reproduced.
const DTOL: f64 = 0.01f32 as f64;
const WIDEN: f64 = 1.1f32 as f64;

/// A fitted cubic Shepard interpolant.
#[derive(Debug, Clone)]
pub struct CubicShepard2 {
    x: Vec<f64>,
    y: Vec<f64>,
    f: Vec<f64>,
    /// Nodal cubic coefficients: dx³, dx²dy, dxdy², dy³, dx², dxdy, dy², dx, dy.
    a: Vec<[f64; 9]>,
    rw: Vec<f64>,
    rmax: f64,
}

#[allow(clippy::too_many_arguments)] // node k, node i and the fit parameters
fn row(
    xk: f64,
    yk: f64,
    fk: f64,
    xi: f64,
    yi: f64,
    fi: f64,
    s: (f64, f64, f64),
    rc: f64,
) -> ([f64; 9], f64) {
    let (dx, dy) = (xi - xk, yi - yk);
    let d = dx.hypot(dy);
    if d <= 0.0 || d >= rc {
        return ([0.0; 9], 0.0);
    }
    let w = (rc - d) / rc / d;
    let (w1, w2, w3) = (s.0 * w, s.1 * w, s.2 * w);
    (
        [
            dx * dx * dx * w3,
            dx * dx * dy * w3,
            dx * dy * dy * w3,
            dy * dy * dy * w3,
            dx * dx * w2,
            dx * dy * w2,
            dy * dy * w2,
            dx * w1,
            dy * w1,
        ],
        (fi - fk) * w,
    )
}

/// Solve the (possibly augmented) least-squares system; returns the solution and min |R_ii|
/// over `check` diagonal entries.
fn qr_solve(
    rows: &[([f64; 9], f64)],
    check: std::ops::Range<usize>,
) -> Option<(DVector<f64>, f64)> {
    let m = rows.len().max(9);
    let mut a = DMatrix::<f64>::zeros(m, 9);
    let mut b = DVector::<f64>::zeros(m);
    for (i, (r, rhs)) in rows.iter().enumerate() {
        for j in 0..9 {
            a[(i, j)] = r[j];
        }
        b[i] = *rhs;
    }
    let qr = a.qr();
    let r = qr.r();
    let dmin = check.map(|i| r[(i, i)].abs()).fold(f64::INFINITY, f64::min);
    let qtb = qr.q().transpose() * b;
    let rt = r.fixed_view::<9, 9>(0, 0).into_owned();
    let sol = rt.solve_upper_triangular(&qtb.rows(0, 9).into_owned())?;
    Some((DVector::from_iterator(9, sol.iter().copied()), dmin))
}

impl CubicShepard2 {
    /// Fit the interpolant. `nc`: nodes in each least-squares fit (Renka: 17, 11 near a grid);
    /// `nw`: nodes within each radius of influence (Renka: 30).
    pub fn new(
        x: &[f64],
        y: &[f64],
        f: &[f64],
        nc: usize,
        nw: usize,
    ) -> Result<Self, ShepardError> {
        let n = x.len().min(y.len()).min(f.len());
        if n < 10 {
            return Err(ShepardError::TooFewNodes(n));
        }
        for k in 0..n {
            if !(x[k].is_finite() && y[k].is_finite() && f[k].is_finite()) {
                return Err(ShepardError::NotFinite(k));
            }
        }
        let lmax = LMAX.min(n - 1);
        if nc < 9 || nw < 1 || nc.max(nw) > lmax {
            return Err(ShepardError::BadParameters { nc, nw, n });
        }
        let ncw = nc.max(nw);
        let mut a = vec![[0.0; 9]; n];
        let mut rw = vec![0.0; n];
        let mut rsmx: f64 = 0.0;
        let mut order: Vec<(f64, usize)> = Vec::with_capacity(n);
        for k in 0..n {
            let (xk, yk, fk) = (x[k], y[k], f[k]);
            // the lmax nearest other nodes, by squared distance (ties by index)
            order.clear();
            order.extend(
                (0..n)
                    .filter(|&j| j != k)
                    .map(|j| ((x[j] - xk).powi(2) + (y[j] - yk).powi(2), j)),
            );
            let cmp = |p: &(f64, usize), q: &(f64, usize)| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1));
            if order.len() > lmax {
                order.select_nth_unstable_by(lmax, cmp);
                order.truncate(lmax);
            }
            order.sort_by(cmp);
            if let Some(&(d0, j)) = order.first() {
                if d0 == 0.0 {
                    return Err(ShepardError::DuplicateNodes(k.min(j), k.max(j)));
                }
            }
            let nb = |i: usize| order[i];
            // choose the fit's nodes (neq), its radius rc, the weight radius rw and the scale
            let (mut rs, mut sum, mut rws, mut rc) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            let (mut lnp, mut neq, mut sfs) = (0usize, 0usize, 0.0f64);
            loop {
                sum += rs;
                if lnp == lmax {
                    if rws == 0.0 {
                        rws = WIDEN * rs;
                    }
                    if rc == 0.0 {
                        neq = lmax;
                        rc = (WIDEN * rs).sqrt();
                        sfs = neq as f64 / sum;
                    }
                    break;
                }
                lnp += 1;
                let rsold = rs;
                rs = nb(lnp - 1).0;
                if (rs - rsold) / rs < RTOL {
                    continue;
                }
                if rws == 0.0 && lnp > nw {
                    rws = rs;
                }
                if rc == 0.0 && lnp > nc {
                    neq = lnp - 1;
                    rc = rs.sqrt();
                    sfs = neq as f64 / sum;
                }
                if lnp > ncw {
                    break;
                }
            }
            rw[k] = rws.sqrt();
            rsmx = rsmx.max(rws);
            let sf = sfs.sqrt();
            let scale = (sf, sfs, sf * sfs);
            let sol = loop {
                let rows: Vec<([f64; 9], f64)> = (0..neq)
                    .map(|i| {
                        let j = nb(i).1;
                        row(xk, yk, fk, x[j], y[j], f[j], scale, rc)
                    })
                    .collect();
                let (sol, dmin) = qr_solve(&rows, 0..9).ok_or(ShepardError::Collinear(k))?;
                if dmin * rc >= DTOL {
                    break sol;
                }
                if neq == lmax {
                    // damp the third partials: the fit tends to a quadratic
                    let stf = 1.0 / rc;
                    let mut damped = rows.clone();
                    for i in 0..4 {
                        let mut e = [0.0; 9];
                        e[i] = stf;
                        damped.push((e, 0.0));
                    }
                    let (sol, dmin) = qr_solve(&damped, 4..9).ok_or(ShepardError::Collinear(k))?;
                    if dmin * rc < DTOL {
                        return Err(ShepardError::Collinear(k));
                    }
                    break sol;
                }
                // take one more node (all of a tie) and widen rc to just beyond it
                loop {
                    let rsold = rs;
                    neq += 1;
                    if neq == lmax {
                        rc = (WIDEN * rs).sqrt();
                        break;
                    }
                    if neq < lnp {
                        rs = nb(neq).0;
                    } else {
                        lnp += 1;
                        rs = nb(lnp - 1).0;
                    }
                    if (rs - rsold) / rs >= RTOL {
                        rc = rs.sqrt();
                        break;
                    }
                }
            };
            let sfc = sf * sfs;
            a[k] = [
                sol[0] * sfc,
                sol[1] * sfc,
                sol[2] * sfc,
                sol[3] * sfc,
                sol[4] * sfs,
                sol[5] * sfs,
                sol[6] * sfs,
                sol[7] * sf,
                sol[8] * sf,
            ];
        }
        Ok(CubicShepard2 {
            x: x[..n].to_vec(),
            y: y[..n].to_vec(),
            f: f[..n].to_vec(),
            a,
            rw,
            rmax: rsmx.sqrt(),
        })
    }

    /// The largest radius of influence.
    pub fn rmax(&self) -> f64 {
        self.rmax
    }

    /// The interpolant at (px, py).
    pub fn value(&self, px: f64, py: f64) -> Result<f64, ShepardError> {
        let (mut sw, mut swc) = (0.0, 0.0);
        for k in 0..self.x.len() {
            let (dx, dy) = (px - self.x[k], py - self.y[k]);
            if dx.abs() >= self.rmax || dy.abs() >= self.rmax {
                continue;
            }
            let d = dx.hypot(dy);
            let r = self.rw[k];
            if d >= r {
                continue;
            }
            if d == 0.0 {
                return Ok(self.f[k]);
            }
            let a = &self.a[k];
            let t = 1.0 / d - 1.0 / r;
            let w = t * t * t;
            let ck = ((a[0] * dx + a[1] * dy + a[4]) * dx + (a[2] * dy + a[5]) * dy + a[7]) * dx
                + ((a[3] * dy + a[6]) * dy + a[8]) * dy
                + self.f[k];
            sw += w;
            swc += w * ck;
        }
        if sw == 0.0 {
            return Err(ShepardError::Outside { x: px, y: py });
        }
        Ok(swc / sw)
    }
}
