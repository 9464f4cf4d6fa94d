//! Renka's modified Shepard interpolation, written from the algorithms' descriptions
//! (ACM TOMS 660 QSHEP2D, 661 QSHEP3D, 790 CSHEP2D), with a uniform cell grid for the
//! neighbour and radius searches; `measure::resample` builds the BRDF resamplers on it.
//!
//! The interpolant is Q(p) = Σ W_k(p) Q_k(p) / Σ W_k(p) with
//! - nodal polynomials Q_k (quadratic in 2-D or 3-D, or cubic in 2-D) interpolating f_k, fitted
//!   by weighted least squares to the NQ (NC) nearest nodes: row weights (R_q − d)/(R_q d) with
//!   R_q just large enough to include them, columns scaled by the inverse RMS distance, a QR
//!   solve; an ill-conditioned fit takes more nodes, and at the limit of 40 the highest-order
//!   terms are damped (the fit tends to the next lower degree);
//! - weights W_k = ((R_k − d)₊ / (R_k d))^p with R_k the distance that includes NW nodes, p = 2
//!   for the quadratic methods and 3 for the cubic one.
//!
//! A point within no node's radius has no value (`ShepardError::Outside`), never a silent 0.

use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum ShepardError {
    #[error("need at least 10 nodes, got {0}")]
    TooFewNodes(usize),
    #[error("the fit needs at least as many nodes as coefficients and nq, nw ≤ min(40, n − 1) (nq {nc}, nw {nw}, n {n})")]
    BadParameters { nc: usize, nw: usize, n: usize },
    #[error("nodes {0} and {1} coincide (closer than 1e-9 of the data's extent)")]
    DuplicateNodes(usize, usize),
    #[error("the nodes around node {0} are (nearly) collinear (2-D) or coplanar (3-D): no unique nodal fit")]
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
/// Nodes closer than this fraction of the data's extent are duplicates.
pub(crate) const DUPLICATE_TOL: f64 = 1e-9;

/// Which modified Shepard method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// QSHEP2D: quadratic nodal functions in 2-D, weights squared. Renka: NQ 13, NW 19.
    Quadratic2,
    /// QSHEP3D: quadratic nodal functions in 3-D, weights squared. Renka: NQ 17, NW 32.
    Quadratic3,
    /// CSHEP2D: cubic nodal functions in 2-D, weights cubed. Renka: NC 17, NW 30.
    Cubic2,
}

impl Method {
    fn dims(self) -> usize {
        match self {
            Method::Quadratic2 | Method::Cubic2 => 2,
            Method::Quadratic3 => 3,
        }
    }
    /// Number of coefficients of a nodal function.
    fn terms(self) -> usize {
        match self {
            Method::Quadratic2 => 5,
            Method::Quadratic3 | Method::Cubic2 => 9,
        }
    }
    /// Number of highest-order terms (they come first) damped at the limit.
    fn damped(self) -> usize {
        match self {
            Method::Quadratic2 => 3,
            Method::Quadratic3 => 6,
            Method::Cubic2 => 4,
        }
    }
    fn min_nodes(self) -> usize {
        match self {
            Method::Quadratic2 => 6,
            Method::Quadratic3 | Method::Cubic2 => 10,
        }
    }
    /// The fit's row for a neighbour at offset d, without the row weight; `sf` = 1/RMS distance.
    fn terms_at(self, d: &[f64; 3], sf: f64, out: &mut Vec<f64>) {
        let (dx, dy, dz) = (d[0], d[1], d[2]);
        let (s1, s2, s3) = (sf, sf * sf, sf * sf * sf);
        out.clear();
        match self {
            Method::Quadratic2 => {
                out.extend([dx * dx * s2, dx * dy * s2, dy * dy * s2, dx * s1, dy * s1])
            }
            Method::Quadratic3 => out.extend([
                dx * dx * s2,
                dx * dy * s2,
                dy * dy * s2,
                dx * dz * s2,
                dy * dz * s2,
                dz * dz * s2,
                dx * s1,
                dy * s1,
                dz * s1,
            ]),
            Method::Cubic2 => out.extend([
                dx * dx * dx * s3,
                dx * dx * dy * s3,
                dx * dy * dy * s3,
                dy * dy * dy * s3,
                dx * dx * s2,
                dx * dy * s2,
                dy * dy * s2,
                dx * s1,
                dy * s1,
            ]),
        }
    }
    /// The column scale of each coefficient (to undo after the solve).
    fn scales(self, sf: f64) -> Vec<f64> {
        let (s1, s2, s3) = (sf, sf * sf, sf * sf * sf);
        match self {
            Method::Quadratic2 => vec![s2, s2, s2, s1, s1],
            Method::Quadratic3 => vec![s2, s2, s2, s2, s2, s2, s1, s1, s1],
            Method::Cubic2 => vec![s3, s3, s3, s3, s2, s2, s2, s1, s1],
        }
    }
    /// The damping added to each damped term: 1 for the quadratic methods, 1/R for the cubic.
    fn damping(self, rq: f64) -> f64 {
        match self {
            Method::Quadratic2 | Method::Quadratic3 => 1.0,
            Method::Cubic2 => 1.0 / rq,
        }
    }
    /// Which diagonal entries of R decide conditioning after damping.
    fn checked_after_damping(self) -> std::ops::Range<usize> {
        match self {
            Method::Quadratic2 | Method::Quadratic3 => 0..self.terms(),
            Method::Cubic2 => 4..9,
        }
    }
}

/// A fitted modified Shepard interpolant.
#[derive(Debug, Clone)]
pub struct Shepard {
    method: Method,
    p: Vec<[f64; 3]>,
    f: Vec<f64>,
    /// Nodal coefficients, in the order of `Method::terms_at` (unscaled).
    a: Vec<Vec<f64>>,
    rw: Vec<f64>,
    rmax: f64,
    grid: Grid,
}

/// Solve the least-squares system `rows · x ≈ rhs` (`rows` flat, `m` coefficients a row; fewer
/// rows than coefficients are padded with zero rows) by Householder QR, the reflections
/// applied to the right-hand side as they are made (Q is never formed); returns the solution
/// (None when R is singular or the solution is not finite) and min |R_ii| over `check`. The
/// systems are at most 40 + 3 rows by 10 columns, so one flat column-major buffer is all the
/// storage.
fn qr_solve(
    rows: &[f64],
    rhs: &[f64],
    m: usize,
    check: std::ops::Range<usize>,
) -> (Option<Vec<f64>>, f64) {
    let given = rhs.len().min(rows.len() / m.max(1));
    let n = given.max(m);
    // column-major: a[c * n + r]
    let mut a = vec![0.0; n * m];
    let mut b = vec![0.0; n];
    for r in 0..given {
        for c in 0..m {
            a[c * n + r] = rows[r * m + c];
        }
        b[r] = rhs[r];
    }
    let mut diag = vec![0.0; m];
    let mut v = vec![0.0; n];
    for j in 0..m {
        let len = n - j;
        let col = &a[j * n + j..(j + 1) * n];
        let norm = col.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            // a zero column below the diagonal: R_jj = 0, nothing to reflect
            continue;
        }
        let x0 = col[0];
        // the sign that avoids cancellation in v₀ = x₀ − α
        let alpha = if x0 >= 0.0 { -norm } else { norm };
        v[..len].copy_from_slice(col);
        v[0] -= alpha;
        let vn2: f64 = v[..len].iter().map(|x| x * x).sum();
        diag[j] = alpha;
        if !(vn2 > 0.0) {
            continue;
        }
        for c in j + 1..m {
            let cc = &mut a[c * n + j..(c + 1) * n];
            let s: f64 = v[..len].iter().zip(cc.iter()).map(|(x, y)| x * y).sum();
            let f = 2.0 * s / vn2;
            for (y, x) in cc.iter_mut().zip(&v[..len]) {
                *y -= f * x;
            }
        }
        let bb = &mut b[j..];
        let s: f64 = v[..len].iter().zip(bb.iter()).map(|(x, y)| x * y).sum();
        let f = 2.0 * s / vn2;
        for (y, x) in bb.iter_mut().zip(&v[..len]) {
            *y -= f * x;
        }
    }
    let dmin = check.map(|i| diag[i].abs()).fold(f64::INFINITY, f64::min);
    // back substitution on R (its diagonal in `diag`, above it in `a`)
    let mut x = vec![0.0; m];
    for i in (0..m).rev() {
        if diag[i] == 0.0 {
            return (None, dmin);
        }
        let mut s = b[i];
        for k in i + 1..m {
            s -= a[k * n + i] * x[k];
        }
        x[i] = s / diag[i];
    }
    (x.iter().all(|v| v.is_finite()).then_some(x), dmin)
}

/// A uniform cell grid over the nodes (about 3 nodes per cell, as Renka recommends) for the
/// nearest-neighbour and radius searches.
#[derive(Debug, Clone)]
struct Grid {
    dims: usize,
    lo: [f64; 3],
    cell: [f64; 3],
    nr: [usize; 3],
    /// Node indices per cell, cells in x-fastest order.
    cells: Vec<Vec<usize>>,
}

impl Grid {
    fn new(p: &[[f64; 3]], dims: usize) -> Grid {
        let n = p.len().max(1);
        let per_axis = ((n as f64 / 3.0).powf(1.0 / dims as f64).floor() as usize).max(1);
        let mut lo = [0.0; 3];
        let mut hi = [0.0; 3];
        let mut nr = [1usize; 3];
        let mut cell = [1.0; 3];
        for c in 0..dims {
            lo[c] = p.iter().map(|q| q[c]).fold(f64::INFINITY, f64::min);
            hi[c] = p.iter().map(|q| q[c]).fold(f64::NEG_INFINITY, f64::max);
            let span = hi[c] - lo[c];
            if span > 0.0 {
                nr[c] = per_axis;
                cell[c] = span / per_axis as f64;
            }
        }
        let mut g = Grid {
            dims,
            lo,
            cell,
            nr,
            cells: vec![Vec::new(); nr[0] * nr[1] * nr[2]],
        };
        for (i, q) in p.iter().enumerate() {
            let c = g.cell_of(q);
            let id = g.id(c);
            g.cells[id].push(i);
        }
        g
    }
    fn coord(&self, v: f64, c: usize) -> isize {
        ((v - self.lo[c]) / self.cell[c]).floor() as isize
    }
    fn cell_of(&self, q: &[f64; 3]) -> [usize; 3] {
        let mut out = [0; 3];
        for c in 0..self.dims {
            out[c] = self.coord(q[c], c).clamp(0, self.nr[c] as isize - 1) as usize;
        }
        out
    }
    fn id(&self, c: [usize; 3]) -> usize {
        c[0] + self.nr[0] * (c[1] + self.nr[1] * c[2])
    }
    /// Visit every node in the cells that meet the box `q ± r`.
    fn within(&self, q: &[f64; 3], r: f64, mut visit: impl FnMut(usize)) {
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        for c in 0..3 {
            if c >= self.dims {
                continue;
            }
            let a = self.coord(q[c] - r, c);
            let b = self.coord(q[c] + r, c);
            if b < 0 || a >= self.nr[c] as isize {
                return;
            }
            lo[c] = a.max(0) as usize;
            hi[c] = b.min(self.nr[c] as isize - 1) as usize;
        }
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    for &i in &self.cells[self.id([x, y, z])] {
                        visit(i);
                    }
                }
            }
        }
    }
    /// The `k` nearest nodes to node `me` by (squared distance, index), excluding `me`.
    fn nearest(&self, p: &[[f64; 3]], me: usize, k: usize, out: &mut Vec<(f64, usize)>) {
        let q = p[me];
        let min_cell = (0..self.dims)
            .map(|c| self.cell[c])
            .fold(f64::INFINITY, f64::min);
        let mut r = min_cell;
        loop {
            out.clear();
            self.within(&q, r, |j| {
                if j != me {
                    out.push((dist2(&p[j], &q), j));
                }
            });
            // every node within distance r of q has been seen; enough of them means done
            let inside = out.iter().filter(|(d, _)| *d <= r * r).count();
            if inside >= k || out.len() + 1 >= p.len() {
                break;
            }
            r *= 2.0;
        }
        let cmp = |u: &(f64, usize), v: &(f64, usize)| u.0.total_cmp(&v.0).then(u.1.cmp(&v.1));
        if out.len() > k {
            out.select_nth_unstable_by(k, cmp);
            out.truncate(k);
        }
        out.sort_by(cmp);
    }
}

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

impl Shepard {
    /// QSHEP2D: quadratic Shepard in the plane.
    pub fn quadratic_2d(
        x: &[f64],
        y: &[f64],
        f: &[f64],
        nq: usize,
        nw: usize,
    ) -> Result<Self, ShepardError> {
        let p: Vec<[f64; 3]> = x.iter().zip(y).map(|(&x, &y)| [x, y, 0.0]).collect();
        Self::fit(Method::Quadratic2, &p, f, nq, nw)
    }
    /// QSHEP3D: quadratic Shepard in space.
    pub fn quadratic_3d(
        x: &[f64],
        y: &[f64],
        z: &[f64],
        f: &[f64],
        nq: usize,
        nw: usize,
    ) -> Result<Self, ShepardError> {
        let p: Vec<[f64; 3]> = x
            .iter()
            .zip(y)
            .zip(z)
            .map(|((&x, &y), &z)| [x, y, z])
            .collect();
        Self::fit(Method::Quadratic3, &p, f, nq, nw)
    }
    /// CSHEP2D: cubic Shepard in the plane.
    pub fn cubic_2d(
        x: &[f64],
        y: &[f64],
        f: &[f64],
        nc: usize,
        nw: usize,
    ) -> Result<Self, ShepardError> {
        let p: Vec<[f64; 3]> = x.iter().zip(y).map(|(&x, &y)| [x, y, 0.0]).collect();
        Self::fit(Method::Cubic2, &p, f, nc, nw)
    }

    /// Fit with `nq` nodes in each nodal least-squares fit and `nw` nodes in each radius.
    pub fn fit(
        method: Method,
        p: &[[f64; 3]],
        f: &[f64],
        nq: usize,
        nw: usize,
    ) -> Result<Self, ShepardError> {
        let n = p.len().min(f.len());
        if n < method.min_nodes() {
            return Err(ShepardError::TooFewNodes(n));
        }
        for k in 0..n {
            if !(p[k].iter().all(|v| v.is_finite()) && f[k].is_finite()) {
                return Err(ShepardError::NotFinite(k));
            }
        }
        let m = method.terms();
        let lmax = LMAX.min(n - 1);
        if nq < m || nw < 1 || nq.max(nw) > lmax {
            return Err(ShepardError::BadParameters { nc: nq, nw, n });
        }
        let nqw = nq.max(nw);
        // nodes closer than this (relative to the data's extent) count as duplicates: their data
        // differences are rounding noise, and a fit through them is meaningless
        let extent = (0..3)
            .map(|c| {
                let (lo, hi) = p[..n]
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                        (lo.min(q[c]), hi.max(q[c]))
                    });
                hi - lo
            })
            .fold(0.0, f64::max);
        let dup2 = (DUPLICATE_TOL * extent).powi(2);
        let grid = Grid::new(&p[..n], method.dims());
        let mut a = vec![Vec::new(); n];
        let mut rw = vec![0.0; n];
        let mut rsmx: f64 = 0.0;
        let mut order: Vec<(f64, usize)> = Vec::with_capacity(n);
        let mut terms = Vec::with_capacity(m);
        for k in 0..n {
            // the lmax nearest other nodes by squared distance (ties by index)
            grid.nearest(&p[..n], k, lmax, &mut order);
            if let Some(&(d0, j)) = order.first() {
                if d0 <= dup2 {
                    return Err(ShepardError::DuplicateNodes(k.min(j), k.max(j)));
                }
            }
            let r = Radii::choose(&order, lmax, nq, nw, nqw);
            rw[k] = r.rws.sqrt();
            rsmx = rsmx.max(r.rws);
            let sf = r.sfs.sqrt();
            let sol = nodal_fit(method, &p[..n], &f[..n], k, &order, lmax, r, sf, &mut terms)?;
            a[k] = sol
                .iter()
                .zip(method.scales(sf))
                .map(|(c, s)| c * s)
                .collect();
        }
        Ok(Shepard {
            method,
            p: p[..n].to_vec(),
            f: f[..n].to_vec(),
            a,
            rw,
            rmax: rsmx.sqrt(),
            grid,
        })
    }

    /// The interpolant at `q` (2 or 3 coordinates as the method has).
    pub fn value(&self, q: &[f64]) -> Result<f64, ShepardError> {
        self.value_with_spread(q).map(|(v, _)| v)
    }

    /// The interpolant at `q` and the spread of the nodal functions that make it: the standard
    /// deviation of Q_k(q) about Q(q) under the weights W_k (0 at a node). Where the local fits
    /// agree the data are well resolved; where they disagree the value is uncertain, so the
    /// spread is the interpolation's uncertainty at no extra cost.
    ///
    /// At a node, and wherever `q` is so close to one that its weight overflows (closer than
    /// about 1e-154 for the quadratic methods, 1e-103 for the cubic one), the result is that
    /// node's nodal function Q_k(q) with spread 0: the limit the weighted mean and spread tend to
    /// as W_k outgrows every other weight, so the interpolant stays continuous there. The
    /// closest such node decides.
    pub fn value_with_spread(&self, q: &[f64]) -> Result<(f64, f64), ShepardError> {
        let dims = self.method.dims();
        let mut pq = [0.0; 3];
        for (i, v) in q.iter().take(dims).enumerate() {
            pq[i] = *v;
        }
        let outside = || ShepardError::Outside { x: pq[0], y: pq[1] };
        let power = if self.method == Method::Cubic2 { 3 } else { 2 };
        // weighted Welford: no cancellation when the nodal values are large and nearly equal
        let (mut sw, mut mean, mut m2) = (0.0f64, 0.0f64, 0.0f64);
        let mut terms = Vec::with_capacity(self.method.terms());
        // the node q coincides with, if any: (distance, Q_k(q))
        let mut at_node: Option<(f64, f64)> = None;
        self.grid.within(&pq, self.rmax, |k| {
            let d = [
                pq[0] - self.p[k][0],
                pq[1] - self.p[k][1],
                pq[2] - self.p[k][2],
            ];
            let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let r = self.rw[k];
            if dist >= r {
                return;
            }
            let w = (1.0 / dist - 1.0 / r).powi(power);
            let coincides = w == f64::INFINITY;
            if at_node.is_some() && !coincides {
                return;
            }
            self.method.terms_at(&d, 1.0, &mut terms);
            let qk: f64 = terms
                .iter()
                .zip(&self.a[k])
                .map(|(t, c)| t * c)
                .sum::<f64>()
                + self.f[k];
            if coincides {
                // 1/d^p overflows (d = 0 included): this node's weight outgrows all others
                if at_node.is_none_or(|(d0, _)| dist < d0) {
                    at_node = Some((dist, qk));
                }
                return;
            }
            if !(w > 0.0) {
                // 1/d and 1/r round to the same value: this node has no weight here
                return;
            }
            let sw_new = sw + w;
            let delta = qk - mean;
            mean += delta * (w / sw_new);
            m2 += w * delta * (qk - mean);
            sw = sw_new;
        });
        if let Some((_, v)) = at_node {
            return Ok((v, 0.0));
        }
        if sw == 0.0 || !sw.is_finite() {
            return Err(outside());
        }
        Ok((mean, (m2 / sw).max(0.0).sqrt()))
    }
}

/// The radii of one node's fit: how many neighbours its fit uses (`neq`, within `rq`), the
/// squared weight radius `rws`, and the scale `sfs`; `lnp` neighbours were looked at, the last
/// at squared distance `rs`.
#[derive(Debug, Clone, Copy)]
struct Radii {
    lnp: usize,
    neq: usize,
    rs: f64,
    rws: f64,
    rq: f64,
    sfs: f64,
}

impl Radii {
    /// Renka's choice from the neighbours by squared distance (`order`): the fit takes at least
    /// `nq` nodes and the weight at least `nw`, each radius widened past ties.
    fn choose(order: &[(f64, usize)], lmax: usize, nq: usize, nw: usize, nqw: usize) -> Radii {
        let (mut rs, mut sum, mut rws, mut rq) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let (mut lnp, mut neq, mut sfs) = (0usize, 0usize, 0.0f64);
        loop {
            sum += rs;
            if lnp == lmax {
                if rws == 0.0 {
                    rws = WIDEN * rs;
                }
                if rq == 0.0 {
                    neq = lmax;
                    rq = (WIDEN * rs).sqrt();
                    sfs = neq as f64 / sum;
                }
                break;
            }
            lnp += 1;
            let rsold = rs;
            rs = order[lnp - 1].0;
            if (rs - rsold) / rs < RTOL {
                continue;
            }
            if rws == 0.0 && lnp > nw {
                rws = rs;
            }
            if rq == 0.0 && lnp > nq {
                neq = lnp - 1;
                rq = rs.sqrt();
                sfs = neq as f64 / sum;
            }
            if lnp > nqw {
                break;
            }
        }
        Radii {
            lnp,
            neq,
            rs,
            rws,
            rq,
            sfs,
        }
    }
}

/// The nodal function's coefficients at node `k` (scaled by `sf`): a weighted least-squares fit
/// over its `neq` nearest neighbours, taking more neighbours while the fit is ill-conditioned
/// and damping the highest-order terms once all `lmax` are in.
#[allow(clippy::too_many_arguments)]
fn nodal_fit(
    method: Method,
    p: &[[f64; 3]],
    f: &[f64],
    k: usize,
    order: &[(f64, usize)],
    lmax: usize,
    r: Radii,
    sf: f64,
    terms: &mut Vec<f64>,
) -> Result<Vec<f64>, ShepardError> {
    let m = method.terms();
    let (pk, fk) = (p[k], f[k]);
    let nb = |i: usize| order[i];
    let Radii {
        mut lnp,
        mut neq,
        mut rs,
        mut rq,
        ..
    } = r;
    loop {
        let mut rows = Vec::with_capacity((neq + m) * m);
        let mut rhs = Vec::with_capacity(neq + m);
        for i in 0..neq {
            let j = nb(i).1;
            let d = [p[j][0] - pk[0], p[j][1] - pk[1], p[j][2] - pk[2]];
            let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if dist <= 0.0 || dist >= rq {
                rows.extend(std::iter::repeat_n(0.0, m));
                rhs.push(0.0);
                continue;
            }
            let w = (rq - dist) / rq / dist;
            method.terms_at(&d, sf, terms);
            rows.extend(terms.iter().map(|t| t * w));
            rhs.push((f[j] - fk) * w);
        }
        // an ill-conditioned (or exactly singular) fit takes more nodes: only a well-conditioned
        // one is solved
        let (sol, dmin) = qr_solve(&rows, &rhs, m, 0..m);
        if dmin * rq >= DTOL {
            return sol.ok_or(ShepardError::Collinear(k));
        }
        if neq == lmax {
            // damp the highest-order terms: the fit tends to the next lower degree
            for i in 0..method.damped() {
                rows.extend((0..m).map(|c| if c == i { method.damping(rq) } else { 0.0 }));
                rhs.push(0.0);
            }
            let (sol, dmin) = qr_solve(&rows, &rhs, m, method.checked_after_damping());
            if dmin * rq < DTOL {
                return Err(ShepardError::Collinear(k));
            }
            return sol.ok_or(ShepardError::Collinear(k));
        }
        // take one more node (all of a tie) and widen rq to just beyond it
        loop {
            let rsold = rs;
            neq += 1;
            if neq == lmax {
                rq = (WIDEN * rs).sqrt();
                break;
            }
            if neq < lnp {
                rs = nb(neq).0;
            } else {
                lnp += 1;
                rs = nb(lnp - 1).0;
            }
            if (rs - rsold) / rs >= RTOL {
                rq = rs.sqrt();
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(p: &[[f64; 3]], me: usize, k: usize) -> Vec<(f64, usize)> {
        let mut v: Vec<(f64, usize)> = (0..p.len())
            .filter(|&j| j != me)
            .map(|j| (dist2(&p[j], &p[me]), j))
            .collect();
        v.sort_by(|u, w| u.0.total_cmp(&w.0).then(u.1.cmp(&w.1)));
        v.truncate(k);
        v
    }

    #[test]
    fn grid_search_equals_brute_force() {
        let mut s = crate::fixtures::Lcg(3u64);
        let mut u = || s.uniform();
        let random2: Vec<[f64; 3]> = (0..500).map(|_| [u(), u() * 3.0, 0.0]).collect();
        let grid9: Vec<[f64; 3]> = (0..81)
            .map(|i| [(i % 9) as f64 / 8.0, (i / 9) as f64 / 8.0, 0.0])
            .collect();
        let random3: Vec<[f64; 3]> = (0..400).map(|_| [u(), u(), u() * 0.1]).collect();
        for (p, dims) in [(random2, 2), (grid9, 2), (random3, 3)] {
            let g = Grid::new(&p, dims);
            let mut out = Vec::new();
            for me in 0..p.len() {
                for k in [1, 9, 40] {
                    g.nearest(&p, me, k, &mut out);
                    assert_eq!(out, brute(&p, me, k), "node {me}, k {k}");
                }
            }
            // the radius search visits every node within r
            let q = p[p.len() / 2];
            let mut seen = Vec::new();
            g.within(&q, 0.2, |j| seen.push(j));
            for (j, pj) in p.iter().enumerate() {
                if dist2(pj, &q).sqrt() <= 0.2 {
                    assert!(seen.contains(&j));
                }
            }
        }
    }
}
