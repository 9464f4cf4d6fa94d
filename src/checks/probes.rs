//! The drift probes on the checking side, with one owner for everything a probe is: the lamp
//! probe's pose (configured, or chosen from the captures checked), the probes' gain and colour
//! fits, and the joint-3 sentinel (its pose, chosen from the pole light's sweep, and its slip
//! test against the lamp probe of its round). The engine owns only when a round is asked for.
//!
//! The poses are chosen from the captures checked, never from the link, so a replay or a resume
//! makes the same choice.

use super::alarm::{Affects, Alarm, AlarmCode, AlarmKind, Handling, Severity};
use super::drift::{drift_alarm, ColourDriftSpec, ColourStage};
use super::evidence::{self, Evidence, Source};
use super::{CaptureInput, CheckOutput, Ledger, Measured};
use crate::detect::drift::DriftEstimate;
use crate::detect::drift::DriftEvent;
use crate::detect::probes::{choose_probe_pose, PoseSample, ProbeDrift, ProbePose, ProbeSpec};
use crate::detect::sentinel::{
    choose_sentinel, Joint3Sentinel, RingSample, SentinelPose, SentinelSummary,
};
use crate::detect::sweeps::PoseCheck;
use crate::measure::kinematics::{Incidence, Rig};
use crate::measure::plan::SamplingPlan;

/// The most captures a sentinel probe may follow its round's lamp probe by (see
/// `ProbeStage::sentinel_probe`).
const SENTINEL_ROUND_CAPTURES: u64 = 3;

/// A pose check's reading this many standard deviations from the pair's readings in control
/// says the camera's pose moved: a steady pose reaches it about 3 times in 1,000.
pub(crate) const POSE_MOVED_Z: f64 = 3.0;
/// A held step waits at most this many regular captures for its pose check, then is raised.
const HOLD_MAX_CAPTURES: u64 = 2 * crate::detect::sweeps::RECAPTURE_WAIT_CAPTURES;

/// A lamp probe's step held until the wagon pair says whether the camera's pose moved with it:
/// the wagon moves the camera along the arc, and a lamp probe pose whose luminance turns with the
/// view cannot tell a degree of wagon from a lamp step of its size.
#[derive(Debug, Clone)]
struct HeldStep {
    alarm: Alarm,
    direction: i8,
    statistic: f64,
    threshold: f64,
    probe_idx: u64,
    /// The probe pose's ln Y per degree of wagon, when the sweeps' model gives one.
    sensitivity: Option<f64>,
    waited: u64,
}

/// What choosing the probes' poses after a regular capture gave, in order: a pose chosen, or
/// the alarm that none qualifies (said once).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum ProbeSetup {
    ProbePose(ProbePose),
    SentinelPose(SentinelPose),
    Alarm(Box<Alarm>),
}

/// The joint-3 sentinel's test settings, from `[probes]`.
#[derive(Debug, Clone, Copy)]
struct SentinelSettings {
    step_sigmas: f64,
    min_deg: f64,
    min_readings: usize,
    /// ln units.
    sd_floor: f64,
}

/// The joint-3 sentinel: whether the session wants one, the one chosen, and whether none can
/// be.
#[derive(Debug, Clone, Default)]
struct SentinelWatch {
    /// Anisotropic samples with probes and the sentinel on.
    settings: Option<SentinelSettings>,
    chosen: Option<Joint3Sentinel>,
    /// The pole light's sweep was complete and no pose qualified (or the plan has no pole).
    unavailable: bool,
    /// Whether that was said (once).
    said: bool,
}

/// Everything the probes are on the checking side.
pub(super) struct ProbeStage {
    /// `[probes] every`: a round every this many regular captures (0: no probes).
    every: u64,
    drift: ProbeDrift,
    /// The lamp's colour from the probes (probes enabled).
    colour: Option<ColourStage>,
    /// The lamp probe's entry, configured or chosen; None until chosen.
    entry: Option<usize>,
    /// The pose chosen for the lamp probe (no entry configured).
    pose: Option<ProbePose>,
    /// The last usable lamp probe checked: a step the next probe finds began after it.
    last_probe_idx: Option<u64>,
    /// The lamp probe just checked, usable: its index and ln luminance ratio to its original
    /// capture. Cleared by any other probe, taken by the sentinel probe after it.
    last_lamp_probe: Option<(u64, f64)>,
    sentinel: SentinelWatch,
    /// Regular captures checked: the poses are chosen at each multiple of a light sweep.
    regular_checked: u64,
    /// A step waiting for a check of the camera's pose.
    held: Option<HeldStep>,
}

impl ProbeStage {
    pub(super) fn new(isotropic: bool, probes: ProbeSpec, colour: &ColourDriftSpec) -> Self {
        let enabled = probes.cadence() > 0;
        ProbeStage {
            every: probes.cadence(),
            colour: enabled
                .then(|| {
                    ColourStage::probes(
                        colour,
                        probes.min_probes,
                        probes.design_scatter_pct / 100.0,
                    )
                })
                .flatten(),
            entry: None,
            pose: None,
            last_probe_idx: None,
            last_lamp_probe: None,
            sentinel: SentinelWatch {
                settings: (!isotropic && enabled && probes.sentinel).then_some(SentinelSettings {
                    step_sigmas: probes.step_sigmas,
                    min_deg: probes.sentinel_min_deg,
                    min_readings: probes.min_probes,
                    // the scatter of the difference of two probes at the design scatter
                    sd_floor: std::f64::consts::SQRT_2 * probes.design_scatter_pct / 100.0,
                }),
                ..SentinelWatch::default()
            },
            drift: ProbeDrift::new(probes),
            regular_checked: 0,
            held: None,
        }
    }

    pub(super) fn enabled(&self) -> bool {
        self.every > 0
    }

    /// No more probes: the controller refused them. What they measured stays for the summary.
    pub(super) fn withdraw(&mut self) {
        self.every = 0;
    }

    /// `[probes] every` (0: no probes).
    pub(super) fn every(&self) -> u64 {
        self.every
    }

    /// The lamp probe's entry, when the configuration names one.
    pub(super) fn set_entry(&mut self, entry: Option<usize>) {
        self.entry = entry;
    }

    /// The entries of a probe round: the lamp probe's, then the sentinel's (its probe follows
    /// the lamp's, whose gain cancels between the two). None until the lamp probe's is known.
    pub(super) fn round(&self) -> Option<(usize, Option<usize>)> {
        let lamp = self.entry?;
        Some((lamp, self.sentinel.chosen.as_ref().map(|s| s.pose().entry)))
    }

    /// The pose chosen for the lamp probe.
    pub(super) fn pose(&self) -> Option<ProbePose> {
        self.pose
    }

    /// Whether a probe capture is the sentinel's (any other probe is the lamp's); a lamp probe
    /// ends the round of the one before it.
    pub(super) fn route(&mut self, input: &CaptureInput) -> bool {
        let sentinel = input.probe
            && self.sentinel.chosen.as_ref().map(|s| s.pose().entry) == Some(input.entry);
        if input.probe && !sentinel {
            self.last_lamp_probe = None;
        }
        sentinel
    }

    /// A lamp probe re-captures its entry's pose: its luminance against the entry's original
    /// is the gain change. With `hold` (a check of the camera's pose can be asked for; the
    /// probe pose's wagon sensitivity beside it), a step is held for it rather than raised;
    /// returns whether one was.
    pub(super) fn lamp_probe(
        &mut self,
        ledger: &Ledger,
        input: &CaptureInput,
        m: &Measured,
        hold: Option<Option<f64>>,
        out: &mut CheckOutput,
    ) -> bool {
        let mut held = false;
        if m.checked.dark {
            return held;
        }
        let Some(orig) = ledger.get(input.entry) else {
            return held;
        };
        let at = (Some(input.idx), Some(input.t));
        let (t0, y0) = (orig.t, orig.xyz[1]);
        if y0 > 0.0 && m.checked.xyz[1] > 0.0 {
            self.last_lamp_probe = Some((input.idx, (m.checked.xyz[1] / y0).ln()));
        }
        for ev in self.drift.add(
            input.idx,
            t0 / 3600.0,
            y0,
            input.t / 3600.0,
            m.checked.xyz[1],
        ) {
            // a step happened after the last probe before this one
            let since = self.last_probe_idx.map(|i| i + 1);
            let alarm = drift_alarm(ev, Source::Probes, at, since);
            match (ev, hold) {
                (
                    DriftEvent::Step {
                        direction,
                        statistic,
                        threshold,
                        ..
                    },
                    Some(sensitivity),
                ) if self.held.is_none() => {
                    self.held = Some(HeldStep {
                        alarm,
                        direction,
                        statistic,
                        threshold,
                        probe_idx: input.idx,
                        sensitivity,
                        waited: 0,
                    });
                    held = true;
                }
                _ => out.alarms.push(alarm),
            }
        }
        if let Some(colour) = self.colour.as_mut() {
            colour.observe(
                (0, 0),
                (t0 / 3600.0, orig.xyz),
                (input.t / 3600.0, m.checked.xyz),
                at,
                &mut out.alarms,
            );
        }
        self.last_probe_idx = Some(input.idx);
        held
    }

    /// Whether a step waits for a check of the pose.
    pub(super) fn holds_step(&self) -> bool {
        self.held.is_some()
    }

    /// The pose check a held step waited for: a reading `POSE_MOVED_Z` from the pair's readings
    /// in control, the way the probe pose's wagon sensitivity makes the step's sign (any way
    /// when the model gives none), explains the step, which is said as `probe-moved-with-pose`
    /// (info); anything else raises the step as it was found.
    pub(super) fn resolve_held_step(&mut self, check: PoseCheck, out: &mut CheckOutput) {
        let Some(h) = self.held.take() else {
            return;
        };
        let PoseCheck::Read { z, wagon_deg } = check else {
            out.alarms.push(h.alarm);
            return;
        };
        let sign_agrees = h
            .sensitivity
            .is_none_or(|s| s * wagon_deg * f64::from(h.direction) > 0.0);
        if !(z.abs() >= POSE_MOVED_Z && sign_agrees) {
            out.alarms.push(h.alarm);
            return;
        }
        out.alarms.push(
            Alarm::new(
                AlarmKind::Drift,
                Severity::Info,
                AlarmCode::ProbeMovedWithPose,
                format!(
                    "the lamp probe at capture {} went {} from its trend by {:.1} standard deviations (a step's threshold is {}), while the camera's pose moved: the wagon pair, re-captured right after it and blind to the lamp's gain, read {:+.2}° of wagon, {:.1} standard deviations from its readings in control; not raised as a lamp step (the positioning checks name the axis), and the probes' trend starts again at this probe",
                    h.probe_idx,
                    if h.direction > 0 { "up" } else { "down" },
                    h.statistic,
                    h.threshold,
                    wagon_deg,
                    z
                ),
            )
            .at(h.alarm.idx, h.alarm.t)
            .with(Evidence::ProbePoseMoved(evidence::ProbePoseMoved {
                direction: h.direction,
                statistic: h.statistic,
                threshold: h.threshold,
                probe_idx: h.probe_idx,
                pose_z: z,
                wagon_deg,
                probe_sensitivity_pct_per_deg: h.sensitivity.map(|s| 100.0 * s),
            })),
        );
    }

    /// A regular capture was checked while a step is held: past `HOLD_MAX_CAPTURES` (the pair
    /// was never asked: the link was down) it is raised.
    pub(super) fn held_step_wait(&mut self, out: &mut CheckOutput) {
        let Some(h) = self.held.as_mut() else {
            return;
        };
        h.waited += 1;
        if h.waited >= HOLD_MAX_CAPTURES {
            self.release_held_step(out);
        }
    }

    /// A held step is raised as found (the run ended, or no check of the pose could be asked).
    pub(super) fn release_held_step(&mut self, out: &mut CheckOutput) {
        if let Some(h) = self.held.take() {
            out.alarms.push(h.alarm);
        }
    }

    /// A sentinel probe: its luminance ratio against the lamp probe of its round is joint 3's
    /// turn (`detect::sentinel`). The round's lamp probe is the last probe before it, at most
    /// `SENTINEL_ROUND_CAPTURES` captures earlier: the round is two PROBE commands, and a
    /// controller may read the second one a capture or two after taking the first, while the
    /// lamp's gain does not move measurably in those seconds. Left out without such a lamp
    /// probe (the lamp could not be divided out), and when it is dark.
    pub(super) fn sentinel_probe(
        &mut self,
        ledger: &Ledger,
        input: &CaptureInput,
        m: &Measured,
        out: &mut CheckOutput,
    ) {
        let lamp = self.last_lamp_probe.take();
        let (Some(orig), Some(sentinel)) = (ledger.get(input.entry), self.sentinel.chosen.as_mut())
        else {
            return;
        };
        let Some((lamp_idx, lamp_ln)) = lamp else {
            return;
        };
        if input.idx <= lamp_idx
            || input.idx - lamp_idx > SENTINEL_ROUND_CAPTURES
            || m.checked.dark
            || !(orig.xyz[1] > 0.0 && m.checked.xyz[1] > 0.0)
        {
            return;
        }
        let d = (m.checked.xyz[1] / orig.xyz[1]).ln() - lamp_ln;
        let pose = sentinel.pose();
        if let Some(slip) = sentinel.add(input.idx, d) {
            out.alarms.push(
                Alarm::new(
                    AlarmKind::Positioning,
                    Severity::Warning,
                    AlarmCode::JointOffsetSuspected,
                    format!(
                        "joint 3 looks turned by about {:+.2}° (the sample's rotation about its normal; a tilt or a shift of the sample in its holder moves it too): the sentinel probe (entry {}, θo {:.0}°, {:+.2} %/° of joint 3) moved {:+.2} % against the lamp probe, {:.1} standard deviations of its earlier readings (threshold {}), while the encoders agree with the commands",
                        slip.offset_deg,
                        pose.entry,
                        pose.theta_o_deg,
                        pose.sensitivity_pct_per_deg,
                        slip.offset_deg * pose.sensitivity_pct_per_deg,
                        slip.statistic,
                        slip.threshold
                    ),
                )
                .at(Some(input.idx), Some(input.t))
                .with(Evidence::Joint3Slip(evidence::Joint3Slip {
                    joint: 3,
                    offset_deg: slip.offset_deg,
                    source: Source::SentinelProbes,
                    since_idx: slip.since_idx,
                    statistic: slip.statistic,
                    threshold: slip.threshold,
                    entry: pose.entry,
                    sensitivity_pct_per_deg: pose.sensitivity_pct_per_deg,
                }))
                .advise(
                    &format!("Pause the run; check the sample clamp and arm joint 3 (re-home the joint if it slipped, re-seat the sample if it turned in its holder), then resume; every capture since {} is on the retake list.", slip.since_idx),
                    Some(Affects::Since { from_idx: slip.since_idx, handling: Handling::Retake }),
                ),
            );
        }
    }

    /// After a regular capture is checked: the lamp probe's pose and the joint-3 sentinel are
    /// chosen once a light sweep's worth of captures is checked, and tried again after each
    /// further sweep's worth while none qualifies; the sentinel once the lamp probe's pose is
    /// known (it is not offered as the sentinel). That none qualifies is said once each.
    pub(super) fn after_regular_capture(
        &mut self,
        ledger: &Ledger,
        plan: &SamplingPlan,
        rig: &Rig,
        (idx, t): (u64, f64),
    ) -> Vec<ProbeSetup> {
        self.regular_checked += 1;
        let mut setup = Vec::new();
        let sweep = plan.direction_count().max(1) as u64;
        if !self.enabled() || !self.regular_checked.is_multiple_of(sweep) {
            return setup;
        }
        if self.entry.is_none() {
            match choose_probe_pose(&pose_samples(ledger, plan)) {
                Some(pose) => {
                    self.entry = Some(pose.entry);
                    self.pose = Some(pose);
                    setup.push(ProbeSetup::ProbePose(pose));
                }
                None if self.regular_checked == sweep => {
                    setup.push(ProbeSetup::Alarm(Box::new(
                        Alarm::new(
                            AlarmKind::Drift,
                            Severity::Warning,
                            AlarmCode::ProbePoseUnavailable,
                            "no checked capture qualifies as the drift probes' pose (off grazing, off the mirror direction, not dark, with neighbours); no probe is asked for until one does: set [probes] entry to choose one".into(),
                        )
                        .at(Some(idx), Some(t))
                        .advise(
                            "Set [probes] entry to a bright plan entry off grazing and off the mirror direction and restart the daemon (the session resumes); until then nothing watches the lamp through probes.",
                            None,
                        ),
                    )));
                }
                None => {}
            }
        }
        let Some(lamp) = self.entry else {
            return setup;
        };
        if self.sentinel.chosen.is_some() || self.sentinel.settings.is_none() {
            return setup;
        }
        match self.choose_sentinel(ledger, plan, rig, lamp) {
            Some(pose) => setup.push(ProbeSetup::SentinelPose(pose)),
            None if self.sentinel.unavailable && !self.sentinel.said => {
                self.sentinel.said = true;
                setup.push(ProbeSetup::Alarm(Box::new(
                    Alarm::new(
                        AlarmKind::Positioning,
                        Severity::Info,
                        AlarmCode::Joint3SentinelUnavailable,
                        "no capture of the pole light's sweep is sensitive enough to arm joint 3 to serve as its sentinel (off grazing, on a flank of the sample's anisotropy, at least 0.5 %/°); joint 3 stays unwatched until one is: the sample may be too close to isotropic for it to matter".into(),
                    )
                    .at(Some(idx), Some(t))
                    .advise(
                        "Nothing to do if the sample is nearly isotropic; otherwise check the sample's mount by eye when convenient.",
                        None,
                    ),
                )));
            }
            None => {}
        }
        setup
    }

    /// Chooses the joint-3 sentinel's pose (`detect::sentinel`) from the pole light's checked
    /// captures; `lamp_entry` (the lamp probe's pose) is not offered. None while the pole
    /// light's sweep is incomplete, and (marked unavailable) when it is complete and no capture
    /// qualifies, or the plan has no pole.
    fn choose_sentinel(
        &mut self,
        ledger: &Ledger,
        plan: &SamplingPlan,
        rig: &Rig,
        lamp_entry: usize,
    ) -> Option<SentinelPose> {
        let set = self.sentinel.settings?;
        let dirs = plan.directions();
        let Some(pole) = dirs
            .iter()
            .find(|d| d.theta_deg.abs() < 1e-6)
            .map(|d| d.index)
        else {
            self.sentinel.unavailable = true;
            return None;
        };
        if !ledger.light_complete(pole) {
            return None;
        }
        let ring_len = |theta: f64| {
            dirs.iter()
                .filter(|d| (d.theta_deg - theta).abs() < 1e-6)
                .count()
                .max(1)
        };
        let samples: Vec<RingSample> = (0..plan.capture_count())
            .filter_map(|e| {
                let pe = plan.entry(e).ok()?;
                if pe.light != pole || e == lamp_entry {
                    return None;
                }
                let c = ledger.get(e)?;
                if !c.exact_pose || c.dark || c.substitute {
                    return None;
                }
                let cam = dirs.get(pe.camera)?;
                Some(RingSample {
                    entry: e,
                    theta_o_deg: cam.theta_deg,
                    phi_o_deg: cam.phi_deg.rem_euclid(360.0),
                    ring_step_deg: 360.0 / ring_len(cam.theta_deg) as f64,
                    y: c.xyz[1],
                    dphi_dq3: dphi_o_dq3(
                        rig,
                        &Incidence {
                            omega_i: c.omega_i,
                            omega_o: c.omega_o,
                        },
                    )?,
                })
            })
            .collect();
        // a 1° turn must clear the slip test's own threshold at the design scatter
        let min_pct_per_deg = 100.0 * set.step_sigmas * set.sd_floor;
        let Some(pose) = choose_sentinel(&samples, min_pct_per_deg) else {
            self.sentinel.unavailable = true;
            return None;
        };
        self.sentinel.chosen = Some(Joint3Sentinel::new(
            pose,
            set.step_sigmas,
            set.min_deg,
            set.min_readings,
            set.sd_floor,
        ));
        Some(pose)
    }

    /// Whether the sentinel watches joint 3 (wanted, and not found unavailable).
    pub(super) fn watches_joint3(&self) -> bool {
        self.sentinel.settings.is_some() && !self.sentinel.unavailable
    }

    /// The sentinel's pose, readings and estimate so far.
    pub(super) fn sentinel(&self) -> Option<SentinelSummary> {
        self.sentinel.chosen.as_ref().map(|s| SentinelSummary {
            pose: s.pose(),
            readings: s.readings(),
            offset_deg: s.offset_deg(),
        })
    }

    /// The probes' fit of the gain.
    pub(super) fn drift(&self) -> &ProbeDrift {
        &self.drift
    }

    /// The gain drift estimate from the probes, once there are enough.
    pub(super) fn estimate(&self) -> Option<DriftEstimate> {
        self.drift.estimate()
    }

    /// The lamp's colour from the probes.
    pub(super) fn colour(&self) -> Option<&ColourStage> {
        self.colour.as_ref()
    }
}

/// The captures the lamp probe's pose is chosen from (`detect::probes`): usable captures at
/// their exact pose, neither dark nor occlusion substitutes.
fn pose_samples(ledger: &Ledger, plan: &SamplingPlan) -> Vec<PoseSample> {
    (0..plan.capture_count())
        .filter_map(|e| {
            let c = ledger.get(e)?;
            if !c.exact_pose || c.dark || c.substitute {
                return None;
            }
            let pe = plan.entry(e).ok()?;
            Some(PoseSample {
                entry: e,
                light: pe.light,
                camera: pe.camera,
                omega_i: c.omega_i,
                omega_o: c.omega_o,
                y: c.xyz[1],
            })
        })
        .collect()
}

/// ∂φo/∂q₃ at an incidence (degrees of camera azimuth per degree of joint 3), through the rig's
/// kinematics.
fn dphi_o_dq3(rig: &Rig, inc: &Incidence) -> Option<f64> {
    const H: f64 = 0.01;
    let pose = rig.inverse(inc).ok()?;
    let mut turned = pose;
    turned.joints_deg[2] += H;
    let a = rig.forward(&pose).ok()?.angles().phi_o_deg;
    let b = rig.forward(&turned).ok()?.angles().phi_o_deg;
    let d = ((b - a + 180.0).rem_euclid(360.0) - 180.0) / H;
    d.is_finite().then_some(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::probes::ProbeEvery;

    fn stage_holding(sensitivity: Option<f64>) -> ProbeStage {
        let mut st = ProbeStage::new(
            true,
            ProbeSpec {
                every: ProbeEvery::Captures(75),
                ..ProbeSpec::default()
            },
            &ColourDriftSpec::default(),
        );
        let ev = DriftEvent::Step {
            direction: -1,
            statistic: 6.8,
            threshold: 5.0,
            pairs_since_reset: 43,
        };
        st.held = Some(HeldStep {
            alarm: drift_alarm(ev, Source::Probes, (Some(3291), Some(23037.0)), Some(3216)),
            direction: -1,
            statistic: 6.8,
            threshold: 5.0,
            probe_idx: 3291,
            sensitivity,
            waited: 0,
        });
        st
    }

    fn resolved(sensitivity: Option<f64>, check: PoseCheck) -> Vec<Alarm> {
        let mut st = stage_holding(sensitivity);
        assert!(st.holds_step());
        let mut out = CheckOutput::default();
        st.resolve_held_step(check, &mut out);
        assert!(!st.holds_step());
        out.alarms
    }

    /// A probe 1.3 % down (its pose loses 1.3 %/° as the wagon rises) with the pair reading
    /// +1° of wagon at 5 SD is the pose's, said as info at the probe; anything else raises the
    /// step as found, at the probe.
    #[test]
    fn a_held_step_is_the_pose_s_only_when_the_pair_moved_the_way_that_explains_it() {
        let moved = PoseCheck::Read {
            z: 5.0,
            wagon_deg: 1.0,
        };
        for sensitivity in [Some(-0.013), None] {
            let a = resolved(sensitivity, moved);
            assert_eq!(a.len(), 1);
            assert_eq!(a[0].code, AlarmCode::ProbeMovedWithPose);
            assert_eq!(a[0].severity, Severity::Info);
            assert_eq!((a[0].idx, a[0].t), (Some(3291), Some(23037.0)));
            let Evidence::ProbePoseMoved(e) = &a[0].evidence else {
                panic!("{:?}", a[0].evidence)
            };
            assert_eq!((e.direction, e.probe_idx, e.pose_z), (-1, 3291, 5.0));
            assert_eq!(
                e.probe_sensitivity_pct_per_deg,
                sensitivity.map(|s| 100.0 * s)
            );
        }
        for (sensitivity, check) in [
            // the pair moved the other way
            (
                Some(-0.013),
                PoseCheck::Read {
                    z: -5.0,
                    wagon_deg: -1.0,
                },
            ),
            // the pair did not move
            (
                Some(-0.013),
                PoseCheck::Read {
                    z: 1.2,
                    wagon_deg: 0.2,
                },
            ),
            (
                None,
                PoseCheck::Read {
                    z: -2.9,
                    wagon_deg: -0.6,
                },
            ),
            (None, PoseCheck::Unanswered),
        ] {
            let a = resolved(sensitivity, check);
            assert_eq!(a.len(), 1, "{check:?}");
            assert_eq!(a[0].code, AlarmCode::GainStep, "{check:?}");
            assert_eq!((a[0].idx, a[0].severity), (Some(3291), Severity::Warning));
        }
    }

    #[test]
    fn a_held_step_is_raised_when_no_check_comes_and_at_the_end() {
        let mut st = stage_holding(None);
        let mut out = CheckOutput::default();
        for _ in 1..HOLD_MAX_CAPTURES {
            st.held_step_wait(&mut out);
        }
        assert!(out.alarms.is_empty() && st.holds_step());
        st.held_step_wait(&mut out);
        assert_eq!(out.alarms.len(), 1);
        assert_eq!(out.alarms[0].code, AlarmCode::GainStep);
        assert!(!st.holds_step());
        // the run's end raises it as found; nothing held, nothing raised
        let mut st = stage_holding(None);
        let mut out = CheckOutput::default();
        st.release_held_step(&mut out);
        st.release_held_step(&mut out);
        assert_eq!(out.alarms.len(), 1);
    }
}
