//! Confirming a slip the light sweeps name by re-capturing two earlier poses.
//!
//! The sweeps see a slip as a pattern across a sweep's cameras that follows a joint's
//! sensitivity. A stationary effect of the geometry that follows the whole pose (a lamp beam
//! aimed beside the arm's rotation centre, a holder's rim) makes patterns of the same form,
//! changing from light to light within a θi layer as a slip's would: the sweeps cannot tell the
//! two apart. A re-capture can. A pose taken again shows a stationary effect exactly as it was,
//! and a slip δ of joint j as s_j·δ.
//!
//! When a probe-taking rig's sweeps name a slip, the alarm waits for re-captures, asked for
//! back to back, of poses from one sweep completed well before the slip can have begun
//! (`RECAPTURE_BACK_SWEEPS` before the sweep the slip is placed in: a CUSUM run can start
//! sweeps after the slip, and a pose first taken after it would show nothing): the
//! poses whose luminance rises most with the joint and as many whose luminance falls most (the
//! smooth model's sensitivities, as the slip's size uses), the fewest per side of
//! `RECAPTURE_PER_SIDE` that show the named offset by `RECAPTURE_EXPECTED_Z` standard errors.
//! A pattern no such set can show (a named offset smaller than the re-captures can check) is
//! not named: the sweeps alone cannot tell it from the geometry's, so it is
//! `SlipUnverifiable` (an advisory with the offset the re-captures could check), and a slip
//! that grows is asked about when it crosses again. With
//! r = ln(Y/Y0), each re-capture against its original, d = mean r of the rising ones less mean
//! r of the falling ones is free of the lamp twice over: the originals were taken within one
//! sweep and the re-captures are adjacent. A slip moves d by (s̄_up − s̄_down)·δ; a stationary
//! pattern not at all. Each r's variance is that of two captures at its luminance: twice the
//! probes' design scatter at the lamp probe's luminance, scaled as shot noise (inversely with
//! the luminance) below it. The slip is named when d shows it, by `RECAPTURE_Z` standard errors
//! and half the joint tolerance, in the named direction; otherwise the finding is `SlipRefuted`
//! and the layer may raise again (at most `MAX_REFUTED_PER_LAYER` times).
//! 8 to 16 captures per question (0.12–0.24 % of the UBO run): a fault-free run pays only for
//! the patterns it shows.

use super::findings::{Recapture, RecaptureReading};
use super::model::Model;
use super::{JointCrossing, JointFit, Latch, SweepAt, SweepFinding, SweepMonitor, SweepOutcome};

/// A slip is confirmed when the re-captures' offset points the named way by this many standard
/// errors ...
pub(super) const RECAPTURE_Z: f64 = 3.0;
/// ... and by at least this fraction of the joint tolerance.
pub(super) const RECAPTURE_MIN_TOLERANCE: f64 = 0.5;
/// A set is asked for only when the named offset would move it by this many standard errors
/// (a confirmation at `RECAPTURE_Z` then has 98 % power); else the pattern is
/// `SlipUnverifiable`.
pub(super) const RECAPTURE_EXPECTED_Z: f64 = 5.0;
/// Re-captures on each side (rising and falling with the joint), the fewest tried first.
pub(super) const RECAPTURE_PER_SIDE: [usize; 3] = [4, 6, 8];
/// The re-captured poses come from a sweep at least this many sweeps before the one the slip is
/// placed in ...
pub(super) const RECAPTURE_BACK_SWEEPS: usize = 6;
/// Re-captured poses are at most this far from the normal on the camera side (cos θo): at
/// grazing view the captures are dim and their luminance turns fastest with a jitter.
const RECAPTURE_MIN_COS_THETA_O: f64 = 0.42; // θo ≤ 65°
/// ... and of this many sweeps from there back, the one whose poses show the slip best.
const RECAPTURE_SWEEPS: usize = 3;
/// The slip is named from the sweeps alone when its re-captures have not both been checked
/// this many regular captures after they were wanted.
pub(crate) const RECAPTURE_WAIT_CAPTURES: u64 = 30;
/// A θi layer whose sweeps' patterns were refuted this many times raises no more positioning
/// alarms from its patterns: they are the geometry's.
pub(super) const MAX_REFUTED_PER_LAYER: usize = 3;

/// The poses to re-capture, as plan entries (the rising ones first, `up` of them), with their
/// originals' luminance, their sensitivities to the named joint (ln Y per degree) and the
/// variance of their r; and for a lag of the wagon named before them, each pose's sensitivity
/// to the wagon and its original's capture and direction of approach.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RecaptureSet {
    entries: Vec<usize>,
    up: usize,
    y0: Vec<f64>,
    s: Vec<f64>,
    var: Vec<f64>,
    originals: Vec<Original>,
    /// The smooth model's sensitivities [joint 1, joint 2, wagon] at each pose (NaN: none).
    smooth: Vec<[f64; 3]>,
}

/// What a lag of the wagon did to a re-captured pose's original: its capture, the wagon's
/// direction of approach to it and the pose's ln Y per degree of wagon (NaN when the model
/// gives none: no correction then).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Original {
    idx: u64,
    wagon_dir: f64,
    s_wagon: f64,
}

/// The wagon's lag once named: its size (degrees, read through the smooth model's slopes, as
/// every correction with it is) and the first capture it can have affected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct NamedLag {
    pub backlash_deg: f64,
    pub from_idx: u64,
}

#[cfg(test)]
impl Original {
    /// An original taken at capture `idx`, approached from below, with no wagon slope known.
    pub(super) fn for_test(idx: u64) -> Self {
        Original {
            idx,
            wagon_dir: 1.0,
            s_wagon: f64::NAN,
        }
    }
}

impl NamedLag {
    /// What the lag moves ln Y of a re-capture approached from `dir` against its original
    /// `o`: each sits at −b·dir of wagon, the original only when taken once the lag began.
    fn effect(&self, o: &Original, dir: f64) -> f64 {
        if !o.s_wagon.is_finite() {
            return 0.0;
        }
        let before = if o.idx >= self.from_idx {
            o.wagon_dir
        } else {
            0.0
        };
        -self.backlash_deg * o.s_wagon * (dir - before)
    }
}

impl RecaptureSet {
    pub(super) fn entries(&self) -> &[usize] {
        &self.entries
    }

    /// The rising poses' count: the first `up` of `entries`.
    pub(super) fn up(&self) -> usize {
        self.up
    }

    /// The originals' luminance.
    pub(super) fn y0(&self) -> &[f64] {
        &self.y0
    }

    /// The smooth model's sensitivities [joint 1, joint 2, wagon] at each pose (NaN: none).
    pub(super) fn smooth(&self) -> &[[f64; 3]] {
        &self.smooth
    }

    /// The difference of the two sides' mean values of `v`.
    pub(super) fn contrast(&self, v: &[f64]) -> f64 {
        let (a, b) = v.split_at(self.up);
        a.iter().sum::<f64>() / a.len() as f64 - b.iter().sum::<f64>() / b.len() as f64
    }

    /// The contrast's sensitivity (ln Y per degree) and standard deviation (ln units).
    pub(super) fn sensitivity_and_sd(&self) -> (f64, f64) {
        let (a, b) = self.var.split_at(self.up);
        let na = a.len() as f64;
        let nb = b.len() as f64;
        let var = a.iter().sum::<f64>() / (na * na) + b.iter().sum::<f64>() / (nb * nb);
        (self.contrast(&self.s), var.sqrt())
    }
}

/// The re-captures' noise: the SD of one capture's ln Y at the reference luminance, the probes'
/// scatter (None: the reference not known yet, then taken at every luminance). A re-capture
/// read against its own original holds two captures' noise; readings that share their
/// originals (the wagon watch's) differ from one another by the re-captures' alone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RecaptureNoise {
    pub capture_sd: f64,
    pub y_ref: Option<f64>,
}

impl RecaptureNoise {
    /// The variance of one capture's ln Y at luminance `y`: shot noise below the reference.
    pub(super) fn capture_var(&self, y: f64) -> f64 {
        let scale = self.y_ref.map_or(1.0, |r| (r / y).max(1.0));
        self.capture_sd * self.capture_sd * scale
    }

    /// The variance of r = ln(Y/Y₀), a re-capture at luminance `y` against its original (or
    /// of two captures of one pose against each other).
    pub(super) fn var_at(&self, y: f64) -> f64 {
        2.0 * self.capture_var(y)
    }
}

/// What `hold_for_recapture` did with a slip the sweeps found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Hold {
    /// Held for its re-captures.
    Held,
    /// To be named now, from the sweeps alone.
    NotAsked,
    /// Not named: the best set of re-captures shows a degree of the joint by `z_per_deg`
    /// standard errors, too few for the named offset.
    Unverifiable { z_per_deg: f64 },
}

/// The set `recapture_set` chose.
enum SetChoice {
    /// No re-captures, or no earlier sweep with enough poses.
    None,
    /// The best set shows a degree by `z_per_deg` standard errors, too few.
    TooWeak {
        z_per_deg: f64,
    },
    Set(RecaptureSet),
}

/// A slip the sweeps named, waiting for its re-captures.
#[derive(Debug, Clone)]
pub(super) struct PendingSlip {
    at: SweepAt,
    crossing: JointCrossing,
    /// The sweep's fits of the other joints (for the alarm).
    fits: Vec<JointFit>,
    set: RecaptureSet,
    asked: bool,
    /// Regular captures checked since the slip was found.
    waited: u64,
    /// ln(Y / Y0) of each re-capture, once checked, with the wagon's direction of approach.
    readings: Vec<Option<(f64, f64)>>,
}

#[cfg(test)]
impl PendingSlip {
    /// A slip found at `at` waiting for re-captures of `entries`, the first half rising with
    /// the joint (originals of luminance 1).
    pub(super) fn for_test(at: SweepAt, crossing: JointCrossing, entries: &[usize]) -> Self {
        let n = entries.len();
        PendingSlip {
            at,
            crossing,
            fits: Vec::new(),
            set: RecaptureSet {
                entries: entries.to_vec(),
                up: n / 2,
                y0: vec![1.0; n],
                s: (0..n)
                    .map(|k| if k < n / 2 { 0.025 } else { -0.025 })
                    .collect(),
                var: vec![1e-4; n],
                originals: vec![
                    Original {
                        idx: 0,
                        wagon_dir: 1.0,
                        s_wagon: 0.04,
                    };
                    n
                ],
                smooth: vec![[f64::NAN; 3]; n],
            },
            asked: false,
            waited: 0,
            readings: vec![None; n],
        }
    }
}

impl SweepMonitor {
    /// Re-capture slips before naming them: `Some(noise)` on a rig that takes probes; `None`
    /// names them from the sweeps alone (watch mode, archives, a rig that refused probes). A
    /// slip already waiting keeps waiting and is named unconfirmed when its wait runs out.
    pub(crate) fn set_recapture(&mut self, noise: Option<RecaptureNoise>) {
        self.recapture = noise.filter(|n| {
            n.capture_sd.is_finite()
                && n.capture_sd > 0.0
                && n.y_ref.is_none_or(|y| y.is_finite() && y > 0.0)
        });
    }

    /// Plan entries that are not offered for re-capture (the lamp probe's and the sentinel's:
    /// a probe of them is theirs).
    pub(crate) fn reserve_entries(&mut self, entries: &[usize]) {
        self.reserved = entries.to_vec();
    }

    /// The entries to re-capture now, once per question: a waiting slip's first, then the
    /// wagon watch's pair (`wagon_watch`).
    pub(crate) fn recapture_wanted(&self) -> Option<Vec<usize>> {
        self.pending
            .as_ref()
            .filter(|p| !p.asked)
            .map(|p| p.set.entries.clone())
            .or_else(|| self.wagon_watch.wanted())
    }

    /// The re-captures `recapture_wanted` gave were asked for.
    pub(crate) fn handle_recapture_asked(&mut self) {
        match self.pending.as_mut().filter(|p| !p.asked) {
            Some(p) => p.asked = true,
            None => self.wagon_watch.asked(),
        }
    }

    /// Whether a probe of `entry` is a re-capture the pending slip or the wagon watch waits
    /// for.
    pub(crate) fn awaits_recapture(&self, entry: usize) -> bool {
        self.wagon_watch.awaits(entry)
            || self.pending.as_ref().is_some_and(|p| {
                p.asked
                    && p.set
                        .entries
                        .iter()
                        .zip(&p.readings)
                        .any(|(e, r)| *e == entry && r.is_none())
            })
    }

    /// A re-capture of `entry` was checked with luminance `y` (a dark or unusable one gives no
    /// reading: the wait runs out). Once both are in, the slip is named or refuted, or the
    /// wagon watch's reading judged.
    pub(crate) fn handle_recapture(
        &mut self,
        entry: usize,
        y: f64,
        wagon_dir: f64,
    ) -> SweepOutcome {
        if self.wagon_watch.awaits_approach(entry) {
            return self.handle_approach(entry, y, wagon_dir);
        }
        if self.wagon_watch.awaits_axis(entry) {
            return self.handle_axis(entry, y);
        }
        if self.wagon_watch.awaits(entry) {
            // its reading is judged here, named at a sweep's end (`wagon_watch`)
            self.handle_wagon_recapture(entry, y);
            return SweepOutcome::default();
        }
        let Some(p) = self.pending.as_mut() else {
            return SweepOutcome::default();
        };
        for k in 0..p.set.entries.len() {
            if p.set.entries[k] == entry && p.readings[k].is_none() {
                let r = (y / p.set.y0[k]).ln();
                if r.is_finite() {
                    p.readings[k] = Some((r, wagon_dir));
                }
                break;
            }
        }
        let Some(rd) = p
            .readings
            .iter()
            .copied()
            .collect::<Option<Vec<(f64, f64)>>>()
        else {
            return SweepOutcome::default();
        };
        let Some(p) = self.pending.take() else {
            return SweepOutcome::default();
        };
        // a lag of the wagon named before moves each re-capture by the way the wagon came to
        // it (and its original, when taken once the lag began): not the joint's
        let lag = self.named_lag;
        let r: Vec<f64> = rd
            .iter()
            .zip(&p.set.originals)
            .map(|(&(r, dir), o)| r - lag.map_or(0.0, |l| l.effect(o, dir)))
            .collect();
        let x = p.crossing;
        let d = p.set.contrast(&r);
        let (sensitivity, sd) = p.set.sensitivity_and_sd();
        let offset = d / sensitivity;
        let se = sd / sensitivity.abs();
        let reading = RecaptureReading {
            joint: x.joint + 1,
            entries: p.set.entries.clone(),
            change_pct: 100.0 * d,
            sensitivity_pct_per_deg: 100.0 * sensitivity,
            offset_deg: offset,
            se_deg: se,
        };
        let sign = x.mean.signum();
        let shown = sign * offset >= RECAPTURE_MIN_TOLERANCE * self.spec.joint_tolerance_deg
            && sign * offset >= RECAPTURE_Z * se;
        let mut findings = Vec::new();
        if shown {
            let named = self.name_slip(
                p.at,
                &x,
                &p.fits,
                Recapture::Confirmed(reading.clone()),
                &mut findings,
            );
            return SweepOutcome {
                findings,
                slip_at_s: named.at_s,
                withdrawn_steps_s: named.withdrawn_steps_s,
                ..SweepOutcome::default()
            };
        }
        let layer = p.at.layer_mdeg;
        let refuted = self.refuted.entry(layer).or_insert(0);
        *refuted += 1;
        if *refuted < MAX_REFUTED_PER_LAYER {
            self.latched.remove(&Latch::Joint { layer });
        }
        findings.push(SweepFinding::SlipRefuted {
            at: p.at,
            joint: x.joint + 1,
            offset_deg: x.mean,
            reading,
        });
        SweepOutcome {
            findings,
            ..SweepOutcome::default()
        }
    }

    /// A regular capture was checked: a slip whose re-captures have not come within
    /// `RECAPTURE_WAIT_CAPTURES` is named from the sweeps alone.
    pub(crate) fn handle_regular_capture(&mut self) -> SweepOutcome {
        self.wagon_watch_wait();
        let Some(p) = self.pending.as_mut() else {
            return SweepOutcome::default();
        };
        p.waited += 1;
        if p.waited < RECAPTURE_WAIT_CAPTURES {
            return SweepOutcome::default();
        }
        self.name_unanswered()
    }

    /// The run ended: a slip still waiting for its re-captures is named from the sweeps alone.
    pub(crate) fn handle_end(&mut self) -> SweepOutcome {
        self.name_unanswered()
    }

    fn name_unanswered(&mut self) -> SweepOutcome {
        let Some(p) = self.pending.take() else {
            return SweepOutcome::default();
        };
        let mut findings = Vec::new();
        let named = self.name_slip(
            p.at,
            &p.crossing,
            &p.fits,
            Recapture::Unanswered {
                entries: p.set.entries.clone(),
            },
            &mut findings,
        );
        SweepOutcome {
            findings,
            slip_at_s: named.at_s,
            withdrawn_steps_s: named.withdrawn_steps_s,
            ..SweepOutcome::default()
        }
    }

    /// Holds the slip `x` found at `at` for its re-captures, when the rig takes them and
    /// earlier poses can show it (`Hold::Held`; the layer is latched meanwhile, one question
    /// at a time). `Hold::NotAsked`: no re-captures (a rig without probes), or no earlier sweep
    /// to take them from; the slip is named now from the sweeps alone. `Hold::Unverifiable`:
    /// re-captures could be taken but none would show the named offset.
    pub(super) fn hold_for_recapture(
        &mut self,
        at: SweepAt,
        x: &JointCrossing,
        fits: &[JointFit],
    ) -> Hold {
        let set = match self.recapture_set(x) {
            SetChoice::None => return Hold::NotAsked,
            SetChoice::TooWeak { z_per_deg } => return Hold::Unverifiable { z_per_deg },
            SetChoice::Set(set) => set,
        };
        self.latched.insert(Latch::Joint {
            layer: at.layer_mdeg,
        });
        self.pending = Some(PendingSlip {
            at,
            crossing: *x,
            fits: fits.to_vec(),
            readings: vec![None; set.entries.len()],
            set,
            asked: false,
            waited: 0,
        });
        Hold::Held
    }

    /// Whether a slip waits for its re-captures.
    pub(super) fn recapture_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// The poses to re-capture for the slip `x`: of the `RECAPTURE_SWEEPS` sweeps completed
    /// `RECAPTURE_BACK_SWEEPS` or more before the one the slip is placed in, the one whose
    /// captures with the largest and as many with the smallest sensitivity to the joint (θo
    /// within `RECAPTURE_MIN_COS_THETA_O`, not a reserved entry) show a slip at the most
    /// standard errors, with the fewest per side of `RECAPTURE_PER_SIDE` that show the named
    /// offset by `RECAPTURE_EXPECTED_Z`. `SetChoice::None` without re-captures or an earlier
    /// sweep with enough poses; `TooWeak` when no set shows the named offset.
    fn recapture_set(&self, x: &JointCrossing) -> SetChoice {
        let Some(noise) = self.recapture else {
            return SetChoice::None;
        };
        let j = x.joint;
        let cut = self.slip_first_idx(x.since);
        let candidates = self.set_candidates(cut, RECAPTURE_BACK_SWEEPS, |smooth, interpolant| {
            smooth.or(interpolant).map(|s| s[j])
        });
        let mut strongest: Option<f64> = None;
        for per_side in RECAPTURE_PER_SIDE {
            let Some((z, set)) = best_set(&candidates, per_side, &noise) else {
                continue;
            };
            if z * x.mean.abs() >= RECAPTURE_EXPECTED_Z {
                return SetChoice::Set(set);
            }
            strongest = Some(strongest.map_or(z, |s: f64| s.max(z)));
        }
        match strongest {
            Some(z) => SetChoice::TooWeak { z_per_deg: z },
            None => SetChoice::None,
        }
    }
}

/// A pose a set of re-captures can be chosen from: the value that orders the set (ln Y per unit
/// of what the set is to show), its plan entry and original, and the smooth model's
/// sensitivities [joint 1, joint 2, wagon] at it (NaN where the model gives none).
#[derive(Debug, Clone, Copy)]
pub(super) struct Candidate {
    pub value: f64,
    pub entry: usize,
    pub y0: f64,
    pub original: Original,
    pub smooth: [f64; 3],
}

/// Of the sweeps' candidate poses (each sweep's sorted by value, largest first), the set of
/// `per_side` largest and as many smallest that shows the value's contrast at the most standard
/// errors of the noise, with that number. None when no sweep has enough poses.
pub(super) fn best_set(
    candidates: &[Vec<Candidate>],
    per_side: usize,
    noise: &RecaptureNoise,
) -> Option<(f64, RecaptureSet)> {
    let mut best: Option<(f64, RecaptureSet)> = None;
    for poses in candidates.iter().filter(|p| p.len() >= 2 * per_side) {
        let chosen: Vec<&Candidate> = poses[..per_side]
            .iter()
            .chain(&poses[poses.len() - per_side..])
            .collect();
        let set = RecaptureSet {
            entries: chosen.iter().map(|c| c.entry).collect(),
            up: per_side,
            y0: chosen.iter().map(|c| c.y0).collect(),
            s: chosen.iter().map(|c| c.value).collect(),
            var: chosen.iter().map(|c| noise.var_at(c.y0)).collect(),
            originals: chosen.iter().map(|c| c.original).collect(),
            smooth: chosen.iter().map(|c| c.smooth).collect(),
        };
        let (sensitivity, sd) = set.sensitivity_and_sd();
        let z = sensitivity / sd;
        if sensitivity > 0.0 && z.is_finite() && best.as_ref().is_none_or(|b| z > b.0) {
            best = Some((z, set));
        }
    }
    best
}

impl SweepMonitor {
    /// The candidate poses of the `RECAPTURE_SWEEPS` sweeps completed before capture `cut`,
    /// from the `back`th last on (1: the last), each sweep's sorted by `value` (of the smooth
    /// model's sensitivities and the interpolant's; None leaves the pose out), largest first:
    /// θo within `RECAPTURE_MIN_COS_THETA_O`, not a reserved entry nor one of the wagon watch's.
    pub(super) fn set_candidates(
        &self,
        cut: u64,
        back: usize,
        value: impl Fn(Option<[f64; 3]>, Option<[f64; 3]>) -> Option<f64>,
    ) -> Vec<Vec<Candidate>> {
        let mut spans: Vec<_> = self
            .sweep_starts
            .iter()
            .filter(|s| s.last_idx < cut)
            .collect();
        spans.sort_by_key(|s| std::cmp::Reverse(s.last_idx));
        spans
            .into_iter()
            .skip(back.saturating_sub(1))
            .take(RECAPTURE_SWEEPS)
            .map(|span| {
                let mut poses: Vec<Candidate> = self
                    .captures
                    .iter()
                    .filter(|c| {
                        c.light == span.light
                            && c.omega_o.z >= RECAPTURE_MIN_COS_THETA_O
                            && !self.reserved.contains(&c.entry)
                            && !self.wagon_watch.holds(c.entry)
                    })
                    .filter_map(|c| {
                        let smooth = self.sensitivities(&c.cmd, Model::Smooth);
                        let interpolant = || self.sensitivities(&c.cmd, Model::Interpolant);
                        let value = value(smooth, smooth.is_none().then(interpolant).flatten())
                            .filter(|v| v.is_finite())?;
                        Some(Candidate {
                            value,
                            entry: c.entry,
                            y0: c.y,
                            original: Original {
                                idx: c.idx,
                                wagon_dir: c.wagon_dir,
                                s_wagon: smooth.map_or(f64::NAN, |s| s[2]),
                            },
                            smooth: smooth.unwrap_or([f64::NAN; 3]),
                        })
                    })
                    .collect();
                poses.sort_by(|a, b| b.value.total_cmp(&a.value).then(a.entry.cmp(&b.entry)));
                poses
            })
            .collect()
    }
}
