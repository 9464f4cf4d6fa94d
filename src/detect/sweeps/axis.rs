//! Which axis moved when the wagon watch's pair departs: the wagon or arm joint 1, told apart by
//! re-captures chosen for it (a rig that takes probes).
//!
//! The pair moves with joint 1 about as much as with the wagon (`wagon_watch`): both move the
//! camera along the arc, and joint 1 moves the light besides. A departure c of the pair (ln
//! units, a = its sensitivities per degree) is a wagon offset c/a_w or a joint-1 slip c/a₁, and
//! the two predict different changes at other poses: one whose luminance turns with the light
//! moves under the slip and not under the wagon. So when the pair departs (after the question
//! of approach, which tells a lag from both), poses of a sweep completed before the change are
//! re-captured back to back: the `per_side` whose v = s₁/a₁ − s_w/a_w is largest and as many
//! whose v is smallest (the smooth model's sensitivities; v is what a unit change of the pair
//! moves a pose by under the slip, less under the wagon), from a sweep `RECAPTURE_BACK_SWEEPS`
//! or more before the change's first possible capture (a CUSUM run can start a reading after
//! the change). Their contrast D (the first half's
//! mean r less the second half's, free of the lamp twice over as a slip's re-captures are)
//! reads c·K₁/a₁ under the slip and c·K_w/a_w under the wagon, K the contrasts of s₁ and s_w.
//! With u = (D − c·K_w/a_w) / (c·K₁/a₁ − c·K_w/a_w), 0 for the wagon and 1 for the slip, and
//! its standard error from the re-capture noise, an axis is named when u is within `AXIS_Z`
//! standard errors and `MODEL_SHARE` of its value (the model's slopes) and beyond them from the
//! other's. Otherwise (or with no reading) the light sweeps' refit decides as before. The
//! fewest per side of `RECAPTURE_PER_SIDE` whose two predictions stand `EXPECTED_SEPARATION`
//! standard errors apart, else the strongest set if a reading at either prediction can decide
//! at all (`MIN_SEPARATION`); none asked otherwise. 8 to 16 captures, once a departure.

use super::recapture::{
    best_set, RecaptureSet, RECAPTURE_BACK_SWEEPS, RECAPTURE_PER_SIDE, RECAPTURE_WAIT_CAPTURES,
};
use super::*;

/// An axis is named when the reading is within this many standard errors of its prediction
/// and further from the other's.
pub(super) const AXIS_Z: f64 = 3.0;
/// The smooth model's slopes are taken to be uncertain by this share of the gap between the
/// two predictions: a reading between them is neither's (the quarter `wagon_watch` allows a
/// pose's response to depart from its slope).
pub(super) const MODEL_SHARE: f64 = 0.25;
/// A set is asked for when its two predictions stand this many standard errors apart (a
/// reading at either then decides with room for the noise) ...
const EXPECTED_SEPARATION: f64 = 5.0;
/// ... or, when none of up to 8 poses a side does, the strongest if they stand this far apart:
/// the least at which a reading at either prediction decides at all,
/// `AXIS_Z` / (1 − `MODEL_SHARE`).
const MIN_SEPARATION: f64 = AXIS_Z / (1.0 - MODEL_SHARE);

/// The question: the set asked for and what each hypothesis predicts of it.
#[derive(Debug, Clone)]
pub(super) struct AxisQuestion {
    set: RecaptureSet,
    /// The set's contrast as a joint-1 slip and as a wagon offset explaining the pair's change
    /// would make it (ln units), and the contrast's standard deviation.
    joint: f64,
    wagon: f64,
    sd: f64,
    asked: bool,
    waited: u64,
    readings: Vec<Option<f64>>,
}

/// What the question read.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AxisReading {
    /// The plan entries re-captured, the first `up` the ones a slip moves up against the wagon.
    pub entries: Vec<usize>,
    pub up: usize,
    /// Their contrast (%), and what a joint-1 slip and a wagon offset that move the pair as it
    /// moved would make it (%), with its standard error (%).
    pub change_pct: f64,
    pub joint1_pct: f64,
    pub wagon_pct: f64,
    pub se_pct: f64,
}

impl AxisReading {
    /// Where the reading falls between the wagon's prediction (0) and the slip's (1), and the
    /// standard error of that.
    pub(crate) fn share_and_se(&self) -> (f64, f64) {
        let gap = self.joint1_pct - self.wagon_pct;
        (
            (self.change_pct - self.wagon_pct) / gap,
            self.se_pct / gap.abs(),
        )
    }
}

/// How the question ended.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum AxisOutcome {
    /// The reading is the slip's and not the wagon's.
    Joint1(AxisReading),
    /// The reading is the wagon's and not the slip's.
    Wagon(AxisReading),
    /// Neither is ruled out, or both are.
    Undecided(AxisReading),
    /// A re-capture was unusable.
    Unread,
}

impl AxisQuestion {
    /// The question for a change `change` (ln units) of the pair `p` with sensitivities
    /// `s` = [wagon, joint 1, joint 2] (ln Y per degree), from the candidate poses of sweeps
    /// completed before it (`SweepMonitor::set_candidates`, valued by v). None when no set
    /// separates the two predictions by `MIN_SEPARATION` standard errors.
    pub(super) fn choose(
        change: f64,
        s: [f64; 3],
        candidates: &[Vec<recapture::Candidate>],
        noise: &recapture::RecaptureNoise,
    ) -> Option<AxisQuestion> {
        if !(change.is_finite() && change != 0.0 && s[0] != 0.0 && s[1] != 0.0) {
            return None;
        }
        // the fewest per side whose predictions stand `EXPECTED_SEPARATION` apart, else the
        // strongest set if a reading at either prediction can decide at all
        let mut strongest: Option<(f64, RecaptureSet)> = None;
        let mut chosen = None;
        for per_side in RECAPTURE_PER_SIDE {
            let Some((z, set)) = best_set(candidates, per_side, noise) else {
                continue;
            };
            let separation = z * change.abs();
            if separation >= EXPECTED_SEPARATION {
                chosen = Some(set);
                break;
            }
            if strongest.as_ref().is_none_or(|(s, _)| separation > *s) {
                strongest = Some((separation, set));
            }
        }
        let set = match (chosen, strongest) {
            (Some(set), _) => set,
            (None, Some((separation, set))) if separation >= MIN_SEPARATION => set,
            _ => return None,
        };
        let k = |col: usize| {
            let v: Vec<f64> = set.smooth().iter().map(|x| x[col]).collect();
            set.contrast(&v)
        };
        let (joint, wagon) = (change * k(0) / s[1], change * k(2) / s[0]);
        let (_, sd) = set.sensitivity_and_sd();
        if !(joint.is_finite() && wagon.is_finite() && sd.is_finite() && sd > 0.0) {
            return None;
        }
        let n = set.entries().len();
        Some(AxisQuestion {
            set,
            joint,
            wagon,
            sd,
            asked: false,
            waited: 0,
            readings: vec![None; n],
        })
    }

    pub(super) fn wanted(&self) -> Option<Vec<usize>> {
        (!self.asked).then(|| self.set.entries().to_vec())
    }

    pub(super) fn asked(&mut self) {
        self.asked = true;
    }

    /// Whether a probe of `entry` is a re-capture the question waits for.
    pub(super) fn awaits(&self, entry: usize) -> bool {
        self.asked
            && self
                .set
                .entries()
                .iter()
                .zip(&self.readings)
                .any(|(e, r)| *e == entry && r.is_none())
    }

    /// A regular capture was checked: true when the question has waited too long.
    pub(super) fn wait(&mut self) -> bool {
        if self.asked {
            self.waited += 1;
        }
        self.waited >= RECAPTURE_WAIT_CAPTURES
    }

    /// A re-capture of `entry` with luminance `y`; the outcome once all are in.
    pub(super) fn handle(&mut self, entry: usize, y: f64) -> Option<AxisOutcome> {
        let k = self
            .set
            .entries()
            .iter()
            .zip(&self.readings)
            .position(|(e, r)| *e == entry && r.is_none())?;
        // NaN marks an unusable re-capture: the question then reads nothing
        let r = (y / self.set.y0()[k]).ln();
        self.readings[k] = Some(if r.is_finite() { r } else { f64::NAN });
        let r: Vec<f64> = self.readings.iter().copied().collect::<Option<_>>()?;
        if r.iter().any(|v| !v.is_finite()) {
            return Some(AxisOutcome::Unread);
        }
        let reading = AxisReading {
            entries: self.set.entries().to_vec(),
            up: self.set.up(),
            change_pct: 100.0 * self.set.contrast(&r),
            joint1_pct: 100.0 * self.joint,
            wagon_pct: 100.0 * self.wagon,
            se_pct: 100.0 * self.sd,
        };
        let (u, se) = reading.share_and_se();
        // each prediction is uncertain by the noise and by `MODEL_SHARE` of their gap
        let reach = AXIS_Z * se + MODEL_SHARE;
        Some(if !(u.is_finite() && se.is_finite()) {
            AxisOutcome::Unread
        } else if u > reach && (1.0 - u).abs() <= reach {
            AxisOutcome::Joint1(reading)
        } else if u.abs() <= reach && 1.0 - u > reach {
            AxisOutcome::Wagon(reading)
        } else {
            AxisOutcome::Undecided(reading)
        })
    }
}

impl SweepMonitor {
    /// The question for a departure of the pair by `change` (ln units) since capture
    /// `since_idx`, with the pair's sensitivities `s` ([wagon, joint 1, joint 2]).
    pub(super) fn choose_axis(
        &self,
        change: f64,
        s: [f64; 3],
        since_idx: u64,
    ) -> Option<AxisQuestion> {
        let noise = self.recapture?;
        // poses first taken before the change: a CUSUM run can start a reading after it
        let candidates = self.set_candidates(since_idx, RECAPTURE_BACK_SWEEPS, |smooth, _| {
            smooth.map(|x| x[0] / s[1] - x[2] / s[0])
        });
        AxisQuestion::choose(change, s, &candidates, &noise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use recapture::{Candidate, Original, RecaptureNoise};

    /// The pair: 1.2 %/° of wagon, −1.6 %/° of joint 1.
    const PAIR: [f64; 3] = [0.012, -0.016, 0.0];

    /// One sweep's poses, their sensitivities [joint 1, joint 2, wagon] spread over both signs.
    fn poses() -> Vec<[f64; 3]> {
        (0..12)
            .map(|k| {
                let a = k as f64 / 11.0 - 0.5;
                [0.06 * a, 0.0, 0.02 * (3.0 * a).sin()]
            })
            .collect()
    }

    fn candidates() -> Vec<Vec<Candidate>> {
        let mut c: Vec<Candidate> = poses()
            .into_iter()
            .enumerate()
            .map(|(k, s)| Candidate {
                value: s[0] / PAIR[1] - s[2] / PAIR[0],
                entry: 100 + k,
                y0: 1.0,
                original: Original::for_test(k as u64),
                smooth: s,
            })
            .collect();
        c.sort_by(|a, b| b.value.total_cmp(&a.value));
        vec![c]
    }

    fn noise() -> RecaptureNoise {
        RecaptureNoise {
            capture_sd: 0.003,
            y_ref: None,
        }
    }

    /// The question for the pair's change `change`, answered by poses that moved by
    /// `joint1`° of joint 1 and `wagon`° of wagon (and `extra` each, ln units).
    fn answer(change: f64, joint1: f64, wagon: f64, extra: f64) -> AxisOutcome {
        let mut q =
            AxisQuestion::choose(change, PAIR, &candidates(), &noise()).expect("a question");
        let entries = q.wanted().expect("asked once");
        q.asked();
        assert!(q.wanted().is_none());
        let s = poses();
        let mut out = None;
        for e in entries {
            assert!(q.awaits(e));
            let p = s[e - 100];
            out = q.handle(e, (p[0] * joint1 + p[2] * wagon + extra).exp());
        }
        out.expect("all answered")
    }

    #[test]
    fn a_slip_of_joint_1_and_a_wagon_offset_that_move_the_pair_alike_read_apart() {
        // a +1° slip moves the pair by −1.6 %; so does a −1.33° wagon offset
        let change = PAIR[1];
        assert!(matches!(
            answer(change, 1.0, 0.0, 0.0),
            AxisOutcome::Joint1(_)
        ));
        assert!(matches!(
            answer(change, 0.0, change / PAIR[0], 0.0),
            AxisOutcome::Wagon(_)
        ));
        // the lamp moves every re-capture alike: it cancels
        assert!(matches!(
            answer(change, 1.0, 0.0, 0.05),
            AxisOutcome::Joint1(_)
        ));
        // half of each is neither
        assert!(matches!(
            answer(change, 0.5, 0.5 * change / PAIR[0], 0.0),
            AxisOutcome::Undecided(_)
        ));
        let AxisOutcome::Joint1(r) = answer(-change, -1.0, 0.0, 0.0) else {
            panic!("a slip of the other sign")
        };
        let (u, se) = r.share_and_se();
        assert!(
            (u - 1.0).abs() < 1e-9 && se > 0.0 && se < 1.0 / (2.0 * AXIS_Z),
            "{r:?}"
        );
    }

    #[test]
    fn a_broken_re_capture_reads_nothing_and_a_change_too_small_asks_nothing() {
        let mut q = AxisQuestion::choose(PAIR[1], PAIR, &candidates(), &noise()).unwrap();
        let entries = q.wanted().unwrap();
        assert!(!q.awaits(entries[0]), "not before it is asked");
        q.asked();
        assert_eq!(q.handle(entries[0], 0.0), None);
        assert!(!q.awaits(entries[0]), "each pose once");
        assert_eq!(q.handle(9999, 1.0), None, "not one of its poses");
        let mut out = None;
        for &e in &entries[1..] {
            out = q.handle(e, 1.0);
        }
        assert_eq!(out, Some(AxisOutcome::Unread));
        // a change of a tenth of a per cent: no set separates the two at this noise
        assert!(AxisQuestion::choose(0.001, PAIR, &candidates(), &noise()).is_none());
        assert!(AxisQuestion::choose(f64::NAN, PAIR, &candidates(), &noise()).is_none());
        // the wait runs out after it is asked
        let mut q = AxisQuestion::choose(PAIR[1], PAIR, &candidates(), &noise()).unwrap();
        assert!(!(0..100).any(|_| q.wait()), "not asked: no wait");
        q.asked();
        assert!((0..RECAPTURE_WAIT_CAPTURES).any(|_| q.wait()));
    }

    fn reading(change: f64, joint: f64, wagon: f64, se: f64) -> AxisReading {
        AxisReading {
            entries: vec![1, 2],
            up: 1,
            change_pct: change,
            joint1_pct: joint,
            wagon_pct: wagon,
            se_pct: se,
        }
    }

    #[test]
    fn the_share_is_zero_at_the_wagons_prediction_and_one_at_the_slips() {
        let (u, se) = reading(-0.5, 2.0, -0.5, 0.25).share_and_se();
        assert!(u.abs() < 1e-12 && (se - 0.1).abs() < 1e-12);
        let (u, _) = reading(2.0, 2.0, -0.5, 0.25).share_and_se();
        assert!((u - 1.0).abs() < 1e-12);
        // a negative change: the predictions change sign with it, the share does not
        let (u, se) = reading(-2.0, -2.0, 0.5, 0.25).share_and_se();
        assert!((u - 1.0).abs() < 1e-12 && (se - 0.1).abs() < 1e-12);
    }
}
