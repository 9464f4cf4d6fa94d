//! The MERL isotropic BRDF layout (Matusik et al. 2003, the MERL BRDF database) filled from a
//! session.
//!
//! The file: three little-endian int32 dimensions (90, 90, 180), then 3 × 1,458,000
//! little-endian float64 values, the red channel's block, then green, then blue. A block runs
//! over (θh, θd, φd) with φd fastest: cell = φd_i + 180·θd_i + 180·90·θh_i, where
//! θh_i = ⌊√(θh / (π/2))·90⌋, θd_i = ⌊θd / (π/2)·90⌋, φd_i = ⌊φd / π·180⌋ with φd taken into
//! [0, π) (φd and φd + π are the reciprocal pair). A stored value is the BRDF (sr⁻¹) divided by
//! the channel's scale (1/1500, 1.15/1500, 1.66/1500); a cell with no value holds −1.
//!
//! Each cell is evaluated at its centre ((i + ½)² / 90 degrees of θh, i + ½ degrees of θd and
//! φd) with the half vector in the plane φh = 0 (an isotropic BRDF does not depend on φh), by
//! the layered resampler (`measure::resample::LayeredResampler`): the paper's mirror-aligned
//! square in each measured θi layer and a Lagrange polynomial across layers. A cell is left
//! empty when a direction is below the horizon, when θi or θo lies beyond the measured range,
//! or when the interpolant has no data near it; every cell's state and σ (the nodal functions'
//! spread) are kept.

use crate::measure::geometry::Vec3;
use crate::measure::resample::{LayeredResampler, ResampleError};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};

pub const THETA_H_CELLS: usize = 90;
pub const THETA_D_CELLS: usize = 90;
pub const PHI_D_CELLS: usize = 180;
pub const CELLS: usize = THETA_H_CELLS * THETA_D_CELLS * PHI_D_CELLS;
/// A stored value times its channel's scale is the BRDF in sr⁻¹ (R, G, B).
pub const CHANNEL_SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
/// What a cell without a value holds.
pub const NO_VALUE: f64 = -1.0;

/// The flat index of a cell.
pub fn cell(theta_h: usize, theta_d: usize, phi_d: usize) -> usize {
    phi_d + PHI_D_CELLS * (theta_d + THETA_D_CELLS * theta_h)
}

/// The centre of a cell: (θh, θd, φd) in radians.
pub fn cell_centre(theta_h: usize, theta_d: usize, phi_d: usize) -> (f64, f64, f64) {
    let h = (theta_h as f64 + 0.5) / THETA_H_CELLS as f64;
    (
        h * h * std::f64::consts::FRAC_PI_2,
        (theta_d as f64 + 0.5) / THETA_D_CELLS as f64 * std::f64::consts::FRAC_PI_2,
        (phi_d as f64 + 0.5) / PHI_D_CELLS as f64 * std::f64::consts::PI,
    )
}

/// Rotate `v` about the y axis by `a` (right-handed).
fn rotate_y(v: Vec3, a: f64) -> Vec3 {
    let (s, c) = a.sin_cos();
    Vec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z)
}

/// Rotate `v` about the z axis by `a`.
fn rotate_z(v: Vec3, a: f64) -> Vec3 {
    let (s, c) = a.sin_cos();
    Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

/// The incoming and outgoing unit vectors of half-difference angles (φh = 0).
pub fn directions(theta_h: f64, theta_d: f64, phi_d: f64) -> (Vec3, Vec3) {
    let (sd, cd) = theta_d.sin_cos();
    let (sp, cp) = phi_d.sin_cos();
    let d = Vec3::new(sd * cp, sd * sp, cd);
    let mirrored = Vec3::new(-d.x, -d.y, d.z);
    (rotate_y(d, theta_h), rotate_y(mirrored, theta_h))
}

/// The half-difference angles (θh, θd, φd) of a direction pair, φd in (−π, π].
pub fn half_diff(omega_i: &Vec3, omega_o: &Vec3) -> Option<(f64, f64, f64)> {
    let (wi, wo) = (omega_i.normalize(), omega_o.normalize());
    let h = wi + wo;
    let n = h.norm();
    if !(n > 1e-12) || !n.is_finite() {
        return None;
    }
    let h = h / n;
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let phi_h = h.y.atan2(h.x);
    let d = rotate_y(rotate_z(wi, -phi_h), -theta_h);
    Some((theta_h, d.z.clamp(-1.0, 1.0).acos(), d.y.atan2(d.x)))
}

/// The cell a direction pair falls in, by the format's lookup.
pub fn cell_of(omega_i: &Vec3, omega_o: &Vec3) -> Option<usize> {
    let (th, td, mut pd) = half_diff(omega_i, omega_o)?;
    let ih = if th <= 0.0 {
        0
    } else {
        ((th / std::f64::consts::FRAC_PI_2).sqrt() * THETA_H_CELLS as f64) as usize
    };
    let id = (td / std::f64::consts::FRAC_PI_2 * THETA_D_CELLS as f64) as usize;
    if pd < 0.0 {
        pd += std::f64::consts::PI;
    }
    let ip = (pd / std::f64::consts::PI * PHI_D_CELLS as f64) as usize;
    Some(cell(
        ih.min(THETA_H_CELLS - 1),
        id.min(THETA_D_CELLS - 1),
        ip.min(PHI_D_CELLS - 1),
    ))
}

/// What became of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CellState {
    /// Interpolated from the session's captures.
    Filled,
    /// The light or the camera would be below the sample's horizon.
    BelowHorizon,
    /// θi or θo lies beyond the largest θ the session measured.
    BeyondThetaRange,
    /// Within the θ range but too far from the captures for the interpolant.
    OutsideInterpolant,
    /// The interpolant gave a value that is not finite.
    NotFinite,
}

/// How many cells ended in each state.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CellCounts {
    pub filled: u64,
    pub below_horizon: u64,
    pub beyond_theta_range: u64,
    pub outside_interpolant: u64,
    pub not_finite: u64,
}

/// The filled grid: per cell the BRDF (R, G, B in sr⁻¹), its σ and its state.
#[derive(Debug, Clone, PartialEq)]
pub struct MerlGrid {
    pub value: Vec<[f64; 3]>,
    pub sigma: Vec<[f64; 3]>,
    pub state: Vec<CellState>,
    /// The θ limit the cells were held to (degrees).
    pub theta_max_deg: f64,
}

/// One θh row of cells.
type Row = Vec<([f64; 3], [f64; 3], CellState)>;

fn fill_row(resampler: &LayeredResampler, ih: usize, cos_max: f64) -> Row {
    let mut out = Vec::with_capacity(THETA_D_CELLS * PHI_D_CELLS);
    for id in 0..THETA_D_CELLS {
        for ip in 0..PHI_D_CELLS {
            let (th, td, pd) = cell_centre(ih, id, ip);
            let (wi, wo) = directions(th, td, pd);
            let state_value = if wi.z <= 1e-9 || wo.z <= 1e-9 {
                Err(CellState::BelowHorizon)
            } else if wi.z < cos_max || wo.z < cos_max {
                Err(CellState::BeyondThetaRange)
            } else {
                match resampler.at(&wi, &wo) {
                    Ok(r) if r.value.iter().chain(&r.spread).all(|v| v.is_finite()) => Ok(r),
                    Ok(_) => Err(CellState::NotFinite),
                    Err(ResampleError::BadDirection) => Err(CellState::BelowHorizon),
                    Err(_) => Err(CellState::OutsideInterpolant),
                }
            };
            out.push(match state_value {
                Ok(r) => (r.value, r.spread, CellState::Filled),
                Err(s) => ([NO_VALUE; 3], [NO_VALUE; 3], s),
            });
        }
    }
    out
}

/// Fill every cell from `resampler` (values without cos θi: a BRDF), holding θi and θo to
/// `theta_max_deg`, on `threads` threads (the result does not depend on how many).
pub fn fill(resampler: &LayeredResampler, theta_max_deg: f64, threads: usize) -> MerlGrid {
    let cos_max = theta_max_deg.to_radians().cos();
    let next = AtomicUsize::new(0);
    let mut rows: Vec<(usize, Row)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads.clamp(1, 64))
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let ih = next.fetch_add(1, Ordering::Relaxed);
                        if ih >= THETA_H_CELLS {
                            break;
                        }
                        mine.push((ih, fill_row(resampler, ih, cos_max)));
                    }
                    mine
                })
            })
            .collect();
        // a worker that panicked loses its rows; they are filled again below
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    rows.sort_by_key(|r| r.0);
    let mut grid = MerlGrid {
        value: Vec::with_capacity(CELLS),
        sigma: Vec::with_capacity(CELLS),
        state: Vec::with_capacity(CELLS),
        theta_max_deg,
    };
    let mut have = rows.into_iter().peekable();
    for ih in 0..THETA_H_CELLS {
        let row = match have.peek() {
            Some((k, _)) if *k == ih => have.next().map(|r| r.1).unwrap_or_default(),
            _ => fill_row(resampler, ih, cos_max),
        };
        for (v, s, st) in row {
            grid.value.push(v);
            grid.sigma.push(s);
            grid.state.push(st);
        }
    }
    grid
}

impl MerlGrid {
    pub fn counts(&self) -> CellCounts {
        let mut c = CellCounts::default();
        for s in &self.state {
            match s {
                CellState::Filled => c.filled += 1,
                CellState::BelowHorizon => c.below_horizon += 1,
                CellState::BeyondThetaRange => c.beyond_theta_range += 1,
                CellState::OutsideInterpolant => c.outside_interpolant += 1,
                CellState::NotFinite => c.not_finite += 1,
            }
        }
        c
    }

    /// Per (θh, θd) cell row, the fraction of its 180 φd cells that are filled ([θh][θd]).
    pub fn coverage(&self) -> Vec<Vec<f64>> {
        (0..THETA_H_CELLS)
            .map(|ih| {
                (0..THETA_D_CELLS)
                    .map(|id| {
                        let start = cell(ih, id, 0);
                        let n = self.state[start..start + PHI_D_CELLS]
                            .iter()
                            .filter(|s| **s == CellState::Filled)
                            .count();
                        n as f64 / PHI_D_CELLS as f64
                    })
                    .collect()
            })
            .collect()
    }

    /// Quantiles (50 %, 95 %, max) of the filled cells' relative σ (σ / value, the worst
    /// channel).
    pub fn relative_sigma_quantiles(&self) -> Option<[f64; 3]> {
        let mut rel: Vec<f64> = self
            .value
            .iter()
            .zip(&self.sigma)
            .zip(&self.state)
            .filter(|(_, s)| **s == CellState::Filled)
            .map(|((v, s), _)| {
                (0..3)
                    .map(|c| {
                        if v[c] > 0.0 {
                            s[c] / v[c]
                        } else {
                            f64::INFINITY
                        }
                    })
                    .fold(0.0, f64::max)
            })
            .collect();
        if rel.is_empty() {
            return None;
        }
        rel.sort_by(|a, b| a.total_cmp(b));
        let q = |p: f64| rel[((rel.len() - 1) as f64 * p).round() as usize];
        Some([q(0.5), q(0.95), q(1.0)])
    }

    /// Write the values (or, with `sigma`, the σ) in the MERL layout.
    pub fn write(&self, w: &mut impl Write, sigma: bool) -> std::io::Result<()> {
        for d in [THETA_H_CELLS, THETA_D_CELLS, PHI_D_CELLS] {
            w.write_all(&(d as i32).to_le_bytes())?;
        }
        let src = if sigma { &self.sigma } else { &self.value };
        let mut buf = Vec::with_capacity(8 * PHI_D_CELLS * THETA_D_CELLS);
        for c in 0..3 {
            for (k, (v, s)) in src.iter().zip(&self.state).enumerate() {
                let stored = if *s == CellState::Filled {
                    v[c] / CHANNEL_SCALE[c]
                } else {
                    NO_VALUE
                };
                buf.extend_from_slice(&stored.to_le_bytes());
                if (k + 1) % (PHI_D_CELLS * THETA_D_CELLS) == 0 {
                    w.write_all(&buf)?;
                    buf.clear();
                }
            }
            w.write_all(&buf)?;
            buf.clear();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::geometry::Spherical;
    use crate::measure::resample::{ResampleSpec, Sample};

    #[test]
    fn a_cells_centre_maps_back_to_the_cell() {
        for ih in (0..90).step_by(7) {
            for id in (0..90).step_by(5) {
                for ip in (0..180).step_by(11) {
                    let (th, td, pd) = cell_centre(ih, id, ip);
                    let (wi, wo) = directions(th, td, pd);
                    assert!((wi.norm() - 1.0).abs() < 1e-12 && (wo.norm() - 1.0).abs() < 1e-12);
                    let (h, d, p) = half_diff(&wi, &wo).unwrap();
                    assert!(
                        (h - th).abs() < 1e-9 && (d - td).abs() < 1e-9,
                        "{ih} {id} {ip}"
                    );
                    assert!((p.rem_euclid(std::f64::consts::PI) - pd).abs() < 1e-9);
                    assert_eq!(cell_of(&wi, &wo), Some(cell(ih, id, ip)));
                }
            }
        }
    }

    #[test]
    fn the_mirror_configuration_has_theta_d_zero_and_retro_reflection_theta_h_zero() {
        let wi = Spherical::from_deg(40.0, 0.0).to_vector();
        let mirror = Spherical::from_deg(40.0, 180.0).to_vector();
        let (th, td, _) = half_diff(&wi, &mirror).unwrap();
        assert!(th.abs() < 1e-12 && (td - 40f64.to_radians()).abs() < 1e-12);
        let (th, td, _) = half_diff(&wi, &wi).unwrap();
        assert!((th - 40f64.to_radians()).abs() < 1e-12 && td.abs() < 1e-7);
        // swapping the directions (reciprocity) is the same cell
        let wo = Spherical::from_deg(25.0, 130.0).to_vector();
        assert_eq!(cell_of(&wi, &wo), cell_of(&wo, &wi));
        // opposite directions have no half vector
        assert_eq!(
            half_diff(&Vec3::new(1.0, 0.0, 0.0), &Vec3::new(-1.0, 0.0, 0.0)),
            None
        );
    }

    fn lambert_samples(value: [f64; 3]) -> Vec<Sample> {
        let mut s = Vec::new();
        for (ti, n_phi) in [
            (0.0, 1),
            (15.0, 6),
            (30.0, 12),
            (45.0, 18),
            (60.0, 20),
            (75.0, 24),
        ] {
            for k in 0..n_phi {
                let wi = Spherical::from_deg(ti, 360.0 * k as f64 / n_phi as f64).to_vector();
                for (to, m_phi) in [
                    (0.0, 1),
                    (15.0, 6),
                    (30.0, 12),
                    (45.0, 18),
                    (60.0, 20),
                    (75.0, 24),
                ] {
                    for j in 0..m_phi {
                        let wo =
                            Spherical::from_deg(to, 360.0 * j as f64 / m_phi as f64).to_vector();
                        s.push(Sample {
                            omega_i: wi,
                            omega_o: wo,
                            value,
                        });
                    }
                }
            }
        }
        s
    }

    #[test]
    fn a_constant_brdf_fills_every_covered_cell_with_itself_and_the_file_reads_back() {
        let rho = [0.5, 0.4, 0.3].map(|a: f64| a / std::f64::consts::PI);
        let r = LayeredResampler::new(&lambert_samples(rho), &ResampleSpec::default()).unwrap();
        let grid = fill(&r, 75.25, 2);
        let c = grid.counts();
        assert_eq!(
            c.filled
                + c.below_horizon
                + c.beyond_theta_range
                + c.outside_interpolant
                + c.not_finite,
            CELLS as u64
        );
        assert!(
            c.filled > 200_000 && c.below_horizon > 0 && c.beyond_theta_range > 0,
            "{c:?}"
        );
        for (v, s) in grid.value.iter().zip(&grid.state) {
            if *s == CellState::Filled {
                for k in 0..3 {
                    assert!((v[k] / rho[k] - 1.0).abs() < 1e-9, "{v:?}");
                }
            }
        }
        // a filled cell's directions are within the range, an empty one's outside or far
        for (k, s) in grid.state.iter().enumerate() {
            let ip = k % PHI_D_CELLS;
            let id = (k / PHI_D_CELLS) % THETA_D_CELLS;
            let ih = k / (PHI_D_CELLS * THETA_D_CELLS);
            let (th, td, pd) = cell_centre(ih, id, ip);
            let (wi, wo) = directions(th, td, pd);
            let inside = wi.z >= 75.25f64.to_radians().cos() && wo.z >= 75.25f64.to_radians().cos();
            if *s == CellState::Filled {
                assert!(inside);
            }
            if *s == CellState::BelowHorizon {
                assert!(wi.z <= 1e-9 || wo.z <= 1e-9);
            }
        }
        let mut bytes = Vec::new();
        grid.write(&mut bytes, false).unwrap();
        assert_eq!(bytes.len(), 12 + 8 * 3 * CELLS);
        assert_eq!(&bytes[0..4], &90i32.to_le_bytes());
        assert_eq!(&bytes[8..12], &180i32.to_le_bytes());
        // the same result on one thread
        assert_eq!(fill(&r, 75.25, 1), grid);
    }
}
