//! Resampling of tabulated BRDF data in the paper's parameterisation (Section 5.3), on top of
//! Renka's modified Shepard interpolation (`measure::shepard`).
//!
//! Two layouts:
//! - **slice**: the samples of one incoming direction ωi, at (x, y) = the extended concentric
//!   square centred on ωi's mirror direction (`MirrorAlignedMap`); cubic Shepard (CSHEP2D) when
//!   there are enough samples, quadratic (QSHEP2D) otherwise. Works for any sample, isotropic
//!   or not: the live check uses it for occlusion substitutes, whose partner pose has a plan
//!   light but an off-grid camera.
//! - **isotropic**: samples of an isotropic material at (θi·s, x, y), every direction pair first
//!   rotated about the normal so that φi = 0; quadratic Shepard in 3-D (QSHEP3D). Used to
//!   resample a reference measurement (other θi than the session's) at the session's poses.
//!   Samples that land on the same point (an isotropy class, or repeats) are merged into their
//!   mean first: duplicate nodes would make the nodal fits meaningless.
//!
//! Every value comes with the spread of the nodal functions at the query point (per channel),
//! the interpolation's own uncertainty estimate.

use super::colour::Xyz;
use super::geometry::{MirrorAlignedMap, Spherical, Vec3};
use super::shepard::{Method, Shepard, ShepardError};
use std::collections::HashMap;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum ResampleError {
    #[error("{0} usable samples; at least {1} are needed")]
    TooFewSamples(usize, usize),
    #[error("the interpolant could not be built: {0}")]
    Build(ShepardError),
    #[error("the query lies outside the data's reach (no sample within any radius of influence)")]
    Outside,
    #[error("a direction is below the horizon or not finite")]
    BadDirection,
}

/// One tabulated value: incoming and outgoing unit vectors (sample frame) and an XYZ value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub value: Xyz,
}

/// Neighbour counts and the θi scale of the 3-D layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResampleSpec {
    /// Nodes in each nodal fit and in each radius of influence (2-D cubic; Renka: 17, 30).
    pub nc_2d: usize,
    pub nw_2d: usize,
    /// The same for the 3-D quadratic (Renka: 17, 32).
    pub nq_3d: usize,
    pub nw_3d: usize,
    /// Units of the θi axis per degree of θi, against the square's ≈ 1/360 per degree of
    /// outgoing angle near the mirror direction.
    pub theta_per_deg: f64,
    /// Interpolate ln(value) when every value is positive: a specular lobe is close to a
    /// Gaussian, i.e. a quadratic in ln f, so the nodal quadratics follow it instead of
    /// overshooting beside it (a steep lobe otherwise makes nodal fits far from it swing by
    /// the lobe's height). Data with zero or negative values stay linear.
    pub log_values: bool,
    /// Across θi layers, interpolate the value × cos θi × cos θo (each layer's at its own
    /// direction for the query's square point) and divide the query's cosines back out. A
    /// microfacet lobe's D·F·G/4 changes far more slowly with θi than the BRDF, whose
    /// 1/(cos θi cos θo) grows fifteenfold from θ = 60° to 75°. Within a layer nothing changes.
    pub cosine_across_layers: bool,
}

impl Default for ResampleSpec {
    fn default() -> Self {
        ResampleSpec {
            nc_2d: 17,
            nw_2d: 30,
            nq_3d: 17,
            nw_3d: 32,
            theta_per_deg: 1.0 / 360.0,
            log_values: true,
            cosine_across_layers: false,
        }
    }
}

/// An interpolated value with the nodal spread of each channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resampled {
    pub value: Xyz,
    pub spread: Xyz,
}

#[derive(Debug, Clone)]
enum Layout {
    Slice(MirrorAlignedMap),
    Isotropic { theta_per_deg: f64 },
}

/// A resampler over one data set: one Shepard interpolant per XYZ channel.
#[derive(Debug, Clone)]
pub struct Resampler {
    layout: Layout,
    channels: [Shepard; 3],
    nodes: usize,
    method: Method,
    log: bool,
    /// Per channel, the range of the node values (in the interpolated space): results are
    /// clamped to it widened by `RANGE_MARGIN` of its span on each side. A nodal polynomial
    /// fitted across a steep lobe can swing far beyond the data beside it (by orders of
    /// magnitude on UBO-sampled data); a peak just off the data (a retro-reflection hole) may
    /// rightly lie a little above the largest node.
    range: [(f64, f64); 3],
}

/// How far beyond the node values' range a result may go: a fraction of the span for linear
/// values, a ratio (1 + this) for ln values.
pub(crate) const RANGE_MARGIN: f64 = 0.25;

/// Points closer than this (in the layout's coordinates) are one node.
const MERGE_TOL: f64 = 1e-7;

fn finite_up(v: &Vec3) -> bool {
    v.iter().all(|c| c.is_finite()) && v.z >= 0.0 && v.norm() > 0.0
}

/// Both directions on or above the horizon and every value finite.
fn usable(s: &Sample) -> bool {
    finite_up(&s.omega_i) && finite_up(&s.omega_o) && s.value.iter().all(|v| v.is_finite())
}

/// The isotropic layout's coordinates of a direction pair: rotate both about the normal so that
/// φi = 0, then (θi·s, x, y) with (x, y) the mirror-aligned square of the rotated ωo.
pub(crate) fn isotropic_coords(omega_i: &Vec3, omega_o: &Vec3, theta_per_deg: f64) -> [f64; 3] {
    let (theta_i, wo) = rotate_to_phi_zero(omega_i, omega_o);
    let (x, y) = MirrorAlignedMap::new(&Spherical::from_deg(theta_i, 0.0).to_vector()).square(&wo);
    [theta_i * theta_per_deg, x, y]
}

/// Merge points within `MERGE_TOL` of each other into one node with the mean value.
fn merge(points: Vec<([f64; 3], Xyz)>) -> Vec<([f64; 3], Xyz)> {
    let key = |p: &[f64; 3]| {
        [
            (p[0] / MERGE_TOL).round() as i64,
            (p[1] / MERGE_TOL).round() as i64,
            (p[2] / MERGE_TOL).round() as i64,
        ]
    };
    let mut groups: Vec<([f64; 3], [f64; 3], usize)> = Vec::new();
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    for (p, v) in points {
        let k = key(&p);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(&g) = index.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        let q = groups[g].0;
                        let d =
                            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                                .sqrt();
                        if d <= MERGE_TOL {
                            found = Some(g);
                            break 'search;
                        }
                    }
                }
            }
        }
        match found {
            Some(g) => {
                let e = &mut groups[g];
                for c in 0..3 {
                    e.1[c] += v[c];
                }
                e.2 += 1;
            }
            None => {
                index.insert(k, groups.len());
                groups.push((p, v, 1));
            }
        }
    }
    groups
        .into_iter()
        .map(|(p, s, n)| {
            let n = n as f64;
            (p, [s[0] / n, s[1] / n, s[2] / n])
        })
        .collect()
}

impl Resampler {
    /// The samples of one incoming direction (their own ωi is ignored) in the mirror-aligned
    /// square of `omega_i`.
    pub(crate) fn slice(
        samples: &[Sample],
        omega_i: &Vec3,
        spec: &ResampleSpec,
    ) -> Result<Self, ResampleError> {
        if !finite_up(omega_i) {
            return Err(ResampleError::BadDirection);
        }
        let map = MirrorAlignedMap::new(&omega_i.normalize());
        let points: Vec<([f64; 3], Xyz)> = samples
            .iter()
            .filter(|s| finite_up(&s.omega_o) && s.value.iter().all(|v| v.is_finite()))
            .map(|s| {
                let (x, y) = map.square(&s.omega_o.normalize());
                ([x, y, 0.0], s.value)
            })
            .collect();
        let points = merge(points);
        let n = points.len();
        // cubic with Renka's counts when there are enough nodes; else quadratic with what there is
        let (method, nq, nw) = if n > spec.nc_2d.max(spec.nw_2d) {
            (Method::Cubic2, spec.nc_2d, spec.nw_2d)
        } else if n >= 7 {
            (Method::Quadratic2, 5.max((n - 1).min(13)), (n - 1).min(19))
        } else {
            return Err(ResampleError::TooFewSamples(n, 7));
        };
        Self::build(Layout::Slice(map), points, method, nq, nw, spec.log_values)
    }

    /// Samples of an isotropic material over any incoming directions, in (θi·s, x, y).
    pub fn isotropic(samples: &[Sample], spec: &ResampleSpec) -> Result<Self, ResampleError> {
        let points: Vec<([f64; 3], Xyz)> = samples
            .iter()
            .filter(|s| usable(s))
            .map(|s| {
                (
                    isotropic_coords(&s.omega_i, &s.omega_o, spec.theta_per_deg),
                    s.value,
                )
            })
            .collect();
        let points = merge(points);
        let n = points.len();
        if n <= spec.nq_3d.max(spec.nw_3d) {
            return Err(ResampleError::TooFewSamples(
                n,
                spec.nq_3d.max(spec.nw_3d) + 1,
            ));
        }
        Self::build(
            Layout::Isotropic {
                theta_per_deg: spec.theta_per_deg,
            },
            points,
            Method::Quadratic3,
            spec.nq_3d,
            spec.nw_3d,
            spec.log_values,
        )
    }

    fn build(
        layout: Layout,
        points: Vec<([f64; 3], Xyz)>,
        method: Method,
        nq: usize,
        nw: usize,
        log_values: bool,
    ) -> Result<Self, ResampleError> {
        let p: Vec<[f64; 3]> = points.iter().map(|(p, _)| *p).collect();
        let log = log_values && points.iter().all(|(_, v)| v.iter().all(|c| *c > 0.0));
        let fit = |c: usize| {
            let f: Vec<f64> = points
                .iter()
                .map(|(_, v)| if log { v[c].ln() } else { v[c] })
                .collect();
            Shepard::fit(method, &p, &f, nq, nw).map_err(ResampleError::Build)
        };
        let range = [0, 1, 2].map(|c| {
            points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, v)| {
                    let x = if log { v[c].ln() } else { v[c] };
                    (lo.min(x), hi.max(x))
                })
        });
        Ok(Resampler {
            layout,
            channels: [fit(0)?, fit(1)?, fit(2)?],
            nodes: p.len(),
            method,
            log,
            range,
        })
    }

    /// Nodes after merging.
    pub(crate) fn nodes(&self) -> usize {
        self.nodes
    }

    /// `cshep2d`, `qshep2d` or `qshep3d`.
    pub(crate) fn method_name(&self) -> &'static str {
        match self.method {
            Method::Cubic2 => "cshep2d",
            Method::Quadratic2 => "qshep2d",
            Method::Quadratic3 => "qshep3d",
        }
    }

    /// The value at a point of a slice's square (the isotropic layout's θi axis at 0).
    fn at_square(&self, x: f64, y: f64) -> Result<Resampled, ResampleError> {
        self.at_point([x, y, 0.0])
    }

    fn at_point(&self, q: [f64; 3]) -> Result<Resampled, ResampleError> {
        let mut value = [0.0; 3];
        let mut spread = [0.0; 3];
        for c in 0..3 {
            let (v, s) = self.channels[c]
                .value_with_spread(&q)
                .map_err(|e| match e {
                    ShepardError::Outside { .. } => ResampleError::Outside,
                    other => ResampleError::Build(other),
                })?;
            let (lo, hi) = self.range[c];
            // ln values: at most RANGE_MARGIN beyond the extreme nodes as a *ratio*; linear
            // values: RANGE_MARGIN of the span
            let margin = if self.log {
                (1.0 + RANGE_MARGIN).ln()
            } else {
                RANGE_MARGIN * (hi - lo)
            };
            let clamped = v.clamp(lo - margin, hi + margin);
            if self.log {
                // first order: d(e^u) = e^u du; a clamped value is at least as uncertain as the
                // amount the clamp removed
                value[c] = clamped.exp();
                spread[c] = (value[c] * s).max((v.exp() - value[c]).abs().min(value[c]));
            } else {
                value[c] = clamped;
                spread[c] = s.max((v - clamped).abs());
            }
        }
        Ok(Resampled { value, spread })
    }

    /// The value at a direction pair (a slice ignores `omega_i`).
    pub fn at(&self, omega_i: &Vec3, omega_o: &Vec3) -> Result<Resampled, ResampleError> {
        if !finite_up(omega_o) || !finite_up(omega_i) {
            return Err(ResampleError::BadDirection);
        }
        let q = match &self.layout {
            Layout::Slice(map) => {
                let (x, y) = map.square(&omega_o.normalize());
                [x, y, 0.0]
            }
            Layout::Isotropic { theta_per_deg } => {
                isotropic_coords(omega_i, omega_o, *theta_per_deg)
            }
        };
        self.at_point(q)
    }
}

/// An isotropic data set measured in layers of θi (a reference instrument's incidence angles,
/// or a session's): a slice interpolant per layer in the mirror-aligned square, and a Lagrange
/// polynomial across the (up to) two layers below and two above the query's θi. The square
/// coordinates follow the mirror direction, so a specular lobe sits at the same (x, y) in every
/// layer and the θi interpolation only has to follow its slow change. Values must not carry the
/// cos θi factor (pass BRDF-like values), or the θi interpolation follows the cosine instead.
#[derive(Debug, Clone)]
pub struct LayeredResampler {
    /// (θi of the layer in degrees, its slice, cos of the largest θo it holds), ascending θi.
    layers: Vec<(f64, Resampler, f64)>,
    cosine_across_layers: bool,
}

/// Samples within this of a layer's θi belong to it (degrees).
pub(crate) const LAYER_TOL_DEG: f64 = 0.25;

fn rotate_to_phi_zero(omega_i: &Vec3, omega_o: &Vec3) -> (f64, Vec3) {
    let si = Spherical::from_vector(omega_i);
    let (c, s) = (si.phi.cos(), si.phi.sin());
    let wo = omega_o.normalize();
    (
        si.theta_deg(),
        Vec3::new(c * wo.x + s * wo.y, -s * wo.x + c * wo.y, wo.z),
    )
}

impl LayeredResampler {
    pub fn new(samples: &[Sample], spec: &ResampleSpec) -> Result<Self, ResampleError> {
        let mut rotated: Vec<(f64, Sample)> = samples
            .iter()
            .filter(|s| usable(s))
            .map(|s| {
                let (t, wo) = rotate_to_phi_zero(&s.omega_i, &s.omega_o);
                (
                    t,
                    Sample {
                        omega_i: Spherical::from_deg(t, 0.0).to_vector(),
                        omega_o: wo,
                        value: s.value,
                    },
                )
            })
            .collect();
        rotated.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut layers = Vec::new();
        let mut start = 0;
        while start < rotated.len() {
            let mut end = start + 1;
            while end < rotated.len() && rotated[end].0 - rotated[start].0 <= 2.0 * LAYER_TOL_DEG {
                end += 1;
            }
            let group = &rotated[start..end];
            let theta = group.iter().map(|g| g.0).sum::<f64>() / group.len() as f64;
            let members: Vec<Sample> = group.iter().map(|g| g.1).collect();
            let min_cos_o = members
                .iter()
                .map(|m| m.omega_o.normalize().z)
                .fold(1.0, f64::min);
            // a layer with too few usable samples is left out; the others interpolate across it
            if let Ok(r) =
                Resampler::slice(&members, &Spherical::from_deg(theta, 0.0).to_vector(), spec)
            {
                layers.push((theta, r, min_cos_o));
            }
            start = end;
        }
        if layers.is_empty() {
            return Err(ResampleError::TooFewSamples(rotated.len(), 7));
        }
        Ok(LayeredResampler {
            layers,
            cosine_across_layers: spec.cosine_across_layers,
        })
    }

    /// θi of the layers (degrees).
    pub(crate) fn layer_thetas(&self) -> Vec<f64> {
        self.layers.iter().map(|l| l.0).collect()
    }

    /// The value at a direction pair. The spread combines the slices' nodal spreads (through
    /// the Lagrange weights) and the difference between the polynomial and the linear
    /// interpolation across θi.
    pub fn at(&self, omega_i: &Vec3, omega_o: &Vec3) -> Result<Resampled, ResampleError> {
        if !finite_up(omega_i) || !finite_up(omega_o) {
            return Err(ResampleError::BadDirection);
        }
        let (tq, wo) = rotate_to_phi_zero(omega_i, omega_o);
        let (x, y) = MirrorAlignedMap::new(&Spherical::from_deg(tq, 0.0).to_vector()).square(&wo);
        // the factor a layer's value is carried across layers with (1: the value itself)
        let cos_weight = |t: f64, z: f64| t.to_radians().cos() * z;
        let eval_weighted = |k: usize, weighted: bool| -> Result<Resampled, ResampleError> {
            let (t, r, min_cos_o) = &self.layers[k];
            // the same square point, seen from the layer's own mirror direction, must lie within
            // the layer's data (no further from the pole than its largest θo): no extrapolation
            let map = MirrorAlignedMap::new(&Spherical::from_deg(*t, 0.0).to_vector());
            let z = map.direction(x, y).z;
            if z < min_cos_o - 1e-9 {
                return Err(ResampleError::Outside);
            }
            let v = r.at_square(x, y)?;
            let w = if weighted { cos_weight(*t, z) } else { 1.0 };
            Ok(Resampled {
                value: v.value.map(|c| c * w),
                spread: v.spread.map(|c| c * w),
            })
        };
        let n = self.layers.len();
        let above = self.layers.partition_point(|l| l.0 < tq);
        // on a layer
        for k in [above.wrapping_sub(1), above] {
            if k < n && (self.layers[k].0 - tq).abs() <= LAYER_TOL_DEG {
                return eval_weighted(k, false);
            }
        }
        if above == 0 || above == n {
            return Err(ResampleError::Outside);
        }
        // across the layers around the query: (value, how many layers it came from)
        let across = |weighted: bool| -> Result<(Resampled, usize), ResampleError> {
            let eval = |k: usize| eval_weighted(k, weighted);
            let (lo, hi) = (above - 1, above);
            let near_lo = eval(lo)?;
            let near_hi = eval(hi)?;
            let mut pts: Vec<(f64, Resampled)> =
                vec![(self.layers[lo].0, near_lo), (self.layers[hi].0, near_hi)];
            if lo >= 1 {
                if let Ok(v) = eval(lo - 1) {
                    pts.insert(0, (self.layers[lo - 1].0, v));
                }
            }
            if hi + 1 < n {
                if let Ok(v) = eval(hi + 1) {
                    pts.push((self.layers[hi + 1].0, v));
                }
            }
            let lagrange = |k: usize| {
                pts.iter()
                    .enumerate()
                    .filter(|(j, _)| *j != k)
                    .map(|(_, (tj, _))| (tq - tj) / (pts[k].0 - tj))
                    .product::<f64>()
            };
            let weights: Vec<f64> = (0..pts.len()).map(lagrange).collect();
            let (t0, t1) = (self.layers[lo].0, self.layers[hi].0);
            let u = (tq - t0) / (t1 - t0);
            let mut value = [0.0; 3];
            let mut spread = [0.0; 3];
            for c in 0..3 {
                let poly: f64 = pts
                    .iter()
                    .zip(&weights)
                    .map(|((_, r), w)| w * r.value[c])
                    .sum();
                let linear = (1.0 - u) * near_lo.value[c] + u * near_hi.value[c];
                let nodal: f64 = pts
                    .iter()
                    .zip(&weights)
                    .map(|((_, r), w)| (w * r.spread[c]).powi(2))
                    .sum();
                // no more than RANGE_MARGIN beyond the layers it comes from (a polynomial through
                // four layers can swing); what the clamp removes counts as uncertainty
                let lo = pts
                    .iter()
                    .map(|(_, r)| r.value[c])
                    .fold(f64::INFINITY, f64::min);
                let hi = pts
                    .iter()
                    .map(|(_, r)| r.value[c])
                    .fold(f64::NEG_INFINITY, f64::max);
                let (lo, hi) = if lo > 0.0 {
                    (lo / (1.0 + RANGE_MARGIN), hi * (1.0 + RANGE_MARGIN))
                } else {
                    (lo - RANGE_MARGIN * (hi - lo), hi + RANGE_MARGIN * (hi - lo))
                };
                value[c] = poly.clamp(lo, hi);
                spread[c] = (nodal + (poly - linear).powi(2))
                    .sqrt()
                    .max((poly - value[c]).abs());
            }
            // back from the weighted values to the query's own
            let wq = if weighted { cos_weight(tq, wo.z) } else { 1.0 };
            if !(wq > 0.0) {
                return Err(ResampleError::Outside);
            }
            Ok((
                Resampled {
                    value: value.map(|v| v / wq),
                    spread: spread.map(|v| v / wq),
                },
                pts.len(),
            ))
        };
        // the cosines' curvature near grazing is more than a line between two layers follows:
        // weighted only where three or more layers carry the query
        if self.cosine_across_layers {
            let (r, layers) = across(true)?;
            if layers >= 3 {
                return Ok(r);
            }
        }
        across(false).map(|r| r.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::plan::SamplingPlan;

    fn dir(t: f64, p: f64) -> Vec3 {
        Spherical::from_deg(t, p).to_vector()
    }

    /// A smooth, glossy-ish isotropic test function of the direction pair.
    fn f(wi: &Vec3, wo: &Vec3) -> Xyz {
        let m = Vec3::new(-wi.x, -wi.y, wi.z);
        let c = m.dot(wo).max(0.0);
        let base = 20.0 + 30.0 * wi.z * wo.z + 15.0 * c.powi(4);
        [base * 0.95, base, base * 1.09]
    }

    #[test]
    fn slice_reproduces_a_smooth_function_near_the_retro_direction() {
        let plan = SamplingPlan::ubo();
        let dirs: Vec<Vec3> = plan
            .directions()
            .iter()
            .map(|d| d.spherical().to_vector())
            .collect();
        let wi = dir(30.0, 60.0);
        // the retro direction itself is missing, as for an occlusion substitute
        let samples: Vec<Sample> = dirs
            .iter()
            .filter(|wo| (*wo - wi).norm() > 1e-9)
            .map(|wo| Sample {
                omega_i: wi,
                omega_o: *wo,
                value: f(&wi, wo),
            })
            .collect();
        let r = Resampler::slice(&samples, &wi, &ResampleSpec::default()).unwrap();
        assert_eq!(r.method_name(), "cshep2d");
        assert_eq!(r.nodes(), 80);
        let q = dir(42.0, 60.0);
        let got = r.at(&wi, &q).unwrap();
        let want = f(&wi, &q);
        for c in 0..3 {
            let rel = (got.value[c] - want[c]).abs() / want[c];
            assert!(rel < 0.01, "channel {c}: {} vs {}", got.value[c], want[c]);
            assert!(got.spread[c].is_finite() && got.spread[c] >= 0.0);
        }
        // at a node: exact, no spread
        let at_node = r.at(&wi, &dirs[5]).unwrap();
        assert_eq!(at_node.spread, [0.0; 3]);
    }

    fn ubo_isotropic_samples() -> Vec<Sample> {
        ubo_samples_of(f)
    }

    /// Every (light, camera) pair of the UBO plan with the value `g` gives it.
    fn ubo_samples_of(g: impl Fn(&Vec3, &Vec3) -> Xyz) -> Vec<Sample> {
        let plan = SamplingPlan::ubo();
        let dirs: Vec<Vec3> = plan
            .directions()
            .iter()
            .map(|d| d.spherical().to_vector())
            .collect();
        let mut samples = Vec::new();
        for wi in &dirs {
            for wo in &dirs {
                samples.push(Sample {
                    omega_i: *wi,
                    omega_o: *wo,
                    value: g(wi, wo),
                });
            }
        }
        samples
    }

    fn rot(v: &Vec3, a: f64) -> Vec3 {
        let (c, s) = (a.cos(), a.sin());
        Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
    }

    #[test]
    fn qshep3d_layout_merges_isotropy_classes_and_is_rotation_invariant() {
        let samples = ubo_isotropic_samples();
        let spec = ResampleSpec {
            theta_per_deg: 1e-3,
            ..Default::default()
        };
        let r = Resampler::isotropic(&samples, &spec).unwrap();
        // 6,561 pairs fall into 1,378 distinct (θi, relative ωo) points
        assert_eq!(r.nodes(), 1378);
        let (wi, wo) = (dir(37.0, 100.0), dir(25.0, 290.0));
        let got = r.at(&wi, &wo).unwrap().value;
        let got2 = r.at(&rot(&wi, 1.0), &rot(&wo, 1.0)).unwrap().value;
        assert!((got2[1] - got[1]).abs() < 1e-9 * got[1]);
        // layered data at the square's own scale give some nodes coplanar nearest neighbours:
        // their fits take more nodes (Renka's rule), from the layers above and below, until the
        // fit is well conditioned, and the value agrees with the finer θ scale's
        let layered = Resampler::isotropic(&samples, &ResampleSpec::default()).unwrap();
        let v = layered.at(&wi, &wo).unwrap().value;
        assert!(
            (v[1] - got[1]).abs() < 0.05 * got[1],
            "{v:?} against {got:?}"
        );
    }

    #[test]
    fn layered_resampler_interpolates_across_theta_i() {
        let samples = ubo_isotropic_samples();
        let r = LayeredResampler::new(&samples, &ResampleSpec::default()).unwrap();
        assert_eq!(r.layer_thetas().len(), 6);
        let mut worst: f64 = 0.0;
        for (ti, to, po) in [
            (37.0, 25.0, 290.0),
            (22.0, 40.0, 180.0),
            (52.5, 50.0, 175.0),
            (8.0, 30.0, 45.0),
        ] {
            let (wi, wo) = (dir(ti, 100.0), dir(to, po + 100.0));
            let got = r.at(&wi, &wo).unwrap();
            let want = f(&wi, &wo);
            worst = worst.max((got.value[1] - want[1]).abs() / want[1]);
            assert!(got.spread[1] > 0.0);
            let again = r.at(&rot(&wi, 2.0), &rot(&wo, 2.0)).unwrap();
            assert!((again.value[1] - got.value[1]).abs() < 1e-9 * got.value[1]);
        }
        assert!(worst < 0.03, "{worst}");
        // on a layer the layer's own slice answers; beyond the last layer nothing is invented
        let on = r.at(&dir(45.0, 0.0), &dir(45.0, 180.0)).unwrap().value;
        assert!((on[1] - f(&dir(45.0, 0.0), &dir(45.0, 180.0))[1]).abs() < 1e-9);
        assert_eq!(
            r.at(&dir(80.0, 0.0), &dir(30.0, 180.0)).unwrap_err(),
            ResampleError::Outside
        );
    }

    /// A microfacet-like lobe: D of the half vector (GGX, α = 0.3) over 4 cos θi cos θo.
    fn lobe(wi: &Vec3, wo: &Vec3) -> f64 {
        let h = (wi + wo).normalize();
        let a2 = 0.09;
        let d = h.z * h.z * (a2 - 1.0) + 1.0;
        0.05 + 0.2 * a2 / (std::f64::consts::PI * d * d) / (4.0 * wi.z * wo.z)
    }

    #[test]
    fn cosine_weighting_across_layers_follows_a_lobe_at_high_theta_and_leaves_layers_alone() {
        let samples = ubo_samples_of(|wi, wo| [lobe(wi, wo); 3]);
        let plain = LayeredResampler::new(&samples, &ResampleSpec::default()).unwrap();
        let weighted = LayeredResampler::new(
            &samples,
            &ResampleSpec {
                cosine_across_layers: true,
                ..ResampleSpec::default()
            },
        )
        .unwrap();
        // near the mirror direction between the 45°, 60° and 75° layers
        let (mut e_plain, mut e_weighted) = (0.0f64, 0.0f64);
        for ti in [50.0, 52.5, 55.0, 63.0, 66.0, 69.0] {
            for dphi in [0.0, 4.0, 8.0] {
                let (wi, wo) = (dir(ti, 0.0), dir(ti - 2.0, 180.0 + dphi));
                let want = lobe(&wi, &wo);
                let rel =
                    |r: &LayeredResampler| (r.at(&wi, &wo).unwrap().value[1] / want - 1.0).abs();
                e_plain = e_plain.max(rel(&plain));
                e_weighted = e_weighted.max(rel(&weighted));
            }
        }
        assert!(
            e_weighted < 0.5 * e_plain,
            "weighted {e_weighted}, plain {e_plain}"
        );
        // on a layer both give the layer's own value
        let (wi, wo) = (dir(60.0, 0.0), dir(50.0, 170.0));
        assert_eq!(plain.at(&wi, &wo).unwrap(), weighted.at(&wi, &wo).unwrap());
    }

    #[test]
    fn too_few_bad_directions_and_outside_are_typed() {
        let wi = dir(30.0, 0.0);
        let few: Vec<Sample> = (0..5)
            .map(|k| Sample {
                omega_i: wi,
                omega_o: dir(10.0 * k as f64, 0.0),
                value: [1.0; 3],
            })
            .collect();
        assert_eq!(
            Resampler::slice(&few, &wi, &ResampleSpec::default()).unwrap_err(),
            ResampleError::TooFewSamples(5, 7)
        );
        assert_eq!(
            Resampler::slice(
                &few,
                &Vec3::new(f64::NAN, 0.0, 1.0),
                &ResampleSpec::default()
            )
            .unwrap_err(),
            ResampleError::BadDirection
        );
        // a cluster of samples near the pole: a query at the horizon far away is Outside
        let cluster: Vec<Sample> = (0..40)
            .map(|k| Sample {
                omega_i: wi,
                omega_o: dir(1.0 + (k % 5) as f64, 9.0 * k as f64),
                value: [1.0 + k as f64 * 0.01; 3],
            })
            .collect();
        let r = Resampler::slice(&cluster, &wi, &ResampleSpec::default()).unwrap();
        assert_eq!(
            r.at(&wi, &dir(85.0, 180.0)).unwrap_err(),
            ResampleError::Outside
        );
    }

    #[test]
    fn duplicate_samples_are_merged_not_fatal() {
        let wi = dir(15.0, 0.0);
        let plan = SamplingPlan::ubo();
        let mut samples: Vec<Sample> = plan
            .directions()
            .iter()
            .map(|d| {
                let wo = d.spherical().to_vector();
                Sample {
                    omega_i: wi,
                    omega_o: wo,
                    value: f(&wi, &wo),
                }
            })
            .collect();
        // the same direction twice, with two readings, and one a hair away
        let mut twin = samples[10];
        twin.value = [
            twin.value[0] + 2.0,
            twin.value[1] + 2.0,
            twin.value[2] + 2.0,
        ];
        samples.push(twin);
        let mut hair = samples[20];
        hair.omega_o = (hair.omega_o + Vec3::new(1e-12, 0.0, 0.0)).normalize();
        samples.push(hair);
        let r = Resampler::slice(&samples, &wi, &ResampleSpec::default()).unwrap();
        assert_eq!(r.nodes(), 81);
        let at = r.at(&wi, &samples[10].omega_o).unwrap().value;
        assert!((at[1] - (samples[10].value[1] + 1.0)).abs() < 1e-9);
    }
}
