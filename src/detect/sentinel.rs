//! Arm joint 3 on an anisotropic sample, from a sentinel probe.
//!
//! Joint 3 turns the sample about its normal. An isotropic BRDF does not change under that
//! turn; an anisotropic one turns its lobes with the sample, so a pose whose luminance changes
//! steeply with the azimuth shows the turn plainly. Reciprocal pairs are too noisy for it: a
//! pair's difference carries a per-direction non-reciprocity of several per cent, as large as
//! the effect of a degree. A probe is not: it re-captures one pose exactly.
//!
//! The sentinel is a second probe, taken right after the lamp probe. Its pose is chosen to be
//! sensitive to joint 3, where the lamp probe's is chosen to be insensitive to every joint. The
//! lamp's gain cancels in the difference of the two: d = ln(Y_s / Y_s0) − ln(Y_l / Y_l0), the
//! sentinel's and the lamp probe's luminance against their original captures. Without a pose
//! change d stays at its level; a turn of δ moves it by s·δ, with s the sentinel's sensitivity
//! (ln Y per degree of joint 3). A new d that departs from the segment's mean by more than
//! `step_sigmas` standard deviations and by at least `min_deg` of joint 3 is a slip.
//!
//! The pose is taken from the pole light's sweep: with the light at the pole, a turn about the
//! normal moves only the camera's azimuth, so ∂ ln Y / ∂φo between the ring neighbours of a
//! camera, times ∂φo/∂q₃ from the kinematics, is the whole sensitivity. A tilt (joints 1 and 2)
//! or the sample moving in its holder moves the sentinel too: the alarm says so.

use serde::{Deserialize, Serialize};

/// A capture of the pole light's sweep offered to the sentinel choice, at its camera's plan
/// direction (measured angles jitter with the encoders; the plan's rings do not).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RingSample {
    pub entry: usize,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
    /// The plan's azimuth step on this ring (360° over its directions): a neighbour further
    /// than 1.5 steps away means one is missing, and the slope would span a lobe.
    pub ring_step_deg: f64,
    /// Its luminance at the original capture.
    pub y: f64,
    /// ∂φo/∂q₃ at its pose (degrees of camera azimuth per degree of joint 3; ±1 on a rig whose
    /// joint 3 is the sample normal).
    pub dphi_dq3: f64,
}

/// The chosen sentinel pose, with the figures it was chosen by.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SentinelPose {
    pub entry: usize,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
    pub luminance: f64,
    /// The change of its luminance per degree of joint 3 (%/°, signed).
    pub sensitivity_pct_per_deg: f64,
}

/// The sentinel as the summary reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SentinelSummary {
    pub pose: SentinelPose,
    /// Sentinel probes read so far.
    pub readings: usize,
    /// The latest reading as a turn of joint 3 against the run's start (degrees).
    pub offset_deg: f64,
}

/// The sentinel sits off grazing: θo at most this ...
pub(crate) const SENTINEL_MAX_THETA_O_DEG: f64 = 60.0;
/// ... and off the pole, where the azimuth is undefined.
pub(crate) const SENTINEL_MIN_THETA_O_DEG: f64 = 5.0;
/// The smallest sensitivity (%/°) a sentinel may have whatever its test's threshold.
pub(crate) const SENTINEL_MIN_PCT_PER_DEG: f64 = 0.5;

/// Chooses the sentinel among the pole light's captures: off grazing and off the pole, both
/// ring neighbours measured (one plan step away), on a flank (one neighbour brighter and the
/// other darker, so the central difference is not a peak's or a valley's noise), the steepest
/// one by the central difference. Ties go to the lower entry; None when none reaches
/// `min_pct_per_deg` (at least `SENTINEL_MIN_PCT_PER_DEG`).
pub(crate) fn choose_sentinel(
    samples: &[RingSample],
    min_pct_per_deg: f64,
) -> Option<SentinelPose> {
    let min_pct_per_deg = min_pct_per_deg.max(SENTINEL_MIN_PCT_PER_DEG);
    let usable: Vec<&RingSample> = samples
        .iter()
        .filter(|s| s.y > 0.0 && s.y.is_finite() && s.dphi_dq3.is_finite())
        .collect();
    let mut best: Option<SentinelPose> = None;
    for s in usable
        .iter()
        .filter(|s| (SENTINEL_MIN_THETA_O_DEG..=SENTINEL_MAX_THETA_O_DEG).contains(&s.theta_o_deg))
    {
        // its ring: the same plan θo, in azimuth order
        let mut ring: Vec<&RingSample> = usable
            .iter()
            .copied()
            .filter(|n| (n.theta_o_deg - s.theta_o_deg).abs() < 1e-6)
            .collect();
        if ring.len() < 3 {
            continue;
        }
        ring.sort_by(|a, b| a.phi_o_deg.total_cmp(&b.phi_o_deg));
        let Some(k) = ring.iter().position(|n| n.entry == s.entry) else {
            continue;
        };
        let prev = ring[(k + ring.len() - 1) % ring.len()];
        let next = ring[(k + 1) % ring.len()];
        let gap = |a: f64, b: f64| (b - a).rem_euclid(360.0);
        let (g_prev, g_next) = (
            gap(prev.phi_o_deg, s.phi_o_deg),
            gap(s.phi_o_deg, next.phi_o_deg),
        );
        let most = 1.5 * s.ring_step_deg;
        if !(g_prev > 1e-6 && g_next > 1e-6 && g_prev <= most && g_next <= most) {
            continue;
        }
        let left = (s.y / prev.y).ln() / g_prev;
        let right = (next.y / s.y).ln() / g_next;
        if left * right <= 0.0 {
            continue;
        }
        // ln Y per degree of azimuth, then per degree of joint 3, in %
        let central = (next.y / prev.y).ln() / (g_prev + g_next);
        let sensitivity = 100.0 * central * s.dphi_dq3;
        if !sensitivity.is_finite() || sensitivity.abs() < min_pct_per_deg {
            continue;
        }
        if best.is_none_or(|b| sensitivity.abs() > b.sensitivity_pct_per_deg.abs()) {
            best = Some(SentinelPose {
                entry: s.entry,
                theta_o_deg: s.theta_o_deg,
                phi_o_deg: s.phi_o_deg,
                luminance: s.y,
                sensitivity_pct_per_deg: sensitivity,
            });
        }
    }
    best
}

/// A slip the sentinel found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Joint3Slip {
    /// Estimated turn of joint 3 (degrees): the two departing readings against the segment.
    pub offset_deg: f64,
    /// The first departure in standard deviations of the segment, and the threshold.
    pub statistic: f64,
    pub threshold: f64,
    /// The first capture it can have affected: the one after the last sentinel probe before
    /// the first departing reading.
    pub since_idx: u64,
}

/// A departing reading waiting for the next one to confirm it.
#[derive(Debug, Clone, Copy)]
struct Pending {
    d: f64,
    statistic: f64,
    since_idx: u64,
}

/// The sentinel's readings and its slip test.
///
/// A reading d departs when |d − mean| exceeds `step_sigmas` standard deviations of the
/// current segment (at least `sd_floor`, the scatter the difference of two probes has at the
/// design scatter) and `min_deg` of joint 3. A slip is named only when the next reading departs
/// the same way: every capture after a slip goes on the retake list, so one glitched probe (a
/// speck, a flicker) must not put it there. An unconfirmed departure is left out of the segment.
#[derive(Debug, Clone)]
pub(crate) struct Joint3Sentinel {
    pose: SentinelPose,
    step_sigmas: f64,
    min_deg: f64,
    min_readings: usize,
    sd_floor: f64,
    /// d of the current segment.
    segment: Vec<f64>,
    pending: Option<Pending>,
    /// The first segment's mean once it has `min_readings`: the level of no turn.
    baseline: Option<f64>,
    last_idx: Option<u64>,
    /// The latest reading against the baseline (degrees), for the surfaces.
    offset_deg: f64,
    readings: usize,
}

impl Joint3Sentinel {
    /// `sd_floor` in ln units.
    pub(crate) fn new(
        pose: SentinelPose,
        step_sigmas: f64,
        min_deg: f64,
        min_readings: usize,
        sd_floor: f64,
    ) -> Self {
        Joint3Sentinel {
            pose,
            step_sigmas,
            min_deg,
            min_readings: min_readings.max(3),
            sd_floor: sd_floor.max(1e-4),
            segment: Vec::new(),
            pending: None,
            baseline: None,
            last_idx: None,
            offset_deg: 0.0,
            readings: 0,
        }
    }

    pub(crate) fn pose(&self) -> SentinelPose {
        self.pose
    }

    /// Sentinel readings taken so far.
    pub(crate) fn readings(&self) -> usize {
        self.readings
    }

    /// The latest reading as a turn of joint 3 against the first readings (degrees; 0 until
    /// they are in).
    pub(crate) fn offset_deg(&self) -> f64 {
        self.offset_deg
    }

    /// One sentinel probe at capture `idx`: `d` is its ln luminance ratio to its original
    /// minus the lamp probe's of the same round.
    pub(crate) fn add(&mut self, idx: u64, d: f64) -> Option<Joint3Slip> {
        if !d.is_finite() {
            return None;
        }
        let s = self.pose.sensitivity_pct_per_deg / 100.0;
        self.readings += 1;
        let since_idx = self.last_idx.map_or(idx, |i| i + 1);
        self.last_idx = Some(idx);
        let departure = self.departure(d, s);
        let mut slip = None;
        match (self.pending.take(), departure) {
            (Some(p), Some((_, e))) if e.signum() == (p.d - self.mean()).signum() => {
                let mean = self.mean();
                slip = Some(Joint3Slip {
                    offset_deg: ((p.d + d) / 2.0 - mean) / s,
                    statistic: p.statistic,
                    threshold: self.step_sigmas,
                    since_idx: p.since_idx,
                });
                self.segment = vec![p.d, d];
            }
            (_, Some((statistic, _))) => {
                // a first departure (or one against the pending one's sign): wait for the next
                self.pending = Some(Pending {
                    d,
                    statistic,
                    since_idx,
                });
            }
            (_, None) => self.segment.push(d),
        }
        if self.baseline.is_none() && self.segment.len() >= self.min_readings && slip.is_none() {
            self.baseline = Some(self.mean());
        }
        if let Some(b) = self.baseline {
            self.offset_deg = (d - b) / s;
        }
        slip
    }

    fn mean(&self) -> f64 {
        self.segment.iter().sum::<f64>() / self.segment.len().max(1) as f64
    }

    /// (statistic, d − mean) when `d` departs from the segment, which has enough readings.
    fn departure(&self, d: f64, s: f64) -> Option<(f64, f64)> {
        let n = self.segment.len();
        if n < self.min_readings {
            return None;
        }
        let mean = self.mean();
        let var = self.segment.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd = var.sqrt().max(self.sd_floor);
        let e = d - mean;
        (e.abs() > self.step_sigmas * sd && (e / s).abs() >= self.min_deg)
            .then_some((e.abs() / sd, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pole light's sweep of a lobe that turns with the sample: ln Y = a·cos 2(φo − φ₀) on
    /// rings of 12 cameras at 30° and 18 at 45°, plus a flat ring at 15°.
    fn rings(amplitude: f64) -> Vec<RingSample> {
        let mut v = Vec::new();
        let mut entry = 1;
        for (theta, n, a) in [(15.0, 6, 0.0), (30.0, 12, amplitude), (45.0, 18, amplitude)] {
            for k in 0..n {
                let phi = 360.0 * k as f64 / n as f64;
                v.push(RingSample {
                    entry,
                    theta_o_deg: theta,
                    phi_o_deg: phi,
                    ring_step_deg: 360.0 / n as f64,
                    y: 10.0 * (a * (2.0 * (phi - 20.0_f64).to_radians()).cos()).exp(),
                    dphi_dq3: -1.0,
                });
                entry += 1;
            }
        }
        v
    }

    #[test]
    fn the_steepest_flank_is_chosen_and_a_flat_sample_has_none() {
        let s = choose_sentinel(&rings(0.3), 0.5).unwrap();
        // the steepest slope of a·cos 2(φ − 20°) is at φ = 65° or 155° … (here on the 45° ring,
        // whose cameras sit closer to it)
        assert_eq!(s.theta_o_deg, 45.0);
        let phi = s.phi_o_deg;
        let slope =
            -2.0 * 0.3 * (2.0 * (phi - 20.0_f64).to_radians()).sin() * std::f64::consts::PI / 180.0;
        assert!(
            (s.sensitivity_pct_per_deg + 100.0 * slope).abs()
                < 0.1 * s.sensitivity_pct_per_deg.abs(),
            "{s:?} {slope}"
        );
        assert!(s.sensitivity_pct_per_deg.abs() > 0.9, "{s:?}");
        assert!(choose_sentinel(&rings(0.0), 0.5).is_none());
        // a sentinel must see a degree above its own threshold: asked for more than the
        // steepest pose gives, there is none
        assert!(choose_sentinel(&rings(0.3), 1.2 * s.sensitivity_pct_per_deg.abs()).is_none());
        assert!(choose_sentinel(&rings(0.01), 0.5).is_none());
        // dark or broken captures are not offered
        let mut v = rings(0.3);
        for r in v.iter_mut() {
            r.y = f64::NAN;
        }
        assert!(choose_sentinel(&v, 0.5).is_none());
        assert!(choose_sentinel(&[], 0.5).is_none());
        // a missing neighbour makes the slope span two steps: that camera is not chosen
        let all = rings(0.3);
        let best = choose_sentinel(&all, 0.5).unwrap();
        let gap: Vec<RingSample> = all
            .iter()
            .copied()
            .filter(|r| {
                !(r.theta_o_deg == best.theta_o_deg
                    && ((r.phi_o_deg - best.phi_o_deg).rem_euclid(360.0) - 20.0).abs() < 1e-9)
            })
            .collect();
        assert_ne!(
            choose_sentinel(&gap, 0.5).map(|s| s.entry),
            Some(best.entry)
        );
    }

    #[test]
    fn a_turn_is_named_when_the_next_reading_confirms_it_and_noise_or_a_glitch_is_not() {
        let pose = SentinelPose {
            entry: 20,
            theta_o_deg: 45.0,
            phi_o_deg: 60.0,
            luminance: 10.0,
            sensitivity_pct_per_deg: -3.0,
        };
        let mut rng = crate::measure::stats::SplitMix64(7);
        let mut noise = move || 0.003 * rng.gauss();
        // the floor: two probes' scatter at a 0.3 % design
        let floor = 0.003 * std::f64::consts::SQRT_2;
        // 30 readings of 0.3 % scatter about an unknown level, no slip: nothing
        for _ in 0..20 {
            let mut m = Joint3Sentinel::new(pose, 5.0, 0.5, 4, floor);
            for k in 0..30 {
                assert_eq!(m.add(100 * k, 0.004 + noise()), None, "reading {k}");
            }
            assert!(m.offset_deg().abs() < 0.5, "{}", m.offset_deg());
        }
        // +1° from reading 12 on: departs there, named at the next reading, with the right sign
        // and size, affecting the captures after reading 11
        let mut m = Joint3Sentinel::new(pose, 5.0, 0.5, 4, floor);
        let mut found = Vec::new();
        for k in 0..30u64 {
            let turn = if k >= 12 { 1.0 } else { 0.0 };
            if let Some(s) = m.add(100 * k, 0.004 - 0.03 * turn + noise()) {
                found.push((k, s));
            }
        }
        assert_eq!(found.len(), 1, "{found:?}");
        let (k, s) = found[0];
        assert_eq!(k, 13);
        assert!((s.offset_deg - 1.0).abs() < 0.2, "{s:?}");
        assert_eq!(s.since_idx, 1101);
        assert!((m.offset_deg() - 1.0).abs() < 0.2);
        // a reading that is not a number is left out
        assert_eq!(m.add(4000, f64::NAN), None);
        assert_eq!(m.readings(), 30);
        // one glitched reading (a speck on one probe) is not a slip, and is left out
        let mut m = Joint3Sentinel::new(pose, 5.0, 0.5, 4, floor);
        for k in 0..30u64 {
            let glitch = if k == 15 { 0.05 } else { 0.0 };
            assert_eq!(m.add(100 * k, glitch + noise()), None, "reading {k}");
        }
    }
}
