//! A smooth model of an isotropic BRDF for sensitivities: per θi layer, ln f as a low-degree
//! polynomial of the view direction's projection in the frame of the light's azimuth,
//! (u, v) = sin θo · (cos Δφ, sin Δφ), in the even powers of v only, fitted by least squares
//! to the layer's nodes; between layers, linear in θi.
//!
//! Why not the interpolant (`resample::LayeredResampler`): it passes through every node, and
//! the light sweeps need its *slopes* (∂ ln Y / ∂q through the rig's kinematics). With one node
//! per isotropy class and a per cent of noise in each, an interpolant's slopes are several times
//! too steep and barely correlated with the BRDF's (docs/decisions.md). A least-squares polynomial smooths the nodes instead of following them.
//! Polynomials in (u, v) are smooth at the pole (θo = 0, where Δφ is undefined), and even in v
//! they are even in Δφ: the isotropic symmetry f(Δφ) = f(−Δφ) holds by construction, so a node
//! counts on both sides of the plane of incidence.

use super::geometry::Vec3;
use nalgebra::{DMatrix, DVector};

/// One node: the directions (sample frame) and ln f there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Node {
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub ln_f: f64,
}

/// The highest total degree in (u, v) a layer is fitted with.
pub(crate) const MAX_DEGREE: usize = 6;
/// A layer's degree is the highest whose term count is at most 1 / `NODES_PER_TERM` of its
/// nodes (fewer nodes, a smoother fit).
const NODES_PER_TERM: usize = 3;
/// Layers whose θi differ by less than this (radians) are one layer.
const LAYER_TOLERANCE: f64 = 1e-4;

/// The fitted layers, in ascending θi.
#[derive(Debug, Clone)]
pub(crate) struct SmoothBrdf {
    layers: Vec<Layer>,
}

#[derive(Debug, Clone)]
struct Layer {
    theta_i: f64,
    degree: usize,
    coef: DVector<f64>,
}

/// The terms u^a v^(2b), a + 2b ≤ degree, in a fixed order.
fn terms(u: f64, v: f64, degree: usize) -> Vec<f64> {
    let v2 = v * v;
    let mut out = Vec::with_capacity(term_count(degree));
    let mut vb = 1.0;
    for b in 0..=degree / 2 {
        let mut ua = 1.0;
        for _ in 0..=(degree - 2 * b) {
            out.push(ua * vb);
            ua *= u;
        }
        vb *= v2;
    }
    out
}

fn term_count(degree: usize) -> usize {
    (0..=degree / 2).map(|b| degree - 2 * b + 1).sum()
}

/// θi, and (u, v) of the view direction in the frame of the light's azimuth.
fn coordinates(omega_i: &Vec3, omega_o: &Vec3) -> (f64, f64, f64) {
    let theta_i = omega_i.z.clamp(-1.0, 1.0).acos();
    let phi_i = if omega_i.x == 0.0 && omega_i.y == 0.0 {
        0.0
    } else {
        omega_i.y.atan2(omega_i.x)
    };
    let (s, c) = phi_i.sin_cos();
    // rotate the view direction by −φi about the normal
    let u = c * omega_o.x + s * omega_o.y;
    let v = -s * omega_o.x + c * omega_o.y;
    (theta_i, u, v)
}

impl SmoothBrdf {
    /// Fits every θi layer that has enough nodes for a constant and a slope in u (degree 1: at
    /// least `NODES_PER_TERM` · 2). `None` when no layer has; non-finite nodes are skipped.
    pub(crate) fn fit(nodes: &[Node]) -> Option<Self> {
        let mut rows: Vec<(f64, f64, f64, f64)> = nodes
            .iter()
            .filter(|n| n.ln_f.is_finite())
            .map(|n| {
                let (t, u, v) = coordinates(&n.omega_i, &n.omega_o);
                (t, u, v, n.ln_f)
            })
            .filter(|r| r.0.is_finite() && r.1.is_finite() && r.2.is_finite())
            .collect();
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut layers = Vec::new();
        let mut start = 0;
        while start < rows.len() {
            let theta = rows[start].0;
            let end = rows[start..]
                .iter()
                .position(|r| r.0 - theta > LAYER_TOLERANCE)
                .map_or(rows.len(), |p| start + p);
            if let Some(layer) = Self::fit_layer(theta, &rows[start..end]) {
                layers.push(layer);
            }
            start = end;
        }
        (!layers.is_empty()).then_some(SmoothBrdf { layers })
    }

    fn fit_layer(theta_i: f64, rows: &[(f64, f64, f64, f64)]) -> Option<Layer> {
        let n = rows.len();
        let degree = (1..=MAX_DEGREE)
            .rev()
            .find(|&d| term_count(d) * NODES_PER_TERM <= n)?;
        let p = term_count(degree);
        let features: Vec<Vec<f64>> = rows.iter().map(|r| terms(r.1, r.2, degree)).collect();
        let x = DMatrix::from_fn(n, p, |i, j| features[i][j]);
        let y = DVector::from_iterator(n, rows.iter().map(|r| r.3));
        let coef = x.svd(true, true).solve(&y, 1e-10).ok()?;
        coef.iter().all(|c| c.is_finite()).then_some(Layer {
            theta_i,
            degree,
            coef,
        })
    }

    fn layer_value(layer: &Layer, u: f64, v: f64) -> f64 {
        terms(u, v, layer.degree)
            .iter()
            .zip(layer.coef.iter())
            .map(|(t, c)| t * c)
            .sum()
    }

    /// ln f at the directions: the layer's polynomial, linear in θi between the two layers
    /// around it. `None` outside the fitted layers' θi range (no extrapolation).
    pub(crate) fn ln_f(&self, omega_i: &Vec3, omega_o: &Vec3) -> Option<f64> {
        let (theta, u, v) = coordinates(omega_i, omega_o);
        let first = self.layers.first()?;
        let last = self.layers.last()?;
        if theta < first.theta_i - LAYER_TOLERANCE || theta > last.theta_i + LAYER_TOLERANCE {
            return None;
        }
        let upper = self
            .layers
            .iter()
            .position(|l| l.theta_i >= theta - LAYER_TOLERANCE)?;
        let hi = &self.layers[upper];
        if (hi.theta_i - theta).abs() <= LAYER_TOLERANCE || upper == 0 {
            return Some(Self::layer_value(hi, u, v)).filter(|v| v.is_finite());
        }
        let lo = &self.layers[upper - 1];
        let t = (theta - lo.theta_i) / (hi.theta_i - lo.theta_i);
        Some((1.0 - t) * Self::layer_value(lo, u, v) + t * Self::layer_value(hi, u, v))
            .filter(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::geometry::Spherical;

    fn dir(theta: f64, phi: f64) -> Vec3 {
        Spherical::from_deg(theta, phi).to_vector()
    }

    #[test]
    fn a_smooth_isotropic_function_is_reproduced_and_is_even_in_the_azimuth() {
        // ln f = 0.2 + 0.5 u − 0.3 v² + 0.1 u² at θi = 30° and 45°, on a ring grid
        let truth = |wi: &Vec3, wo: &Vec3| {
            let (_, u, v) = coordinates(wi, wo);
            0.2 + 0.5 * u - 0.3 * v * v + 0.1 * u * u
        };
        let mut nodes = Vec::new();
        for ti in [30.0, 45.0] {
            for to in [0.0, 15.0, 30.0, 45.0, 60.0, 75.0] {
                for k in 0..12 {
                    let (wi, wo) = (dir(ti, 40.0), dir(to, 40.0 + 30.0 * k as f64));
                    nodes.push(Node {
                        omega_i: wi,
                        omega_o: wo,
                        ln_f: truth(&wi, &wo),
                    });
                }
            }
        }
        let m = SmoothBrdf::fit(&nodes).unwrap();
        assert_eq!(m.layers.len(), 2);
        let (wi, wo) = (dir(30.0, 10.0), dir(52.0, 77.0));
        assert!((m.ln_f(&wi, &wo).unwrap() - truth(&wi, &wo)).abs() < 1e-9);
        // the mirror image across the plane of incidence
        let wo_m = dir(52.0, 10.0 - 67.0);
        assert!((m.ln_f(&wi, &wo_m).unwrap() - m.ln_f(&wi, &wo).unwrap()).abs() < 1e-9);
        // between the layers: linear in θi; outside them: nothing
        let mid = m.ln_f(&dir(37.5, 10.0), &wo).unwrap();
        let (a, b) = (
            m.ln_f(&dir(30.0, 10.0), &wo).unwrap(),
            m.ln_f(&dir(45.0, 10.0), &wo).unwrap(),
        );
        assert!((mid - 0.5 * (a + b)).abs() < 1e-9);
        assert!(m.ln_f(&dir(50.0, 10.0), &wo).is_none());
        assert!(m.ln_f(&dir(20.0, 10.0), &wo).is_none());
    }

    #[test]
    fn few_nodes_lower_the_degree_and_too_few_or_bad_nodes_give_nothing() {
        let nodes: Vec<Node> = (0..13)
            .map(|k| Node {
                omega_i: dir(45.0, 0.0),
                omega_o: dir(30.0, 27.0 * k as f64),
                ln_f: 0.1 * k as f64,
            })
            .collect();
        // 13 nodes: degree 2 (4 terms) at 3 nodes per term
        let m = SmoothBrdf::fit(&nodes).unwrap();
        assert_eq!(m.layers[0].degree, 2);
        assert!(SmoothBrdf::fit(&nodes[..5]).is_none());
        let bad: Vec<Node> = nodes
            .iter()
            .map(|n| Node {
                ln_f: f64::NAN,
                ..*n
            })
            .collect();
        assert!(SmoothBrdf::fit(&bad).is_none());
        assert!(SmoothBrdf::fit(&[]).is_none());
    }
}
