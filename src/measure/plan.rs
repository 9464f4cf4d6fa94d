//! The sampling plan: the UBO direction set (the paper's Table 1), the acquisition order, the
//! reciprocal pairs and the isotropy classes. All look-ups are O(1) index arithmetic.

use super::geometry::{azimuth_difference_deg, Spherical};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum PlanError {
    #[error("plan.thetas_deg and plan.delta_phi_deg must have the same length ({0} vs {1})")]
    LengthMismatch(usize, usize),
    #[error("plan.thetas_deg is empty")]
    Empty,
    #[error("plan.thetas_deg[{index}] = {value}: θ must be in [0, 90) and strictly increasing")]
    BadTheta { index: usize, value: f64 },
    #[error(
        "plan.delta_phi_deg[{index}] = {value}: Δφ must divide 360° into a whole number of steps"
    )]
    BadDeltaPhi { index: usize, value: f64 },
    #[error("plan.delta_phi_deg[{index}] = {value}: the plan would have more than {MAX_DIRECTIONS} directions ({MAX_DIRECTIONS}² captures); use a coarser Δφ")]
    TooLarge { index: usize, value: f64 },
    #[error("capture index {index} is outside the plan (0..{captures})")]
    IndexOutOfRange { index: usize, captures: usize },
}

/// The most directions a plan may have: 1,000 directions are 1,000,000 captures, far beyond any
/// gonioreflectometer run, and bound the memory the checks allocate per capture.
pub(crate) const MAX_DIRECTIONS: usize = 1000;

/// In which order the rig visits the (light, camera) combinations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AcquisitionOrder {
    /// For each light direction, all camera directions (the UBO default).
    #[default]
    LightOuter,
    /// For each camera direction, all light directions.
    CameraOuter,
    /// Light outer, camera inner, the camera sweep reversed on every other light direction.
    LightOuterSerpentine,
}

/// The plan's parameters as written in the config file (`[plan]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanSpec {
    /// Nominal polar angles θ in degrees.
    #[serde(default = "ubo_thetas")]
    pub thetas_deg: Vec<f64>,
    /// Azimuth increment Δφ per θ in degrees; at θ = 0 there is one direction whatever the value.
    #[serde(default = "ubo_delta_phi")]
    pub delta_phi_deg: Vec<f64>,
    #[serde(default)]
    pub order: AcquisitionOrder,
}

fn ubo_thetas() -> Vec<f64> {
    vec![0.0, 15.0, 30.0, 45.0, 60.0, 75.0]
}
fn ubo_delta_phi() -> Vec<f64> {
    vec![0.0, 60.0, 30.0, 20.0, 18.0, 15.0]
}

impl Default for PlanSpec {
    fn default() -> Self {
        PlanSpec {
            thetas_deg: ubo_thetas(),
            delta_phi_deg: ubo_delta_phi(),
            order: AcquisitionOrder::LightOuter,
        }
    }
}

/// One nominal direction of the plan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlanDirection {
    pub index: usize,
    pub theta_deg: f64,
    pub phi_deg: f64,
}

impl PlanDirection {
    pub fn spherical(&self) -> Spherical {
        Spherical::from_deg(self.theta_deg, self.phi_deg)
    }
}

/// One capture of the plan: a light and a camera direction (indices into `directions`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PlanEntry {
    pub index: usize,
    pub light: usize,
    pub camera: usize,
}

/// The key of an isotropy class: θ's and the wrapped azimuth difference in millidegrees.
/// The two θ's are sorted, so a capture and its reciprocal partner share a class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct IsotropyKey {
    pub theta_lo_mdeg: i64,
    pub theta_hi_mdeg: i64,
    pub dphi_mdeg: i64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SamplingPlan {
    directions: Vec<PlanDirection>,
    order: AcquisitionOrder,
}

fn mdeg(v: f64) -> i64 {
    (v * 1000.0).round() as i64
}

impl SamplingPlan {
    pub fn new(spec: &PlanSpec) -> Result<Self, PlanError> {
        if spec.thetas_deg.len() != spec.delta_phi_deg.len() {
            return Err(PlanError::LengthMismatch(
                spec.thetas_deg.len(),
                spec.delta_phi_deg.len(),
            ));
        }
        if spec.thetas_deg.is_empty() {
            return Err(PlanError::Empty);
        }
        let mut directions = Vec::new();
        let mut prev = f64::NEG_INFINITY;
        for (i, (&t, &dp)) in spec.thetas_deg.iter().zip(&spec.delta_phi_deg).enumerate() {
            if !(t.is_finite() && (0.0..90.0).contains(&t) && t > prev) {
                return Err(PlanError::BadTheta { index: i, value: t });
            }
            prev = t;
            if t == 0.0 {
                directions.push(PlanDirection {
                    index: directions.len(),
                    theta_deg: 0.0,
                    phi_deg: 0.0,
                });
                continue;
            }
            let steps = 360.0 / dp;
            if !(dp.is_finite() && dp > 0.0 && (steps - steps.round()).abs() < 1e-9) {
                return Err(PlanError::BadDeltaPhi {
                    index: i,
                    value: dp,
                });
            }
            // checked before a single direction of the ring is made
            if directions.len() as f64 + steps.round() > MAX_DIRECTIONS as f64 {
                return Err(PlanError::TooLarge {
                    index: i,
                    value: dp,
                });
            }
            for k in 0..steps.round() as usize {
                directions.push(PlanDirection {
                    index: directions.len(),
                    theta_deg: t,
                    phi_deg: dp * k as f64,
                });
            }
        }
        Ok(SamplingPlan {
            directions,
            order: spec.order,
        })
    }

    pub fn ubo() -> Self {
        // The UBO spec is a valid constant; `new` cannot fail on it.
        Self::new(&PlanSpec::default()).unwrap_or(SamplingPlan {
            directions: Vec::new(),
            order: AcquisitionOrder::LightOuter,
        })
    }

    pub fn directions(&self) -> &[PlanDirection] {
        &self.directions
    }
    pub(crate) fn order(&self) -> AcquisitionOrder {
        self.order
    }
    pub(crate) fn direction_count(&self) -> usize {
        self.directions.len()
    }
    pub fn capture_count(&self) -> usize {
        self.directions.len() * self.directions.len()
    }

    /// The plan entry taken at capture index `index` (acquisition order).
    pub fn entry(&self, index: usize) -> Result<PlanEntry, PlanError> {
        let n = self.directions.len();
        if index >= n * n {
            return Err(PlanError::IndexOutOfRange {
                index,
                captures: n * n,
            });
        }
        let (outer, inner) = (index / n, index % n);
        let (light, camera) = match self.order {
            AcquisitionOrder::LightOuter => (outer, inner),
            AcquisitionOrder::CameraOuter => (inner, outer),
            AcquisitionOrder::LightOuterSerpentine => (
                outer,
                if outer.is_multiple_of(2) {
                    inner
                } else {
                    n - 1 - inner
                },
            ),
        };
        Ok(PlanEntry {
            index,
            light,
            camera,
        })
    }

    /// The capture index of the (light, camera) combination.
    pub(crate) fn index_of(&self, light: usize, camera: usize) -> Option<usize> {
        let n = self.directions.len();
        if light >= n || camera >= n {
            return None;
        }
        Some(match self.order {
            AcquisitionOrder::LightOuter => light * n + camera,
            AcquisitionOrder::CameraOuter => camera * n + light,
            AcquisitionOrder::LightOuterSerpentine => {
                light * n
                    + if light.is_multiple_of(2) {
                        camera
                    } else {
                        n - 1 - camera
                    }
            }
        })
    }

    /// The reciprocal partner (light and camera swapped) of capture `index`; itself for a self pair.
    pub fn reciprocal_of(&self, index: usize) -> Result<usize, PlanError> {
        let e = self.entry(index)?;
        self.index_of(e.camera, e.light)
            .ok_or(PlanError::IndexOutOfRange {
                index,
                captures: self.capture_count(),
            })
    }

    /// All reciprocal pairs (a < b by capture index) with light ≠ camera.
    pub fn reciprocal_pairs(&self) -> Vec<(usize, usize)> {
        let n = self.directions.len();
        let mut out = Vec::with_capacity(n * (n - 1) / 2);
        for l in 0..n {
            for c in (l + 1)..n {
                if let (Some(a), Some(b)) = (self.index_of(l, c), self.index_of(c, l)) {
                    out.push((a.min(b), a.max(b)));
                }
            }
        }
        out.sort_unstable();
        out
    }

    /// Captures whose light and camera directions coincide (their own reciprocal partner).
    pub(crate) fn self_pairs(&self) -> Vec<usize> {
        (0..self.directions.len())
            .filter_map(|d| self.index_of(d, d))
            .collect()
    }

    /// The isotropy class of a capture: same θᵢ, θₒ (unordered) and wrapped |φᵢ − φₒ|.
    pub(crate) fn isotropy_key(&self, entry: &PlanEntry) -> IsotropyKey {
        let li = &self.directions[entry.light];
        let ca = &self.directions[entry.camera];
        let dphi = if li.theta_deg == 0.0 || ca.theta_deg == 0.0 {
            0.0
        } else {
            azimuth_difference_deg(li.phi_deg, ca.phi_deg)
        };
        let (a, b) = (mdeg(li.theta_deg), mdeg(ca.theta_deg));
        IsotropyKey {
            theta_lo_mdeg: a.min(b),
            theta_hi_mdeg: a.max(b),
            dphi_mdeg: mdeg(dphi),
        }
    }

    /// Every isotropy class with its members (capture indices, ascending).
    pub fn isotropy_classes(&self) -> BTreeMap<IsotropyKey, Vec<usize>> {
        let mut m: BTreeMap<IsotropyKey, Vec<usize>> = BTreeMap::new();
        for i in 0..self.capture_count() {
            if let Ok(e) = self.entry(i) {
                m.entry(self.isotropy_key(&e)).or_default().push(i);
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ubo_counts() {
        let p = SamplingPlan::ubo();
        assert_eq!(p.direction_count(), 81);
        assert_eq!(p.capture_count(), 6561);
        assert_eq!(p.reciprocal_pairs().len(), 3240);
        assert_eq!(p.self_pairs().len(), 81);
    }

    #[test]
    fn every_order_is_a_bijection_and_reciprocity_is_an_involution() {
        for order in [
            AcquisitionOrder::LightOuter,
            AcquisitionOrder::CameraOuter,
            AcquisitionOrder::LightOuterSerpentine,
        ] {
            let p = SamplingPlan::new(&PlanSpec {
                order,
                ..PlanSpec::default()
            })
            .unwrap();
            let mut seen = vec![false; p.capture_count()];
            for i in 0..p.capture_count() {
                let e = p.entry(i).unwrap();
                assert_eq!(p.index_of(e.light, e.camera), Some(i));
                assert!(!seen[i]);
                seen[i] = true;
                let r = p.reciprocal_of(i).unwrap();
                assert_eq!(p.reciprocal_of(r).unwrap(), i);
                assert_eq!(p.isotropy_key(&e), p.isotropy_key(&p.entry(r).unwrap()));
            }
        }
    }

    #[test]
    fn bad_specs_are_typed_errors() {
        let bad = |t: Vec<f64>, d: Vec<f64>| {
            SamplingPlan::new(&PlanSpec {
                thetas_deg: t,
                delta_phi_deg: d,
                order: AcquisitionOrder::LightOuter,
            })
        };
        assert_eq!(
            bad(vec![0.0, 15.0], vec![0.0]),
            Err(PlanError::LengthMismatch(2, 1))
        );
        assert!(matches!(
            bad(vec![0.0, 15.0], vec![0.0, 7.0]),
            Err(PlanError::BadDeltaPhi { index: 1, .. })
        ));
        assert!(matches!(
            bad(vec![0.0, 90.0], vec![0.0, 60.0]),
            Err(PlanError::BadTheta { index: 1, .. })
        ));
        assert!(matches!(
            bad(vec![30.0, 15.0], vec![30.0, 60.0]),
            Err(PlanError::BadTheta { index: 1, .. })
        ));
        assert_eq!(bad(vec![], vec![]), Err(PlanError::Empty));
        assert!(matches!(
            bad(vec![0.0, 15.0], vec![0.0, 1e-9]),
            Err(PlanError::TooLarge { index: 1, .. })
        ));
        assert!(matches!(
            bad(vec![0.0, 15.0, 30.0, 45.0], vec![0.0, 1.0, 1.0, 1.0]),
            Err(PlanError::TooLarge { index: 3, .. })
        ));
        assert!(SamplingPlan::ubo().entry(6561).is_err());
    }
}
