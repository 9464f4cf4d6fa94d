//! The wagon's offset from re-captures of two poses (a rig that takes probes).
//!
//! The light sweeps cannot name a constant wagon offset: it moves ωo along the great circle
//! through both directions, as joint 1 moves both, and the F + L + C reference takes most of it
//! up within a few sweeps (`wagon`). A re-capture can see it: a pose taken again shows the
//! wagon's offset since its original as s_w·δ (s_w = ∂ ln Y / ∂w), and a stationary effect of
//! the geometry not at all.
//!
//! The watch chooses two earlier poses, from the last `PAIR_WINDOW_SWEEPS` completed sweeps,
//! whose luminance moves most against each other with the wagon at the re-capture noise (the
//! smooth model's sensitivities; θo between 10° and 65°, not a probe's entry), while their
//! difference moves with joint 2 by at most `MAX_JOINT_LEAK` of that and its response to a
//! degree departs from its slope by at most `MAX_CURVATURE`. Joint 1 cannot be held out so:
//! it moves the camera along the arc as the wagon does, and the light besides, and the pairs
//! with the most wagon sensitivity move with joint 1 by −1.0 to −1.4 times as much. With
//! d = ln(Y_a/Y_a0) − ln(Y_b/Y_b0), the two re-captured back to back, the lamp's gain cancels
//! between the re-captures, and what it was at the two originals is a constant of the pair.
//! The pair is asked for right after it is chosen and after each sweep until `MIN_SEGMENT`
//! readings are in, then every `wagon_watch_sweeps` sweeps (`[checks.sweeps]`), and after the
//! next sweep when a reading departs by `AGAIN_Z`: on the UBO plan 48 to 66 captures on the
//! design models, under 1 % of the run.
//!
//! Each reading against the mean of the readings in control, in units of their SD (floored at
//! the noise model's, widened into a prediction interval), clipped, feeds a two-sided CUSUM
//! whose threshold comes from the false-alarm budget over the run's questions; a crossing needs
//! two readings (one glitched capture cannot make one) and a mean of `MIN_OFFSET_TOLERANCES`
//! joint tolerances. It is a change of the camera's pose: play in the wagon's drive, which one
//! of the pair's poses re-captured from below and from above shows first (`approach`), or the
//! wagon's or joint 1's offset, which the light sweeps tell apart (`attribute_departure`):
//! joint 1 moves the light too, which the sweeps see. A joint slip the sweeps name restarts
//! the watch's reference: the pose changed, and the slip's alarm covers it.
//!
//! What it cannot see: an offset the wagon had before the pair's originals (a calibration error
//! from the start), and an offset smaller than its noise allows on a sample whose luminance
//! barely changes with the view (the summary gives the pair's standard error per reading).

use super::approach::{Approach, ApproachOutcome, ApproachReading};
use super::axis::{AxisOutcome, AxisQuestion, AxisReading};
use super::level::ScaleHistory;
use super::model::{Model, Row, ATTRIBUTION_Z, SMOOTH_SE_MAX_DEG};
use super::recapture::RecaptureNoise;
use super::*;

/// The wagon is named only when the CUSUM run's mean is at least this many joint tolerances of
/// wagon (0.5° at the default 0.25°).
pub(super) const MIN_OFFSET_TOLERANCES: f64 = 2.0;
/// Readings in the segment before the CUSUM runs.
pub(super) const MIN_SEGMENT: usize = 4;
/// The pair's sensitivity to joint 2 against its sensitivity to the wagon, at most (joint 1
/// cannot be held out so: the module comment); a joint-2 slip of 2° reads as 0.5° of wagon.
pub(super) const MAX_JOINT_LEAK: f64 = 0.25;
/// A pair is chosen only when a 1° offset moves a reading by this many standard deviations of
/// the noise model.
pub(super) const MIN_Z_PER_DEG: f64 = 2.0;
/// The pair's poses come from the completed sweeps among the last this many.
pub(super) const PAIR_WINDOW_SWEEPS: usize = 12;
/// A departure the light sweeps have not attributed after this many sweeps is named as the
/// wagon's, with the joint-1 offset that would read the same.
pub(super) const MAX_ATTRIBUTION_SWEEPS: usize = 3;
/// A reading this many standard deviations from the segment is asked again after the next
/// sweep rather than after `wagon_watch_sweeps`.
const AGAIN_Z: f64 = 2.0;
/// Questions a run asks, about (the CUSUM threshold's false-alarm budget).
const QUESTIONS_PER_RUN: f64 = 30.0;
/// Re-captured poses are at most this far from the normal on the camera side (cos θo): at
/// grazing view the captures are dim and their luminance turns fastest with a jitter ...
const MIN_COS_THETA_O: f64 = 0.42; // θo ≤ 65°
/// ... and at least this far: at the pole a camera's luminance turns with the wagon to second
/// order, whichever way it moves.
const MAX_COS_THETA_O: f64 = 0.985; // θo ≥ 10°
/// The pair's response to a degree of wagon departs from its slope by at most this fraction of
/// it (the smooth model's second difference): the size is read off the slope.
const MAX_CURVATURE: f64 = 0.25;

/// The two poses the watch re-captures.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct WagonPair {
    /// Plan entries: the one rising with the wagon, then the falling one.
    pub entries: [usize; 2],
    /// Their commanded poses (for the current model's sensitivities).
    pub cmd: [[f64; 4]; 2],
    /// The originals' luminance and light directions.
    pub y0: [f64; 2],
    lights: [usize; 2],
    /// ln Y per degree of wagon, joint 1 and joint 2 of the difference, when chosen.
    s: [f64; 3],
    /// The variance of one reading of d against another from the noise model (the two
    /// re-captures'; the originals are common to every reading).
    var: f64,
    /// The last capture before the pair was chosen.
    chosen_idx: u64,
}

/// One question: the pair asked for, and its two readings.
#[derive(Debug, Clone)]
struct Question {
    asked: bool,
    waited: u64,
    readings: [Option<f64>; 2],
    /// The sweep it was asked after.
    at: SweepAt,
}

/// A departure of the pair waiting for the light sweeps to say which axis moved.
#[derive(Debug, Clone, Copy)]
struct Departed {
    /// The question it crossed at.
    at: SweepAt,
    /// The CUSUM run's mean change (ln units) and its standard error, and its readings.
    change: f64,
    change_se: f64,
    readings: usize,
    statistic: f64,
    threshold: f64,
    /// The first capture it can have affected, and the last capture of the sweep its run's
    /// first reading was asked after (every sweep after it is the changed pose's).
    since_idx: u64,
    run_start: u64,
    /// The pair's sensitivities [wagon, joint 1, joint 2] when it crossed.
    s: [f64; 3],
    /// Sweeps completed since.
    sweeps: usize,
    /// Whether the question of which axis moved (`axis`) was asked or could not be.
    axis_asked: bool,
}

/// A reading of the pair the checks asked for out of turn (a lamp probe that departed from its
/// trend, `request_pose_check`): whether the camera's pose moved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum PoseCheck {
    /// The pair's reading against its readings in control: in their standard deviations
    /// (unclipped), and as degrees of wagon.
    Read { z: f64, wagon_deg: f64 },
    /// No reading came: the question was dropped, the watch started again, or the reading was
    /// unusable.
    Unanswered,
}

/// Where an out-of-turn check of the pose stands.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
enum PoseCheckState {
    #[default]
    Idle,
    Waiting,
    Done(PoseCheck),
}

/// The watch as the summary reports it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WagonWatchSummary {
    /// The two plan entries re-captured (none while no pair qualifies).
    pub entries: Option<[usize; 2]>,
    /// The pair's change per degree of wagon (%/°), and per degree of joints 1 and 2.
    pub sensitivity_pct_per_deg: f64,
    pub joint_sensitivity_pct_per_deg: [f64; 2],
    /// Questions answered.
    pub readings: usize,
    /// The latest reading as a wagon offset against the segment (degrees), and the standard
    /// error of one reading.
    pub offset_deg: f64,
    pub se_deg: f64,
}

/// The watch's state.
#[derive(Debug, Clone, Default)]
pub(super) struct WagonWatch {
    pair: Option<WagonPair>,
    question: Option<Question>,
    /// Completed sweeps since the last question was asked for.
    sweeps_since: usize,
    /// The readings in control (held back while a CUSUM run is under way).
    segment: ScaleHistory,
    cusum: Cusum,
    /// The sweep each answered question was asked after (its last capture), in order.
    asked_after: Vec<u64>,
    readings: usize,
    /// The latest reading against the segment (ln units).
    last_e: Option<f64>,
    departed: Option<Departed>,
    /// The latest reading's standardised departure from the segment.
    last_z: f64,
    /// An out-of-turn check of the pose the checks wait for.
    pose_check: PoseCheckState,
    /// The last completed sweep: an out-of-turn question is asked after it.
    last_at: Option<SweepAt>,
    /// A departure's pose re-captured from both sides (`approach`), while it is under way.
    approach: Option<Approach>,
    /// What it read when it showed no lag: the offset's alarm carries it.
    approach_read: Option<ApproachReading>,
    /// Then re-captures that tell the wagon from joint 1 (`axis`), while under way ...
    axis: Option<AxisQuestion>,
    /// ... and what they read: the alarm that names the departure carries it.
    axis_read: Option<AxisReading>,
}

impl WagonWatch {
    /// Whether `entry` is one of the pair's (not offered for other re-captures).
    pub(super) fn holds(&self, entry: usize) -> bool {
        self.pair
            .as_ref()
            .is_some_and(|p| p.entries.contains(&entry))
    }

    /// The entries to ask for, once per question: a departure's question of approach first.
    pub(super) fn wanted(&self) -> Option<Vec<usize>> {
        if let Some(a) = self.approach.as_ref() {
            return a.wanted();
        }
        if let Some(a) = self.axis.as_ref() {
            return a.wanted();
        }
        let p = self.pair.as_ref()?;
        self.question
            .as_ref()
            .filter(|q| !q.asked)
            .map(|_| p.entries.to_vec())
    }

    pub(super) fn asked(&mut self) {
        if let Some(a) = self.approach.as_mut() {
            a.asked();
        } else if let Some(a) = self.axis.as_mut() {
            a.asked();
        } else if let Some(q) = self.question.as_mut() {
            q.asked = true;
        }
    }

    /// Whether a probe of `entry` is a re-capture the question of approach waits for.
    pub(super) fn awaits_approach(&self, entry: usize) -> bool {
        self.approach.as_ref().is_some_and(|a| a.awaits(entry))
    }

    /// Whether a probe of `entry` is a re-capture the question of which axis moved waits for.
    pub(super) fn awaits_axis(&self, entry: usize) -> bool {
        self.axis.as_ref().is_some_and(|a| a.awaits(entry))
    }

    /// Whether a probe of `entry` is a re-capture a question waits for.
    pub(super) fn awaits(&self, entry: usize) -> bool {
        if self.awaits_approach(entry) || self.awaits_axis(entry) {
            return true;
        }
        let (Some(p), Some(q)) = (self.pair.as_ref(), self.question.as_ref()) else {
            return false;
        };
        q.asked
            && p.entries
                .iter()
                .zip(&q.readings)
                .any(|(e, r)| *e == entry && r.is_none())
    }

    /// A joint slip was named: the pose changed, the segment starts again.
    pub(super) fn restart(&mut self) {
        self.segment = ScaleHistory::default();
        self.cusum.reset();
        self.departed = None;
        self.approach = None;
        self.approach_read = None;
        self.axis = None;
        self.axis_read = None;
        self.end_pose_check(PoseCheck::Unanswered);
    }

    /// An out-of-turn check waiting for a reading gets `check`.
    fn end_pose_check(&mut self, check: PoseCheck) {
        if self.pose_check == PoseCheckState::Waiting {
            self.pose_check = PoseCheckState::Done(check);
        }
    }

    /// Sweeps between questions: one while the segment fills and after a reading beyond
    /// `AGAIN_Z` (a departure is asked again at once), `every` otherwise.
    fn cadence(&self, every: usize) -> usize {
        if self.segment.len() < MIN_SEGMENT || self.last_z.abs() > AGAIN_Z {
            1
        } else {
            every.max(1)
        }
    }

    /// The segment's mean and the scale of a reading against it (ln units): the segment's SD,
    /// floored at the noise model's `floor_var`, widened into a prediction interval's (the
    /// mean's own uncertainty, and Student's t against the normal for an SD from few readings).
    fn reference(&self, floor_var: f64) -> Option<(f64, f64)> {
        let v = &self.segment.values;
        let n = v.len();
        if n < MIN_SEGMENT {
            return None;
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let widen = (1.0 + 1.0 / n as f64).sqrt() * t975(n - 1) / T975_NORMAL;
        Some((mean, var.max(floor_var).sqrt() * widen))
    }
}

/// About how many questions the watch asks in a run of `lights` light sweeps at one every
/// `every_sweeps`, two captures each: the readings that fill its reference come one a sweep
/// (the pair is chosen in the run's first layers), and a reading beyond `AGAIN_Z` is asked
/// again after the next sweep (measured on the design models: 24 to 33 in a UBO run).
pub(crate) fn wagon_watch_questions(lights: usize, every_sweeps: usize) -> u64 {
    if every_sweeps == 0 {
        return 0;
    }
    (MIN_SEGMENT + lights / every_sweeps) as u64
}

/// The normal's 97.5 % quantile.
const T975_NORMAL: f64 = 1.959_964;

/// Student's t 97.5 % quantile with `df` degrees of freedom (the normal's beyond 30).
fn t975(df: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => T[0],
        1..=30 => T[df - 1],
        _ => T975_NORMAL,
    }
}

impl SweepMonitor {
    /// After a completed sweep: attribute a departure of the pair (`attribute`), choose the
    /// pair (while none is chosen), and ask the next question when it is due. Only on a
    /// probe-taking rig, with the watch on. Returns the slip named when a departure was a
    /// joint's.
    pub(super) fn wagon_watch_sweep(
        &mut self,
        sweep: &Sweep,
        known: &Known,
        findings: &mut Vec<SweepFinding>,
    ) -> Option<NamedSlip> {
        let every = self.spec.wagon_watch_sweeps;
        let noise = self.recapture.filter(|_| every > 0)?;
        self.wagon_watch.last_at = Some(sweep.at());
        let named = self.attribute_departure(sweep.at(), known, findings);
        if self.wagon_watch.pair.is_none() {
            self.wagon_watch.pair = self.choose_wagon_pair(sweep, &noise);
            if self.wagon_watch.pair.is_none() {
                return named;
            }
            // the first question right away: its reading is the nearest to the originals
            self.wagon_watch.sweeps_since = usize::MAX;
        }
        let w = &mut self.wagon_watch;
        w.sweeps_since = w.sweeps_since.saturating_add(1);
        if w.question.is_none() && w.sweeps_since >= w.cadence(every) {
            w.sweeps_since = 0;
            w.question = Some(Question {
                asked: false,
                waited: 0,
                readings: [None; 2],
                at: sweep.at(),
            });
        }
        named
    }

    /// A departure of the pair is a change of pose between its questions: the wagon's, or a
    /// joint's (the pair moves with joint 1 about as much as with the wagon). The light sweeps
    /// completed after its run's first reading say which. Each is fitted again, as a slip's size
    /// is (`slip_estimate`), against the F + L + C reference of the captures taken up to the last
    /// reading in control, with the smooth model's columns for both joints, the wagon's
    /// offset and its lag together: so neither the reference nor another axis takes the change
    /// up. The axis whose mean offset over those sweeps points the way the pair's change
    /// implies, by `ATTRIBUTION_Z` standard errors and the joint tolerance, and most standard
    /// errors, is named with that mean as its size: the wagon, or a joint as a slip the
    /// re-captures confirm. None after `MAX_ATTRIBUTION_SWEEPS`: the wagon is named, with the
    /// pair's size and the joint-1 offset that would read the same. While a slip the sweeps
    /// named waits for its own re-captures the departure waits too.
    fn attribute_departure(
        &mut self,
        now: SweepAt,
        known: &Known,
        findings: &mut Vec<SweepFinding>,
    ) -> Option<NamedSlip> {
        let mut x = self.wagon_watch.departed?;
        if self.wagon_watch.approach.is_some() {
            // its pose re-captured from both sides says first whether it is the wagon's lag
            return None;
        }
        if self.pending.is_some() {
            // a slip the sweeps named waits for its own re-captures: it is the likelier cause,
            // and naming it here too would name it twice (its naming restarts the watch)
            return None;
        }
        if self.wagon_watch.axis.is_some() || self.ask_axis() {
            // the re-captures that tell the wagon from joint 1 say first
            return None;
        }
        x.sweeps += 1;
        self.wagon_watch.departed = Some(x);
        let fits = self.refit_axes(x.since_idx, x.run_start, known);
        let mut best: Option<(usize, f64, f64, f64)> = None;
        for (axis, fit) in fits.iter().enumerate() {
            let Some((offset, se)) = *fit else {
                continue;
            };
            let z = offset.abs() / se;
            let implied = x.change / x.s[axis];
            if implied * offset > 0.0
                && z >= ATTRIBUTION_Z
                && offset.abs() >= self.spec.joint_tolerance_deg
                && best.is_none_or(|b| z > b.1)
            {
                best = Some((axis, z, offset, se));
            }
        }
        let (axis, z, offset, se) = match best {
            Some((axis, z, offset, se)) => (axis, Some(z), offset, se),
            None if x.sweeps >= MAX_ATTRIBUTION_SWEEPS => {
                (0, None, x.change / x.s[0], x.change_se / x.s[0])
            }
            None => return None,
        };
        self.name_departure(now, &x, axis, z, offset, se, findings)
    }

    /// Names the departure `x` as axis `axis` (0 the wagon, 1 or 2 a joint) with size `offset`
    /// ± `se` and, when the light sweeps' refit named it, its standard errors `z`: the wagon's
    /// offset (once a run), or a joint's slip the re-captures confirm.
    #[allow(clippy::too_many_arguments)]
    fn name_departure(
        &mut self,
        now: SweepAt,
        x: &Departed,
        axis: usize,
        z: Option<f64>,
        offset: f64,
        se: f64,
        findings: &mut Vec<SweepFinding>,
    ) -> Option<NamedSlip> {
        let p = self.wagon_watch.pair.clone()?;
        self.wagon_watch.departed = None;
        self.wagon_watch.axis = None;
        let approach = self.wagon_watch.approach_read.take();
        let axis_read = self.wagon_watch.axis_read.take();
        if axis == 0 {
            if !self.latched.insert(Latch::Wagon) {
                // the lag test named the wagon already
                return None;
            }
            findings.push(SweepFinding::WagonOffset {
                at: now,
                offset: WagonOffset {
                    offset_deg: offset,
                    se_deg: se,
                    entries: p.entries,
                    change_pct: 100.0 * x.change,
                    sensitivity_pct_per_deg: 100.0 * x.s[0],
                    joint_leak: [x.s[1] / x.s[0], x.s[2] / x.s[0]],
                    originals_lights: p.lights,
                    readings: x.readings,
                    sweeps_z: z,
                    statistic: x.statistic,
                    threshold: x.threshold,
                    since_idx: x.since_idx,
                    approach,
                    told: z.is_some()
                        || axis_read.as_ref().is_some_and(|r| r.share_and_se().0 < 0.5),
                    axis: axis_read,
                },
            });
            return None;
        }
        // a joint: a slip the re-captures confirm
        let j = axis - 1;
        let since = self
            .sweep_starts
            .iter()
            .find(|s| s.first_idx >= x.since_idx)
            .map_or(x.at.last_idx, |s| s.last_idx);
        let crossing = JointCrossing {
            joint: j,
            statistic: z.unwrap_or(0.0),
            mean: offset,
            mean_se: se,
            sweeps: x.sweeps,
            since,
            estimate_sweeps: x.sweeps,
            run_mean: x.change / x.s[axis],
            attributed_level: None,
        };
        let reading = RecaptureReading {
            joint: axis,
            entries: p.entries.to_vec(),
            change_pct: 100.0 * x.change,
            sensitivity_pct_per_deg: 100.0 * x.s[axis],
            offset_deg: x.change / x.s[axis],
            se_deg: (x.change_se / x.s[axis]).abs(),
        };
        let named = self.name_slip(now, &crossing, &[], Recapture::Confirmed(reading), findings);
        if let Some(SweepFinding::JointSlip { slip, .. }) = findings.last_mut() {
            if axis_read.is_some() {
                // named by the re-captures, not by a sweeps' CUSUM: the pair's is the statistic
                slip.statistic = x.statistic;
                slip.threshold = x.threshold;
            }
            slip.axis = axis_read;
        }
        Some(named)
    }

    /// The mean offset and its standard error of [wagon, joint 1, joint 2] over the completed
    /// sweeps that began after capture `after`, each fitted with the smooth model's columns
    /// (both joints, the wagon's offset and its lag) against the reference of the captures
    /// before `cut`. None for an axis no such sweep fits within `SMOOTH_SE_MAX_DEG`.
    fn refit_axes(&self, cut: u64, after: u64, known: &Known) -> [Option<(f64, f64)>; 3] {
        let mut out = [None; 3];
        let in_reference =
            |c: &SweepCapture| c.idx < cut && self.completed.get(c.light).copied().unwrap_or(false);
        if !self.captures.iter().any(in_reference) {
            return out;
        }
        let reference = self.reference_before(cut, known);
        let mut sums = [(0.0, 0.0, 0usize); 3];
        for span in self.sweep_starts.iter().filter(|s| s.first_idx > after) {
            let current = self.captures_of_light(span.light);
            let (_, rows) = self.residuals(&current, &reference, known, Model::Smooth);
            let fit = self.pattern_fit(rows.iter().filter_map(Row::with_wagon).collect());
            // columns: 1 joint 1, 2 joint 2, 3 the wagon's offset, 4 its lag
            for (axis, col) in [(0, 3), (1, 1), (2, 2)] {
                let Some(se) = fit
                    .se(col)
                    .filter(|v| v.is_finite() && *v > 0.0 && *v <= SMOOTH_SE_MAX_DEG)
                else {
                    continue;
                };
                if fit.beta[col].is_finite() {
                    let s = &mut sums[axis];
                    s.0 += fit.beta[col];
                    s.1 += se * se;
                    s.2 += 1;
                }
            }
        }
        for (o, (sum, var, n)) in out.iter_mut().zip(sums) {
            if n > 0 {
                let m = n as f64;
                *o = Some((sum / m, var.sqrt() / m));
            }
        }
        out
    }

    /// The pair from the captures of the last `PAIR_WINDOW_SWEEPS` completed sweeps, or None
    /// when none qualifies.
    fn choose_wagon_pair(&self, sweep: &Sweep, noise: &RecaptureNoise) -> Option<WagonPair> {
        let lights: Vec<usize> = self
            .sweep_starts
            .iter()
            .rev()
            .take(PAIR_WINDOW_SWEEPS)
            .map(|s| s.light)
            .collect();
        let candidates: Vec<(usize, [f64; 3], f64)> = (0..self.captures.len())
            .filter(|&i| {
                let c = &self.captures[i];
                lights.contains(&c.light)
                    && (MIN_COS_THETA_O..=MAX_COS_THETA_O).contains(&c.omega_o.z)
                    && !self.reserved.contains(&c.entry)
            })
            .filter_map(|i| {
                let cmd = &self.captures[i].cmd;
                let s = self.sensitivities(cmd, Model::Smooth)?;
                let c = self.wagon_curvature(cmd)?;
                (s.iter().all(|v| v.is_finite()) && c.is_finite()).then_some((i, s, c))
            })
            .collect();
        let mut best: Option<(f64, usize, usize, [f64; 3], f64)> = None;
        for (a, sa, ca) in &candidates {
            // the readings share their originals: one differs from the next by the two
            // re-captures' noise alone
            let var_a = noise.capture_var(self.captures[*a].y);
            for (b, sb, cb) in &candidates {
                // [wagon, joint 1, joint 2] of a less b: a rises with the wagon against b
                let ds = [sa[2] - sb[2], sa[0] - sb[0], sa[1] - sb[1]];
                if ds[0] <= 0.0
                    || ds[2].abs() > MAX_JOINT_LEAK * ds[0]
                    || (ca - cb).abs() > MAX_CURVATURE * ds[0]
                {
                    continue;
                }
                let var = var_a + noise.capture_var(self.captures[*b].y);
                let z = ds[0] / var.sqrt();
                if z.is_finite() && z >= MIN_Z_PER_DEG && best.is_none_or(|bb| z > bb.0) {
                    best = Some((z, *a, *b, ds, var));
                }
            }
        }
        let (_, a, b, s, var) = best?;
        let (ca, cb) = (&self.captures[a], &self.captures[b]);
        Some(WagonPair {
            entries: [ca.entry, cb.entry],
            cmd: [ca.cmd, cb.cmd],
            y0: [ca.y, cb.y],
            lights: [ca.light, cb.light],
            s,
            var,
            chosen_idx: sweep.last_idx,
        })
    }

    /// Half the second difference of the smooth model's ln Y over a degree of wagon either way
    /// from the commanded pose `cmd` (ln Y per degree², so that a degree moves ln Y by the
    /// slope plus this).
    fn wagon_curvature(&self, cmd: &[f64; 4]) -> Option<f64> {
        let at = |d: f64| {
            self.ln_y(
                &Pose {
                    joints_deg: [cmd[0], cmd[1], cmd[2]],
                    wagon_deg: cmd[3] + d,
                },
                Model::Smooth,
            )
        };
        Some((at(1.0)? + at(-1.0)? - 2.0 * at(0.0)?) / 2.0)
    }

    /// The pair's sensitivities [wagon, joint 1, joint 2] of its difference (ln Y per degree)
    /// with the current smooth model; those it was chosen with where the model gives none.
    fn wagon_pair_sensitivity(&self, p: &WagonPair) -> [f64; 3] {
        match (
            self.sensitivities(&p.cmd[0], Model::Smooth),
            self.sensitivities(&p.cmd[1], Model::Smooth),
        ) {
            (Some(a), Some(b)) => {
                let s = [a[2] - b[2], a[0] - b[0], a[1] - b[1]];
                if s.iter().all(|v| v.is_finite()) && s[0] > 0.0 {
                    s
                } else {
                    p.s
                }
            }
            _ => p.s,
        }
    }

    /// A re-capture of `entry` the question waited for, with luminance `y`. Once both are in,
    /// the reading is judged.
    pub(super) fn handle_wagon_recapture(&mut self, entry: usize, y: f64) {
        let Some(p) = self.wagon_watch.pair.clone() else {
            return;
        };
        let Some(q) = self.wagon_watch.question.as_mut() else {
            return;
        };
        for k in 0..2 {
            if p.entries[k] == entry && q.readings[k].is_none() {
                // an unusable reading ends the question (asked again at the next cadence)
                q.readings[k] = Some((y / p.y0[k]).ln());
                break;
            }
        }
        let [Some(ra), Some(rb)] = q.readings else {
            return;
        };
        let Some(q) = self.wagon_watch.question.take() else {
            return;
        };
        let d = ra - rb;
        let departed = self.wagon_watch.departed.is_some();
        if d.is_finite() {
            self.judge_wagon_reading(&p, &q, d);
        }
        if !departed && self.wagon_watch.departed.is_some() && !self.probes_unstable {
            // before the sweeps are asked which axis moved: a lag reads from both sides
            self.wagon_watch.approach = self.choose_approach(&p);
            if self.wagon_watch.approach.is_none() {
                self.ask_axis();
            }
        }
        self.wagon_watch.end_pose_check(PoseCheck::Unanswered);
    }

    /// The question of approach for the pair `p` (`approach`): none without the re-capture
    /// noise model, or when neither pose has earlier poses on both sides of it.
    fn choose_approach(&self, p: &WagonPair) -> Option<Approach> {
        let noise = self.recapture?;
        let s = |k: usize| {
            self.sensitivities(&p.cmd[k], Model::Smooth)
                .map_or(f64::NAN, |s| s[2])
        };
        Approach::choose(p, [s(0), s(1)], &self.captures, &self.reserved, &noise)
    }

    /// A re-capture the question of approach waited for (`awaits_approach`), taken after the
    /// wagon last moved in direction `wagon_dir`. A lag it shows names the wagon's backlash
    /// (once a run) in place of the departure; a reading without one goes with the departure
    /// to the sweeps' attribution, and the offset's alarm carries it.
    pub(super) fn handle_approach(&mut self, entry: usize, y: f64, wagon_dir: f64) -> SweepOutcome {
        let tolerance = self.spec.joint_tolerance_deg;
        let Some(outcome) = self
            .wagon_watch
            .approach
            .as_mut()
            .and_then(|a| a.handle(entry, y, wagon_dir, tolerance))
        else {
            return SweepOutcome::default();
        };
        self.wagon_watch.approach = None;
        let mut findings = Vec::new();
        match outcome {
            ApproachOutcome::Lag(reading) => {
                if let Some(x) = self.wagon_watch.departed {
                    if self.latched.insert(Latch::Wagon) {
                        self.named_lag = Some(recapture::NamedLag {
                            backlash_deg: reading.backlash_deg,
                            from_idx: x.since_idx,
                        });
                        self.wagon_watch.departed = None;
                        self.wagon_watch.approach_read = None;
                        let offset = x.change / x.s[0];
                        findings.push(SweepFinding::WagonBacklash {
                            at: x.at,
                            backlash: WagonBacklash {
                                backlash_deg: reading.backlash_deg,
                                se_deg: reading.se_deg,
                                estimate_sweeps: 0,
                                run_mean_deg: offset,
                                offset_deg: offset,
                                sweeps: 0,
                                since_idx: x.run_start,
                                from_idx: x.since_idx,
                                statistic: x.statistic,
                                threshold: x.threshold,
                                approach: Some(reading),
                            },
                        });
                    }
                }
            }
            ApproachOutcome::NoLag(reading) => {
                self.wagon_watch.approach_read = Some(reading);
                self.ask_axis();
            }
            ApproachOutcome::Unread => {
                self.ask_axis();
            }
        }
        SweepOutcome {
            findings,
            ..SweepOutcome::default()
        }
    }

    /// Asks the question of which axis moved (`axis`) for the departure under way, once: true
    /// when it was asked. Not while the probes see the lamp unstable.
    fn ask_axis(&mut self) -> bool {
        let Some(mut x) = self.wagon_watch.departed else {
            return false;
        };
        if x.axis_asked {
            return false;
        }
        x.axis_asked = true;
        self.wagon_watch.departed = Some(x);
        if self.probes_unstable {
            return false;
        }
        self.wagon_watch.axis = self.choose_axis(x.change, x.s, x.since_idx);
        self.wagon_watch.axis.is_some()
    }

    /// A re-capture the question of which axis moved waited for (`awaits_axis`), with
    /// luminance `y`. Once all are in, a reading that is one axis's and not the other's names
    /// it; otherwise the light sweeps' refit decides, and the wagon's alarm carries the reading.
    pub(super) fn handle_axis(&mut self, entry: usize, y: f64) -> SweepOutcome {
        let Some(outcome) = self
            .wagon_watch
            .axis
            .as_mut()
            .and_then(|a| a.handle(entry, y))
        else {
            return SweepOutcome::default();
        };
        self.wagon_watch.axis = None;
        let Some(x) = self.wagon_watch.departed else {
            return SweepOutcome::default();
        };
        let mut findings = Vec::new();
        let (axis, reading) = match outcome {
            AxisOutcome::Joint1(r) => (1, r),
            AxisOutcome::Wagon(r) => (0, r),
            AxisOutcome::Undecided(r) => {
                self.wagon_watch.axis_read = Some(r);
                return SweepOutcome::default();
            }
            AxisOutcome::Unread => return SweepOutcome::default(),
        };
        self.wagon_watch.axis_read = Some(reading);
        let (offset, se) = (x.change / x.s[axis], (x.change_se / x.s[axis]).abs());
        let at = self.wagon_watch.last_at.unwrap_or(x.at);
        let named = self.name_departure(at, &x, axis, None, offset, se, &mut findings);
        SweepOutcome {
            findings,
            slip_at_s: named.as_ref().and_then(|n| n.at_s),
            withdrawn_steps_s: named.map(|n| n.withdrawn_steps_s).unwrap_or_default(),
            ..SweepOutcome::default()
        }
    }

    /// One answered question: its reading joins the segment while no CUSUM run is under way;
    /// a crossing waits for the sweeps to attribute it (`attribute_departure`).
    fn judge_wagon_reading(&mut self, p: &WagonPair, q: &Question, d: f64) {
        let s = self.wagon_pair_sensitivity(p);
        let min_deg = MIN_OFFSET_TOLERANCES * self.spec.joint_tolerance_deg;
        let (k, clip) = (self.spec.cusum_k, self.spec.clip);
        let h = cusum_threshold(k, self.spec.false_alarm_runs * QUESTIONS_PER_RUN);
        let latched = self.latched.contains(&Latch::Wagon);
        let w = &mut self.wagon_watch;
        w.readings += 1;
        let Some((mean, sd)) = w.reference(p.var) else {
            w.segment.values.push(d);
            w.asked_after.push(q.at.last_idx);
            return;
        };
        w.asked_after.push(q.at.last_idx);
        let e = d - mean;
        w.last_e = Some(e);
        w.end_pose_check(PoseCheck::Read {
            z: e / sd,
            wagon_deg: e / s[0],
        });
        let z = (e / sd).clamp(-clip, clip);
        w.last_z = z;
        w.cusum.add(z, k, e / s[0], sd / s[0], q.at.last_idx);
        let (stat, run) = if w.cusum.up >= w.cusum.down {
            (w.cusum.up, w.cusum.up_run)
        } else {
            (w.cusum.down, w.cusum.down_run)
        };
        let (offset, se) = run.mean_and_se();
        let departs =
            stat > h && run.n >= 2 && offset.abs() >= min_deg && !latched && w.departed.is_none();
        w.segment.record(d, stat > 0.0, departs);
        if departs {
            {
                // the first capture after the question before the run's first
                let since_idx = w
                    .asked_after
                    .iter()
                    .copied()
                    .filter(|&i| i < run.start)
                    .max()
                    .unwrap_or(p.chosen_idx)
                    + 1;
                w.departed = Some(Departed {
                    at: q.at,
                    change: offset * s[0],
                    change_se: se * s[0],
                    readings: run.n,
                    statistic: stat,
                    threshold: h,
                    since_idx,
                    run_start: run.start,
                    s,
                    sweeps: 0,
                    axis_asked: false,
                });
            }
        }
    }

    /// A regular capture was checked: a question not answered within
    /// `RECAPTURE_WAIT_CAPTURES` is dropped (asked again at the next cadence).
    pub(super) fn wagon_watch_wait(&mut self) {
        if self.wagon_watch.approach.as_mut().is_some_and(|a| a.wait()) {
            // the departure goes to the sweeps' attribution without it
            self.wagon_watch.approach = None;
        }
        if self.wagon_watch.axis.as_mut().is_some_and(|a| a.wait()) {
            self.wagon_watch.axis = None;
        }
        if let Some(q) = self.wagon_watch.question.as_mut().filter(|q| q.asked) {
            q.waited += 1;
            if q.waited >= recapture::RECAPTURE_WAIT_CAPTURES {
                self.wagon_watch.question = None;
                self.wagon_watch.end_pose_check(PoseCheck::Unanswered);
            }
        }
    }

    /// Whether the pair can tell now whether the camera's pose moved: the watch is on, its pair
    /// chosen and its readings in control enough to judge one against.
    pub(crate) fn can_check_pose(&self) -> bool {
        self.spec.wagon_watch_sweeps > 0
            && self.recapture.is_some()
            && self.wagon_watch.pair.is_some()
            && self.wagon_watch.last_at.is_some()
            && self.wagon_watch.segment.len() >= MIN_SEGMENT
            && self.wagon_watch.approach.is_none()
    }

    /// Ask the pair out of turn (a question now, or the one under way): its reading comes back
    /// through `poll_pose_check`. False when it cannot (`can_check_pose`).
    pub(crate) fn request_pose_check(&mut self) -> bool {
        if !self.can_check_pose() {
            return false;
        }
        let w = &mut self.wagon_watch;
        let Some(at) = w.last_at else {
            return false;
        };
        if w.question.is_none() {
            w.question = Some(Question {
                asked: false,
                waited: 0,
                readings: [None; 2],
                at,
            });
        }
        w.pose_check = PoseCheckState::Waiting;
        true
    }

    /// The out-of-turn check's result, once (None while it waits or when none was asked).
    pub(crate) fn poll_pose_check(&mut self) -> Option<PoseCheck> {
        match self.wagon_watch.pose_check {
            PoseCheckState::Done(c) => {
                self.wagon_watch.pose_check = PoseCheckState::Idle;
                Some(c)
            }
            PoseCheckState::Idle | PoseCheckState::Waiting => None,
        }
    }

    /// ln Y per degree of wagon at plan entry `entry`'s commanded pose, from the smooth model
    /// (None before it fits, or when the entry's capture is not among the sweeps').
    pub(crate) fn wagon_sensitivity_of(&self, entry: usize) -> Option<f64> {
        let c = self.captures.iter().find(|c| c.entry == entry)?;
        let s = self.sensitivities(&c.cmd, Model::Smooth)?[2];
        s.is_finite().then_some(s)
    }

    /// The watch for the summary: none unless it is on (a probe-taking rig).
    pub(crate) fn wagon_watch_summary(&self) -> Option<WagonWatchSummary> {
        if self.spec.wagon_watch_sweeps == 0 || self.recapture.is_none() {
            return None;
        }
        let w = &self.wagon_watch;
        let Some(p) = w.pair.as_ref() else {
            return Some(WagonWatchSummary {
                entries: None,
                sensitivity_pct_per_deg: 0.0,
                joint_sensitivity_pct_per_deg: [0.0; 2],
                readings: 0,
                offset_deg: 0.0,
                se_deg: 0.0,
            });
        };
        let s = self.wagon_pair_sensitivity(p);
        Some(WagonWatchSummary {
            entries: Some(p.entries),
            sensitivity_pct_per_deg: 100.0 * s[0],
            joint_sensitivity_pct_per_deg: [100.0 * s[1], 100.0 * s[2]],
            readings: w.readings,
            offset_deg: w.last_e.map_or(0.0, |e| e / s[0]),
            se_deg: p.var.sqrt() / s[0],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A monitor whose watch has a pair and a question asked, waiting for both re-captures.
    fn waiting() -> SweepMonitor {
        let rig = Rig::new(Default::default()).unwrap();
        let mut m = SweepMonitor::new(SweepSpec::default(), rig, 81);
        m.set_recapture(Some(RecaptureNoise {
            capture_sd: 0.004 / std::f64::consts::SQRT_2,
            y_ref: None,
        }));
        m.wagon_watch.pair = Some(WagonPair {
            entries: [650, 210],
            cmd: [[0.0; 4]; 2],
            y0: [0.75, 0.63],
            lights: [8, 2],
            s: [0.05, -0.05, 0.0],
            var: 3.2e-5,
            chosen_idx: 728,
        });
        m.wagon_watch.question = Some(Question {
            asked: true,
            waited: 0,
            readings: [None; 2],
            at: SweepAt {
                light: 8,
                last_idx: 728,
                last_t: 5096.0,
                layer_mdeg: 30_000,
            },
        });
        m
    }

    #[test]
    fn a_dark_or_broken_re_capture_ends_the_question_without_a_reading() {
        for bad in [f64::NAN, 0.0, -1.0, f64::INFINITY] {
            let mut m = waiting();
            assert!(m.awaits_recapture(650) && m.awaits_recapture(210));
            assert!(m.handle_recapture(650, bad, 0.0).findings.is_empty());
            assert!(m.handle_recapture(210, 0.63, 0.0).findings.is_empty());
            assert!(m.wagon_watch.question.is_none(), "{bad}");
            assert_eq!(m.wagon_watch.readings, 0, "{bad}");
            assert!(m.wagon_watch.segment.values.is_empty(), "{bad}");
        }
        // a usable pair is a reading
        let mut m = waiting();
        m.handle_recapture(650, 0.75, 0.0);
        m.handle_recapture(210, 0.63, 0.0);
        assert_eq!(m.wagon_watch.readings, 1);
        // an entry the question does not wait for is not the watch's
        let m = waiting();
        assert!(!m.awaits_recapture(651));
    }

    #[test]
    fn an_unanswered_question_is_dropped_after_the_wait() {
        let mut m = waiting();
        for _ in 0..recapture::RECAPTURE_WAIT_CAPTURES {
            assert!(m.handle_regular_capture().findings.is_empty());
        }
        assert!(m.wagon_watch.question.is_none());
        assert!(!m.awaits_recapture(650));
    }

    /// A watch with its pair chosen, four readings in control and no question under way.
    fn in_control() -> SweepMonitor {
        let mut m = waiting();
        m.wagon_watch.question = None;
        m.wagon_watch.segment.values = vec![0.0, 0.002, -0.002, 0.001];
        m.wagon_watch.last_at = Some(SweepAt {
            light: 9,
            last_idx: 809,
            last_t: 5663.0,
            layer_mdeg: 30_000,
        });
        m
    }

    /// Answer the pair's question with the pair's ln change `d` (a rising, b steady).
    fn answer(m: &mut SweepMonitor, d: f64) {
        assert_eq!(m.recapture_wanted(), Some(vec![650, 210]));
        m.handle_recapture_asked();
        assert_eq!(m.poll_pose_check(), None, "waits for both");
        assert!(m
            .handle_recapture(650, 0.75 * d.exp(), 0.0)
            .findings
            .is_empty());
        assert!(m.handle_recapture(210, 0.63, 0.0).findings.is_empty());
    }

    #[test]
    fn a_pose_check_asks_the_pair_out_of_turn_and_reads_it_once() {
        // a degree of wagon at the pair's 5 %/°: far beyond its readings in control
        let mut m = in_control();
        assert!(m.can_check_pose() && m.request_pose_check());
        answer(&mut m, 0.05);
        let Some(PoseCheck::Read { z, wagon_deg }) = m.poll_pose_check() else {
            panic!("a reading")
        };
        assert!(
            z > 3.0 && (wagon_deg - 0.99).abs() < 0.02,
            "{z} {wagon_deg}"
        );
        assert_eq!(m.poll_pose_check(), None, "said once");
        // a steady pose reads within its scatter
        let mut m = in_control();
        assert!(m.request_pose_check());
        answer(&mut m, 0.0005);
        let Some(PoseCheck::Read { z, .. }) = m.poll_pose_check() else {
            panic!("a reading")
        };
        assert!(z.abs() < 1.0, "{z}");
        // a question the cadence put under way serves: no second one
        let mut m = in_control();
        m.wagon_watch.question = Some(Question {
            asked: false,
            waited: 0,
            readings: [None; 2],
            at: m.wagon_watch.last_at.unwrap(),
        });
        assert!(m.request_pose_check());
        answer(&mut m, 0.0);
        assert!(matches!(m.poll_pose_check(), Some(PoseCheck::Read { .. })));
        assert_eq!(m.recapture_wanted(), None);
    }

    #[test]
    fn no_pose_check_before_the_readings_in_control_nor_without_the_watch() {
        let mut m = in_control();
        m.wagon_watch.segment.values.truncate(MIN_SEGMENT - 1);
        assert!(!m.can_check_pose() && !m.request_pose_check());
        assert_eq!(m.recapture_wanted(), None);
        let mut m = in_control();
        m.set_recapture(None);
        assert!(!m.request_pose_check());
        let mut m = in_control();
        m.wagon_watch.pair = None;
        assert!(!m.request_pose_check());
        // nothing asked, nothing to poll
        assert_eq!(in_control().poll_pose_check(), None);
    }

    #[test]
    fn a_pose_check_with_no_usable_reading_is_unanswered() {
        // the question dropped after the wait
        let mut m = in_control();
        assert!(m.request_pose_check());
        m.recapture_wanted();
        m.handle_recapture_asked();
        for _ in 0..recapture::RECAPTURE_WAIT_CAPTURES {
            m.handle_regular_capture();
        }
        assert_eq!(m.poll_pose_check(), Some(PoseCheck::Unanswered));
        // a broken re-capture
        let mut m = in_control();
        assert!(m.request_pose_check());
        m.handle_recapture_asked();
        m.handle_recapture(650, f64::NAN, 0.0);
        m.handle_recapture(210, 0.63, 0.0);
        assert_eq!(m.poll_pose_check(), Some(PoseCheck::Unanswered));
        // the watch started again (a joint slip was named)
        let mut m = in_control();
        assert!(m.request_pose_check());
        m.wagon_watch.restart();
        assert_eq!(m.poll_pose_check(), Some(PoseCheck::Unanswered));
    }

    /// A watch whose pair just departed by −1.2° of wagon, with its question of approach about
    /// entry 650 (4 %/° of wagon) waiting to be asked.
    fn departed() -> SweepMonitor {
        let mut m = in_control();
        let at = m.wagon_watch.last_at.unwrap();
        m.wagon_watch.departed = Some(Departed {
            at,
            change: -0.06,
            change_se: 0.006,
            readings: 2,
            statistic: 5.1,
            threshold: 2.7,
            since_idx: 730,
            run_start: 809,
            s: [0.05, -0.05, 0.0],
            sweeps: 0,
            // the question of which axis moved is left out here (`axis` has its own tests)
            axis_asked: true,
        });
        m.wagon_watch.approach = Some(Approach::for_test([640, 650, 660, 650], 0.04, 3.2e-5));
        m
    }

    /// The rig takes the question's captures back to back, the pose reading `y_below` and
    /// `y_above`; the findings of the last.
    fn approach(m: &mut SweepMonitor, y_below: f64, y_above: f64) -> Vec<SweepFinding> {
        assert_eq!(m.recapture_wanted(), Some(vec![640, 650, 660, 650]));
        m.handle_recapture_asked();
        assert_eq!(m.recapture_wanted(), None, "nothing else while it waits");
        assert!(!m.can_check_pose());
        assert!(m.handle_recapture(640, 0.3, 1.0).findings.is_empty());
        assert!(m.handle_recapture(650, y_below, 1.0).findings.is_empty());
        assert!(m.handle_recapture(660, 0.3, 1.0).findings.is_empty());
        m.handle_recapture(650, y_above, -1.0).findings
    }

    #[test]
    fn a_departure_that_reads_differently_from_both_sides_names_the_wagons_lag() {
        let mut m = departed();
        // a 1° lag at 4 %/°: from below the pose sits 1° low, from above 1° high
        let findings = approach(&mut m, 0.75 * (-0.04f64).exp(), 0.75 * 0.04f64.exp());
        let [SweepFinding::WagonBacklash { at, backlash }] = findings.as_slice() else {
            panic!("the lag: {findings:?}")
        };
        assert_eq!(at.last_idx, 809);
        assert!((backlash.backlash_deg - 1.0).abs() < 1e-9, "{backlash:?}");
        let r = backlash.approach.as_ref().expect("its reading");
        assert_eq!(r.entries, [640, 650, 660, 650]);
        assert!((backlash.offset_deg + 1.2).abs() < 1e-9 && backlash.from_idx == 730);
        assert!(m.wagon_watch.departed.is_none() && m.wagon_watch.approach.is_none());
        assert!(m.latched.contains(&Latch::Wagon));
    }

    #[test]
    fn a_departure_that_reads_the_same_from_both_sides_goes_to_the_sweeps_with_the_reading() {
        let mut m = departed();
        let findings = approach(&mut m, 0.75 * 1.01, 0.75 * 1.01);
        assert!(findings.is_empty(), "{findings:?}");
        assert!(m.wagon_watch.departed.is_some() && m.wagon_watch.approach.is_none());
        let r = m
            .wagon_watch
            .approach_read
            .as_ref()
            .expect("kept for the offset");
        assert!(r.backlash_deg.abs() < 1e-9);
        assert!(!m.latched.contains(&Latch::Wagon));
    }

    #[test]
    fn an_unanswered_question_of_approach_leaves_the_departure_to_the_sweeps() {
        let mut m = departed();
        m.recapture_wanted();
        m.handle_recapture_asked();
        for _ in 0..recapture::RECAPTURE_WAIT_CAPTURES {
            assert!(m.handle_regular_capture().findings.is_empty());
        }
        assert!(m.wagon_watch.approach.is_none() && m.wagon_watch.departed.is_some());
        assert!(m.wagon_watch.approach_read.is_none());
        // the pair is asked again after it
        assert!(m.can_check_pose());
    }

    #[test]
    fn the_cost_is_under_one_percent_of_the_ubo_run_and_none_when_off() {
        let captures = 2 * wagon_watch_questions(81, 3);
        assert!(
            captures > 0 && (captures as f64) < 0.01 * 6561.0,
            "{captures}"
        );
        assert_eq!(wagon_watch_questions(81, 0), 0);
    }
}
