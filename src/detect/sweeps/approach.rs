//! The wagon's lag from one pose re-captured from both sides (a rig that takes probes).
//!
//! A lag b of the wagon against its last commanded direction of motion (play in its drive) puts
//! a camera approached from below at w − b and one approached from above at w + b; a constant
//! wagon offset, an arm joint's slip and every stationary effect of the geometry put both at
//! the same place. So one pose re-captured twice, first right after a pose with a lower wagon
//! angle and then right after one with a higher (`[below, pose, above, pose]`, back to back: the
//! lamp's gain cancels between the two), reads ln(Y₁/Y₂) = −b·s_w·(d₁ − d₂), with d the
//! direction of approach the commanded poses show and s_w = ∂ln Y/∂w the smooth model's.
//!
//! It is asked once the re-captured pair departs (`wagon_watch`), before the light sweeps are
//! asked which axis moved: the pair departs under a lag as under an offset (each of its
//! re-captures comes from whichever side the pose before it was on), and without this question
//! a 1° lag was named as the wagon's offset of −1.0° to −1.3°. A lag shown by `APPROACH_Z`
//! standard errors and the joint tolerance names the wagon's backlash with the reading as its
//! size; otherwise the reading goes with the departure to the attribution (an offset or a joint
//! reads the same from both sides, and the offset's alarm says so). Four captures, once a
//! departure.

use super::recapture::{RecaptureNoise, RECAPTURE_WAIT_CAPTURES};
use super::wagon_watch::WagonPair;
use super::*;

/// A lag is named when the reading shows it by this many standard errors (and by the joint
/// tolerance).
const APPROACH_Z: f64 = 3.0;
/// The poses approached from are at least this far from the pose in wagon angle: more than any
/// play the drive could hide in a move.
const APPROACH_MARGIN_DEG: f64 = 2.0;

/// The pose re-captured from both sides: what was asked and what came back.
#[derive(Debug, Clone)]
pub(super) struct Approach {
    /// Plan entries in the order asked: a pose below, the pose, a pose above, the pose.
    entries: [usize; 4],
    /// Which of `entries` have been taken.
    taken: [bool; 4],
    /// ln Y per degree of wagon at the pose (smooth model) and the variance of the difference
    /// of two of its captures (the re-capture noise model at its luminance).
    s: f64,
    var: f64,
    asked: bool,
    waited: u64,
    /// The pose's captures: ln Y and the direction the wagon approached it from.
    readings: Vec<(f64, f64)>,
    /// A capture of the pose was unusable: the question ends without a reading.
    spoiled: bool,
}

/// What a pose re-captured from both sides read.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ApproachReading {
    /// Plan entries in the order asked: a pose below, the pose, a pose above, the pose.
    pub entries: [usize; 4],
    /// ln Y of the pose approached from below less from above (%), its change per degree of
    /// wagon (%/°), and the lag that makes (degrees, positive: the wagon lags its motion) with
    /// its standard error.
    pub change_pct: f64,
    pub sensitivity_pct_per_deg: f64,
    pub backlash_deg: f64,
    pub se_deg: f64,
}

/// How a question of approach ended.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum ApproachOutcome {
    /// The pose read differently from the two sides: a lag.
    Lag(ApproachReading),
    /// It read the same within its noise (or the wrong way round: a lead is not a drive's play).
    NoLag(ApproachReading),
    /// No reading: a capture of the pose was unusable, or the rig did not approach it from
    /// both sides.
    Unread,
}

impl Approach {
    /// The question for the pair `p`: its pose with the most wagon sensitivity `s[k]` (ln Y per
    /// degree at each pose) that has earlier poses at least `APPROACH_MARGIN_DEG` below and above
    /// it in wagon angle among `captures` (the nearest such; none of `excluded`). None when
    /// neither pose has both.
    pub(super) fn choose(
        p: &WagonPair,
        s: [f64; 2],
        captures: &[SweepCapture],
        excluded: &[usize],
        noise: &RecaptureNoise,
    ) -> Option<Approach> {
        let mut order = [0usize, 1];
        order.sort_by(|&a, &b| s[b].abs().total_cmp(&s[a].abs()));
        for k in order {
            if !(s[k].is_finite() && s[k] != 0.0) {
                continue;
            }
            let w = p.cmd[k][3];
            let usable = |c: &&SweepCapture| {
                c.y > 0.0
                    && c.cmd[3].is_finite()
                    && !excluded.contains(&c.entry)
                    && !p.entries.contains(&c.entry)
            };
            let below = captures
                .iter()
                .filter(usable)
                .filter(|c| c.cmd[3] <= w - APPROACH_MARGIN_DEG)
                .max_by(|a, b| a.cmd[3].total_cmp(&b.cmd[3]));
            let above = captures
                .iter()
                .filter(usable)
                .filter(|c| c.cmd[3] >= w + APPROACH_MARGIN_DEG)
                .min_by(|a, b| a.cmd[3].total_cmp(&b.cmd[3]));
            if let (Some(lo), Some(hi)) = (below, above) {
                let pose = p.entries[k];
                return Some(Approach {
                    entries: [lo.entry, pose, hi.entry, pose],
                    taken: [false; 4],
                    s: s[k],
                    var: noise.var_at(p.y0[k]),
                    asked: false,
                    waited: 0,
                    readings: Vec::with_capacity(2),
                    spoiled: false,
                });
            }
        }
        None
    }

    /// A question about `entries` for the tests, not yet asked.
    #[cfg(test)]
    pub(super) fn for_test(entries: [usize; 4], s: f64, var: f64) -> Self {
        Approach {
            entries,
            taken: [false; 4],
            s,
            var,
            asked: false,
            waited: 0,
            readings: Vec::new(),
            spoiled: false,
        }
    }

    /// The entries to ask for, once.
    pub(super) fn wanted(&self) -> Option<Vec<usize>> {
        (!self.asked).then(|| self.entries.to_vec())
    }

    pub(super) fn asked(&mut self) {
        self.asked = true;
    }

    /// Whether a probe of `entry` is one this question waits for.
    pub(super) fn awaits(&self, entry: usize) -> bool {
        self.asked
            && self
                .entries
                .iter()
                .zip(&self.taken)
                .any(|(e, t)| *e == entry && !t)
    }

    /// A regular capture was checked: true when the question has waited
    /// `RECAPTURE_WAIT_CAPTURES` since it was asked (it is then dropped).
    pub(super) fn wait(&mut self) -> bool {
        if self.asked {
            self.waited += 1;
        }
        self.waited >= RECAPTURE_WAIT_CAPTURES
    }

    /// A re-capture of `entry` with luminance `y`, taken after the wagon last moved in
    /// direction `dir` (+1 up, −1 down, 0 unknown). Some once the pose's second capture is in.
    pub(super) fn handle(
        &mut self,
        entry: usize,
        y: f64,
        dir: f64,
        tolerance_deg: f64,
    ) -> Option<ApproachOutcome> {
        let slot = (0..4).find(|&k| self.entries[k] == entry && !self.taken[k])?;
        self.taken[slot] = true;
        if slot == 1 || slot == 3 {
            let l = y.ln();
            if l.is_finite() {
                self.readings.push((l, dir));
            } else {
                self.spoiled = true;
            }
        }
        if !(self.taken[1] && self.taken[3]) {
            return None;
        }
        Some(self.judge(tolerance_deg))
    }

    fn judge(&self, tolerance_deg: f64) -> ApproachOutcome {
        let [(l1, d1), (l2, d2)] = match self.readings.as_slice() {
            [a, b] if !self.spoiled => [*a, *b],
            _ => return ApproachOutcome::Unread,
        };
        // one from below (d = +1) and one from above (d = −1), whichever came first
        if !(d1 * d2 < 0.0) {
            return ApproachOutcome::Unread;
        }
        let (below, above) = if d1 > 0.0 { (l1, l2) } else { (l2, l1) };
        let change = below - above;
        // ln Y = c − b·s·d: from below less from above is −2·b·s
        let backlash = -change / (2.0 * self.s);
        let se = self.var.sqrt() / (2.0 * self.s).abs();
        let reading = ApproachReading {
            entries: self.entries,
            change_pct: 100.0 * change,
            sensitivity_pct_per_deg: 100.0 * self.s,
            backlash_deg: backlash,
            se_deg: se,
        };
        if !(backlash.is_finite() && se.is_finite()) {
            return ApproachOutcome::Unread;
        }
        if backlash >= APPROACH_Z * se && backlash >= tolerance_deg {
            ApproachOutcome::Lag(reading)
        } else {
            ApproachOutcome::NoLag(reading)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn question() -> Approach {
        let mut q = Approach::for_test([100, 200, 300, 200], 0.04, 2.0 * 0.004f64.powi(2));
        q.asked();
        q
    }

    /// The pose's luminance under a lag `b` (degrees) approached from `dir`.
    fn y(b: f64, dir: f64) -> f64 {
        0.5 * (-b * 0.04 * dir).exp()
    }

    #[test]
    fn a_lag_reads_from_both_sides_and_an_offset_does_not() {
        let mut q = question();
        assert!(q.awaits(100) && q.awaits(200) && q.awaits(300) && !q.awaits(400));
        assert_eq!(q.handle(100, 0.3, 1.0, 0.25), None);
        assert_eq!(q.handle(200, y(1.0, 1.0), 1.0, 0.25), None);
        assert!(q.awaits(200), "the pose is asked twice");
        assert_eq!(q.handle(300, 0.3, 1.0, 0.25), None);
        let Some(ApproachOutcome::Lag(r)) = q.handle(200, y(1.0, -1.0), -1.0, 0.25) else {
            panic!("a lag")
        };
        assert!((r.backlash_deg - 1.0).abs() < 1e-9, "{r:?}");
        assert!((r.se_deg - 0.004 * 2f64.sqrt() / 0.08).abs() < 1e-12);
        assert!(!q.awaits(200));
        // an offset (or a joint) moves both captures alike
        let mut q = question();
        q.handle(200, 0.5 * 1.04, 1.0, 0.25);
        let Some(ApproachOutcome::NoLag(r)) = q.handle(200, 0.5 * 1.04, -1.0, 0.25) else {
            panic!("no lag")
        };
        assert!(r.backlash_deg.abs() < 1e-12);
        // the order of the sides does not matter
        let mut q = question();
        q.handle(200, y(0.8, -1.0), -1.0, 0.25);
        let Some(ApproachOutcome::Lag(r)) = q.handle(200, y(0.8, 1.0), 1.0, 0.25) else {
            panic!("a lag")
        };
        assert!((r.backlash_deg - 0.8).abs() < 1e-9);
    }

    #[test]
    fn a_lead_a_small_lag_one_side_or_a_broken_capture_names_nothing() {
        // a lead is not a drive's play
        let mut q = question();
        q.handle(200, y(-1.0, 1.0), 1.0, 0.25);
        assert!(matches!(
            q.handle(200, y(-1.0, -1.0), -1.0, 0.25),
            Some(ApproachOutcome::NoLag(_))
        ));
        // within the noise (se 0.07°): 0.15° is not shown
        let mut q = question();
        q.handle(200, y(0.15, 1.0), 1.0, 0.25);
        assert!(matches!(
            q.handle(200, y(0.15, -1.0), -1.0, 0.25),
            Some(ApproachOutcome::NoLag(_))
        ));
        // both from the same side, or a side not known (the wagon had not moved yet): no
        // reading
        for (d1, d2) in [(1.0, 1.0), (-1.0, -1.0), (0.0, -1.0), (1.0, 0.0)] {
            let mut q = question();
            q.handle(200, y(1.0, d1), d1, 0.25);
            assert_eq!(
                q.handle(200, y(1.0, d2), d2, 0.25),
                Some(ApproachOutcome::Unread),
                "{d1} {d2}"
            );
        }
        // a pose the question does not wait for changes nothing
        let mut q = question();
        assert_eq!(q.handle(999, 0.5, 1.0, 0.25), None);
        assert!(q.awaits(100) && q.awaits(200));
        // a dark or broken capture of the pose
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let mut q = question();
            q.handle(200, bad, 1.0, 0.25);
            assert_eq!(
                q.handle(200, 0.5, -1.0, 0.25),
                Some(ApproachOutcome::Unread),
                "{bad}"
            );
        }
    }

    #[test]
    fn an_unanswered_question_is_dropped_after_the_wait() {
        let mut q = question();
        for _ in 1..RECAPTURE_WAIT_CAPTURES {
            assert!(!q.wait());
        }
        assert!(q.wait());
        // not counted before it is asked
        let mut q = question();
        q.asked = false;
        for _ in 0..2 * RECAPTURE_WAIT_CAPTURES {
            assert!(!q.wait());
        }
    }
}
