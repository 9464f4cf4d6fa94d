//! Rig kinematics of a UBO-type gonioreflectometer: a fixed lamp, a camera on a wagon that runs
//! on an arc rail through the lamp, and a three-joint arm that orients the sample.
//!
//! Convention (documented in `config/ubo.toml` and ARCHITECTURE.md):
//! - World frame: the sample centre is the origin, the arc lies in the world x–y plane.
//!   The lamp is fixed at L = (1, 0, 0). The camera sits at arc angle w from the lamp:
//!   C(w) = (cos w, sin w, 0). So the lamp–camera separation equals the wagon angle.
//! - The arm's orientation is R = Rz(q₁)·Ry(q₂)·Rz(q₃) (intrinsic z–y–z), mapping sample-frame
//!   vectors to world vectors. Sample frame: z is the sample normal.
//!   Then ωᵢ = Rᵀ·L and ωₒ = Rᵀ·C.
//! - Physical readings relate to the ideal angles through per-joint sign and offset:
//!   reading = sign · ideal + offset (degrees), for each arm joint and for the wagon.
//! - The wagon cannot bring the camera closer to the lamp than `min_separation_deg` (the camera
//!   would shadow the lamp). Plan entries closer than that are taken at a substitute pose with a
//!   slightly different θᵢ (same φᵢ, same ωₒ), as the paper describes for the UBO data.

use super::geometry::{angle_between, Spherical, Vec3};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum KinematicsError {
    #[error("direction below the sample horizon (θ = {theta_deg:.3}°)")]
    BelowHorizon { theta_deg: f64 },
    #[error("lamp–camera separation {separation_deg:.3}° is below the rig's minimum {min_deg:.3}° (camera would shadow the lamp)")]
    Occluded { separation_deg: f64, min_deg: f64 },
    #[error("no substitute θᵢ within [0, {max_theta_deg}]° keeps the lamp–camera separation ≥ {min_deg}°")]
    NoSubstitute { max_theta_deg: f64, min_deg: f64 },
    #[error("wagon angle {wagon_deg:.3}° is outside the rail [{min_deg}, {max_deg}]°")]
    WagonOutOfRange {
        wagon_deg: f64,
        min_deg: f64,
        max_deg: f64,
    },
    #[error("pose contains a non-finite value")]
    NotFinite,
    #[error("rig.{field}: {message}")]
    BadSpec {
        field: &'static str,
        message: String,
    },
}

/// Per-axis calibration: reading = sign · ideal + offset.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisCalibration {
    #[serde(default)]
    pub offset_deg: f64,
    #[serde(default = "plus_one")]
    pub sign: f64,
}

fn plus_one() -> f64 {
    1.0
}

impl Default for AxisCalibration {
    fn default() -> Self {
        AxisCalibration {
            offset_deg: 0.0,
            sign: 1.0,
        }
    }
}

impl AxisCalibration {
    fn to_ideal(self, reading: f64) -> f64 {
        (reading - self.offset_deg) * self.sign
    }
    fn to_reading(self, ideal: f64) -> f64 {
        ideal * self.sign + self.offset_deg
    }
}

/// The rig section of the config file (`[rig]`), shared by the daemon and the simulator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSpec {
    /// Smallest lamp–camera angle the wagon can reach (degrees).
    #[serde(default = "default_min_sep")]
    pub min_separation_deg: f64,
    /// Largest θ a substitute incidence may use (degrees).
    #[serde(default = "default_max_theta")]
    pub max_substitute_theta_deg: f64,
    /// The arc rail's range for the wagon's ideal angle (degrees).
    #[serde(default = "default_wagon_max")]
    pub wagon_max_deg: f64,
    /// Calibration of the arm's three joints q₁, q₂, q₃.
    #[serde(default)]
    pub joints: [AxisCalibration; 3],
    /// Calibration of the wagon.
    #[serde(default)]
    pub wagon: AxisCalibration,
}

fn default_min_sep() -> f64 {
    12.0
}
fn default_max_theta() -> f64 {
    85.0
}
fn default_wagon_max() -> f64 {
    180.0
}

impl Default for RigSpec {
    fn default() -> Self {
        RigSpec {
            min_separation_deg: default_min_sep(),
            max_substitute_theta_deg: default_max_theta(),
            wagon_max_deg: default_wagon_max(),
            joints: [AxisCalibration::default(); 3],
            wagon: AxisCalibration::default(),
        }
    }
}

impl RigSpec {
    pub(crate) fn validate(&self) -> Result<(), KinematicsError> {
        let bad =
            |field: &'static str, message: String| Err(KinematicsError::BadSpec { field, message });
        if !(self.min_separation_deg.is_finite() && (0.0..90.0).contains(&self.min_separation_deg))
        {
            return bad(
                "min_separation_deg",
                format!("{} is not in [0, 90)", self.min_separation_deg),
            );
        }
        if !(self.max_substitute_theta_deg > 0.0 && self.max_substitute_theta_deg < 90.0) {
            return bad(
                "max_substitute_theta_deg",
                format!("{} is not in (0, 90)", self.max_substitute_theta_deg),
            );
        }
        if !(self.wagon_max_deg > self.min_separation_deg && self.wagon_max_deg <= 180.0) {
            return bad(
                "wagon_max_deg",
                format!("{} is not in (min_separation_deg, 180]", self.wagon_max_deg),
            );
        }
        for (i, j) in self.joints.iter().enumerate() {
            if !(j.sign == 1.0 || j.sign == -1.0) || !j.offset_deg.is_finite() {
                let field = ["joints[0]", "joints[1]", "joints[2]"][i];
                return bad(
                    field,
                    format!("sign must be 1 or -1 and offset finite, got {:?}", j),
                );
            }
        }
        if !(self.wagon.sign == 1.0 || self.wagon.sign == -1.0)
            || !self.wagon.offset_deg.is_finite()
        {
            return bad(
                "wagon",
                format!(
                    "sign must be 1 or -1 and offset finite, got {:?}",
                    self.wagon
                ),
            );
        }
        Ok(())
    }
}

/// Physical readings: the arm's three joint angles and the wagon angle, in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub joints_deg: [f64; 3],
    pub wagon_deg: f64,
}

/// The two directions in the sample frame, with their angles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Incidence {
    pub omega_i: Vec3,
    pub omega_o: Vec3,
}

/// Measured angles in degrees (φ ∈ [0, 360), 0 at the pole).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Angles {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
}

impl Incidence {
    pub fn from_angles(a: &Angles) -> Self {
        Incidence {
            omega_i: Spherical::from_deg(a.theta_i_deg, a.phi_i_deg).to_vector(),
            omega_o: Spherical::from_deg(a.theta_o_deg, a.phi_o_deg).to_vector(),
        }
    }
    pub fn angles(&self) -> Angles {
        let i = Spherical::from_vector(&self.omega_i);
        let o = Spherical::from_vector(&self.omega_o);
        Angles {
            theta_i_deg: i.theta_deg(),
            phi_i_deg: i.phi_deg(),
            theta_o_deg: o.theta_deg(),
            phi_o_deg: o.phi_deg(),
        }
    }
    /// Lamp–camera separation seen from the sample (degrees).
    pub fn separation_deg(&self) -> f64 {
        angle_between(&self.omega_i, &self.omega_o).to_degrees()
    }
}

fn rz(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}
fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// Wrap degrees into (−180, 180].
fn wrap_pm180(a: f64) -> f64 {
    let r = (a + 180.0).rem_euclid(360.0) - 180.0;
    if r == -180.0 {
        180.0
    } else {
        r
    }
}

/// A pose chosen for a plan entry: the ideal pose, whether it had to be substituted, and the
/// incidence actually used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedPose {
    pub pose: Pose,
    pub used: Incidence,
    /// θᵢ the plan asked for and the one used, when the entry was substituted.
    pub substitute: Option<(f64, f64)>,
}

/// The rig model.
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    spec: RigSpec,
}

pub(crate) const LAMP: [f64; 3] = [1.0, 0.0, 0.0];

/// cos θ at or below which a direction counts as on or below the horizon.
pub(crate) const HORIZON_EPS: f64 = 1e-9;

impl Rig {
    pub fn new(spec: RigSpec) -> Result<Self, KinematicsError> {
        spec.validate()?;
        Ok(Rig { spec })
    }
    pub fn spec(&self) -> &RigSpec {
        &self.spec
    }

    fn lamp() -> Vec3 {
        Vec3::new(LAMP[0], LAMP[1], LAMP[2])
    }
    fn camera(w_rad: f64) -> Vec3 {
        let (s, c) = w_rad.sin_cos();
        Vec3::new(c, s, 0.0)
    }

    /// Forward kinematics: readings → directions in the sample frame.
    pub fn forward(&self, pose: &Pose) -> Result<Incidence, KinematicsError> {
        if !pose.joints_deg.iter().all(|v| v.is_finite()) || !pose.wagon_deg.is_finite() {
            return Err(KinematicsError::NotFinite);
        }
        let q: Vec<f64> = pose
            .joints_deg
            .iter()
            .zip(&self.spec.joints)
            .map(|(r, cal)| cal.to_ideal(*r).to_radians())
            .collect();
        let w = self.spec.wagon.to_ideal(pose.wagon_deg).to_radians();
        let r = rz(q[0]) * ry(q[1]) * rz(q[2]);
        let rt = r.transpose();
        Ok(Incidence {
            omega_i: rt * Self::lamp(),
            omega_o: rt * Self::camera(w),
        })
    }

    /// Inverse kinematics: directions → readings. Errors when a direction is at or below the
    /// horizon or the separation is below the rig's minimum.
    pub fn inverse(&self, inc: &Incidence) -> Result<Pose, KinematicsError> {
        let wi = inc
            .omega_i
            .try_normalize(0.0)
            .ok_or(KinematicsError::NotFinite)?;
        let wo = inc
            .omega_o
            .try_normalize(0.0)
            .ok_or(KinematicsError::NotFinite)?;
        if !wi.iter().chain(wo.iter()).all(|v| v.is_finite()) {
            return Err(KinematicsError::NotFinite);
        }
        for v in [&wi, &wo] {
            // at or below the horizon (θ ≥ 90° − 6e-8°): the lamp or camera grazes the sample
            if v.z <= HORIZON_EPS {
                return Err(KinematicsError::BelowHorizon {
                    theta_deg: Spherical::from_vector(v).theta_deg(),
                });
            }
        }
        let sep = angle_between(&wi, &wo);
        let sep_deg = sep.to_degrees();
        if sep_deg < self.spec.min_separation_deg - 1e-9 || sep_deg < 1e-9 {
            return Err(KinematicsError::Occluded {
                separation_deg: sep_deg,
                min_deg: self.spec.min_separation_deg,
            });
        }
        if sep_deg > self.spec.wagon_max_deg + 1e-9 {
            return Err(KinematicsError::WagonOutOfRange {
                wagon_deg: sep_deg,
                min_deg: self.spec.min_separation_deg,
                max_deg: self.spec.wagon_max_deg,
            });
        }
        // R maps the sample frame (wi, wo⊥, wi×wo⊥) onto the world frame (L, C⊥, L×C⊥).
        let wo_perp = (wo - wi * wi.dot(&wo)).normalize();
        let s = Matrix3::from_columns(&[wi, wo_perp, wi.cross(&wo_perp)]);
        let l = Self::lamp();
        let c = Self::camera(sep);
        let c_perp = (c - l * l.dot(&c)).normalize();
        let w = Matrix3::from_columns(&[l, c_perp, l.cross(&c_perp)]);
        let r = w * s.transpose();
        let (q1, q2, q3) = zyz_angles(&r);
        let ideal = [q1.to_degrees(), q2.to_degrees(), q3.to_degrees()];
        let mut joints_deg = [0.0; 3];
        for k in 0..3 {
            joints_deg[k] = wrap_pm180(self.spec.joints[k].to_reading(ideal[k]));
        }
        Ok(Pose {
            joints_deg,
            wagon_deg: self.spec.wagon.to_reading(sep_deg),
        })
    }

    /// The pose for a planned (ωᵢ, ωₒ), substituting θᵢ when the camera would shadow the lamp.
    pub fn plan_pose(
        &self,
        planned_i: Spherical,
        planned_o: Spherical,
    ) -> Result<PlannedPose, KinematicsError> {
        let inc = Incidence {
            omega_i: planned_i.to_vector(),
            omega_o: planned_o.to_vector(),
        };
        match self.inverse(&inc) {
            Ok(pose) => Ok(PlannedPose {
                pose,
                used: inc,
                substitute: None,
            }),
            Err(KinematicsError::Occluded { .. }) => {
                let theta_used = self.substitute_theta_i(planned_i, planned_o)?;
                let used = Incidence {
                    omega_i: Spherical {
                        theta: theta_used,
                        phi: planned_i.phi,
                    }
                    .to_vector(),
                    omega_o: inc.omega_o,
                };
                let pose = self.inverse(&used)?;
                Ok(PlannedPose {
                    pose,
                    used,
                    substitute: Some((planned_i.theta_deg(), theta_used.to_degrees())),
                })
            }
            Err(e) => Err(e),
        }
    }

    /// The θᵢ nearest to the planned one (same φᵢ) whose separation from ωₒ is exactly the
    /// rig's minimum. cos γ(θ) = cos θ cos θₒ + sin θ sin θₒ cos Δφ = R cos(θ − δ), so the two
    /// solutions are δ ± acos(cos γ_min / R).
    pub(crate) fn substitute_theta_i(
        &self,
        planned_i: Spherical,
        planned_o: Spherical,
    ) -> Result<f64, KinematicsError> {
        let gmin = self.spec.min_separation_deg.to_radians() + 1e-9;
        let a = planned_o.theta.cos();
        let b = planned_o.theta.sin() * (planned_i.phi - planned_o.phi).cos();
        let r = a.hypot(b);
        let delta = b.atan2(a);
        let max_t = self.spec.max_substitute_theta_deg.to_radians();
        let no = KinematicsError::NoSubstitute {
            max_theta_deg: self.spec.max_substitute_theta_deg,
            min_deg: self.spec.min_separation_deg,
        };
        let ratio = gmin.cos() / r;
        if ratio > 1.0 {
            // every θ along this meridian is farther than the minimum: no occlusion at all
            return Ok(planned_i.theta);
        }
        let off = ratio.clamp(-1.0, 1.0).acos();
        // candidate θ's; θ < 0 on the meridian φᵢ means θ' = −θ on the meridian φᵢ + π,
        // which changes φᵢ, so only θ ≥ 0 qualifies
        let mut best: Option<f64> = None;
        for cand in [delta - off, delta + off] {
            if cand >= 0.0 && cand <= max_t {
                let better = match best {
                    None => true,
                    Some(b) => {
                        let (dc, db) =
                            ((cand - planned_i.theta).abs(), (b - planned_i.theta).abs());
                        dc < db - 1e-12 || ((dc - db).abs() <= 1e-12 && cand < b)
                    }
                };
                if better {
                    best = Some(cand);
                }
            }
        }
        best.ok_or(no)
    }
}

/// Decompose R = Rz(a)·Ry(b)·Rz(c), b ∈ [0, π]. In gimbal lock (b = 0 or π, the sample normal
/// on the world z axis, i.e. θᵢ = 90°) c is set to 0.
fn zyz_angles(r: &Matrix3<f64>) -> (f64, f64, f64) {
    let sb = r[(0, 2)].hypot(r[(1, 2)]);
    let b = sb.atan2(r[(2, 2)]);
    if sb > 1e-12 {
        let a = r[(1, 2)].atan2(r[(0, 2)]);
        let c = r[(2, 1)].atan2(-r[(2, 0)]);
        (a, b, c)
    } else if r[(2, 2)] > 0.0 {
        (r[(1, 0)].atan2(r[(0, 0)]), b, 0.0)
    } else {
        ((-r[(1, 0)]).atan2(-r[(0, 0)]), b, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zyz_round_trip() {
        for (a, b, c) in [
            (0.3, 0.7, -1.2),
            (-2.0, 2.5, 3.0),
            (1.0, 0.0, 0.0),
            (0.5, std::f64::consts::PI, 0.0),
        ] {
            let r = rz(a) * ry(b) * rz(c);
            let (a2, b2, c2) = zyz_angles(&r);
            let r2 = rz(a2) * ry(b2) * rz(c2);
            assert!((r - r2).norm() < 1e-12);
        }
    }

    #[test]
    fn calibration_is_applied_both_ways() {
        let mut spec = RigSpec::default();
        spec.joints[1] = AxisCalibration {
            offset_deg: 2.5,
            sign: -1.0,
        };
        spec.wagon = AxisCalibration {
            offset_deg: -10.0,
            sign: -1.0,
        };
        let rig = Rig::new(spec).unwrap();
        let inc = Incidence::from_angles(&Angles {
            theta_i_deg: 30.0,
            phi_i_deg: 40.0,
            theta_o_deg: 60.0,
            phi_o_deg: 200.0,
        });
        let pose = rig.inverse(&inc).unwrap();
        let back = rig.forward(&pose).unwrap();
        assert!((back.omega_i - inc.omega_i).norm() < 1e-12);
        assert!((back.omega_o - inc.omega_o).norm() < 1e-12);
    }

    #[test]
    fn bad_spec_names_the_field() {
        let mut spec = RigSpec::default();
        spec.joints[2].sign = 0.5;
        let e = Rig::new(spec).unwrap_err();
        assert!(e.to_string().contains("rig.joints[2]"), "{e}");
    }
}
