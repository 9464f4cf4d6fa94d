//! The per-capture checks of a session, incremental and in capture order. A small router
//! (`Checker`) hands each capture to one stage per concern and collects what they find:
//!
//! - `capture`: where it was taken (encoder pose against plan and commands) and whether it can
//!   be used (outcome, non-finite, clipped and dark pixels, runs of failures);
//! - `pairs`: Helmholtz reciprocity with the reciprocal partner, Table 2, outliers, and the
//!   occlusion substitutes' interpolated partners;
//! - `isotropy`: the capture against its isotropy class (isotropic samples);
//! - `drift`: the lamp's gain from repeated geometry (isotropic samples);
//! - the light sweeps (`detect::sweeps`, isotropic samples in a light-outer order) and the
//!   drift probes (`detect::probes`), which are stages of their own in the core.
//!
//! The router owns the ledger (the first usable capture of each plan entry, and which light
//! directions are complete), fills in the gain correction, relays a sweep's step to the drift
//! stage, and counts alarms, once, for everything. Pure: a `Checker` is a deterministic
//! function of the sequence of `CaptureInput`s it is given.

pub mod alarm;
mod capture;
pub mod catalogue;
mod drift;
pub(crate) mod evidence;
mod isotropy;
pub(crate) mod observability;
mod pairs;
mod probes;
pub(crate) mod records;
pub(crate) mod retakes;
mod sweeps;
#[cfg(test)]
mod tests;

pub use records::{
    CaptureInput, CaptureRecord, CaptureStatus, CheckCounts, GainCorrected, Interpolation,
    IsotropyRecord, Outcome, PairRecord, PairStatus, ProbeGainCurve, Table2,
};

use crate::checks::alarm::{Alarm, AlarmCode};
use crate::detect::drift::{mount_coordinates, DriftEstimate, MountPattern, StepEffect};
use crate::detect::probes::{ProbePose, ProbeSpec};
use crate::detect::sentinel::SentinelSummary;
use crate::detect::sweeps::{
    RecaptureNoise, SweepCapture, SweepMonitor, SweepRecord, SweepSpec, SweepSummary,
};
use crate::measure::colour::{RgbToXyz, White, Xyz};
use crate::measure::geometry::{azimuth_difference_deg, Vec3};
use crate::measure::kinematics::Rig;
use crate::measure::plan::{AcquisitionOrder, SamplingPlan};
use capture::{CaptureStage, Measured, Verdict};
use drift::DriftStage;
pub(crate) use drift::{ColourDriftEstimate, ColourDriftSpec};
use isotropy::IsotropyStage;
use pairs::PairStage;
pub(crate) use probes::ProbeSetup;
use probes::ProbeStage;
use serde::{Deserialize, Serialize};

/// Thresholds of the checks (`[checks]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CheckSpec {
    /// A pair is exact when each capture's ωi is within this of the partner's ωo (degrees).
    pub pair_tolerance_deg: f64,
    /// Measured (encoder) directions further than this from the plan raise a positioning alarm.
    pub pose_tolerance_deg: f64,
    /// |encoder − commanded| above this on any axis raises a positioning alarm (degrees).
    pub encoder_tolerance_deg: f64,
    /// A pair is an outlier when its ΔE00 exceeds median + k · 1.4826 · MAD of the pairs so far
    /// with the same two nominal θ …
    pub outlier_k: f64,
    /// … and this floor …
    pub outlier_floor_de2000: f64,
    /// … once this many exact pairs are in.
    pub outlier_min_pairs: usize,
    /// More non-finite pixels than this in a capture raise a capture-quality alarm.
    pub nonfinite_max: u64,
    /// A larger fraction of clipped pixels raises a capture-quality alarm.
    pub clipped_fraction_max: f64,
    /// A capture whose mean Y (configured XYZ scale) is at or below this is dark.
    pub dark_y: f64,
    /// This many failed captures in a row is critical.
    pub failures_critical: u32,
    /// Light-sweep checks: gain level shifts and joint offsets (isotropic samples).
    pub sweeps: SweepSpec,
    /// The lamp's colour drift (from isotropy classes and from the probes).
    pub colour_drift: ColourDriftSpec,
}

impl Default for CheckSpec {
    fn default() -> Self {
        CheckSpec {
            pair_tolerance_deg: 0.5,
            pose_tolerance_deg: 0.25,
            encoder_tolerance_deg: 0.1,
            outlier_k: 6.0,
            outlier_floor_de2000: 5.0,
            outlier_min_pairs: 30,
            nonfinite_max: 0,
            clipped_fraction_max: 0.001,
            dark_y: 0.5,
            failures_critical: 5,
            sweeps: SweepSpec::default(),
            colour_drift: ColourDriftSpec::default(),
        }
    }
}

/// The colour settings the checker needs.
#[derive(Debug, Clone)]
pub struct ColourSettings {
    pub to_xyz: RgbToXyz,
    pub rgb_scale: f64,
    pub white: White,
    pub min_cos: f64,
}

/// Everything the checker produced for one capture.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckOutput {
    pub capture: Option<CaptureRecord>,
    pub pairs: Vec<PairRecord>,
    pub isotropy: Vec<IsotropyRecord>,
    pub sweeps: Vec<SweepRecord>,
    pub alarms: Vec<Alarm>,
}

/// A usable capture as the stages keep it.
#[derive(Debug, Clone)]
struct Checked {
    idx: u64,
    t: f64,
    xyz: Xyz,
    theta_i_deg: f64,
    omega_i: Vec3,
    omega_o: Vec3,
    exact_pose: bool,
    /// Placed by the commanded pose (a steady encoder offset).
    by_command: bool,
    dark: bool,
    substitute: bool,
}

/// (θ light, θ camera, |Δφ|) in millidegrees: captures of one geometry see the same BRDF value.
type GeometryKey = (i64, i64, i64);

/// What every stage may read: the session's fixed settings.
struct Ctx<'a> {
    plan: &'a SamplingPlan,
    rig: &'a Rig,
    colour: &'a ColourSettings,
    spec: &'a CheckSpec,
}

impl Ctx<'_> {
    fn xyz_of(&self, rgb: [f64; 3]) -> Xyz {
        self.colour
            .to_xyz
            .convert_scaled(rgb, self.colour.rgb_scale)
    }

    fn geometry_key(&self, light: usize, camera: usize) -> GeometryKey {
        let dirs = self.plan.directions();
        let (l, c) = (dirs[light], dirs[camera]);
        let dphi = if l.theta_deg == 0.0 || c.theta_deg == 0.0 {
            0.0
        } else {
            azimuth_difference_deg(l.phi_deg, c.phi_deg)
        };
        (
            (l.theta_deg * 1000.0).round() as i64,
            (c.theta_deg * 1000.0).round() as i64,
            (dphi * 1000.0).round() as i64,
        )
    }
}

/// The first usable capture of each plan entry, and which entries and light directions have
/// been seen (any outcome): a light direction is complete when all its entries have.
struct Ledger {
    by_entry: Vec<Option<Checked>>,
    entry_seen: Vec<bool>,
    seen_per_light: Vec<usize>,
    directions: usize,
}

impl Ledger {
    fn new(plan: &SamplingPlan) -> Self {
        let n = plan.capture_count();
        Ledger {
            by_entry: vec![None; n],
            entry_seen: vec![false; n],
            seen_per_light: vec![0; plan.direction_count()],
            directions: plan.direction_count(),
        }
    }

    fn get(&self, entry: usize) -> Option<&Checked> {
        self.by_entry.get(entry).and_then(|c| c.as_ref())
    }

    /// Keep the first usable capture of an entry; false when the entry already had one.
    fn keep(&mut self, entry: usize, capture: Checked) -> bool {
        match self.by_entry.get_mut(entry) {
            Some(slot @ None) => {
                *slot = Some(capture);
                true
            }
            Some(Some(_)) => false,
            None => true,
        }
    }

    /// Note that an entry of `light` was seen; true when that completes the light direction.
    fn see(&mut self, entry: usize, light: usize) -> bool {
        match self.entry_seen.get_mut(entry) {
            Some(seen) if !*seen => {
                *seen = true;
                self.seen_per_light[light] += 1;
                self.seen_per_light[light] == self.directions
            }
            _ => false,
        }
    }

    fn light_complete(&self, light: usize) -> bool {
        self.seen_per_light[light] == self.directions
    }

    /// The captures of one light direction that can be interpolation nodes: usable, at their
    /// exact pose, not dark, not occlusion substitutes.
    fn light_nodes<'a>(
        &'a self,
        plan: &'a SamplingPlan,
        light: usize,
    ) -> impl Iterator<Item = &'a Checked> + 'a {
        (0..plan.directions().len())
            .filter_map(move |c| plan.index_of(light, c))
            .filter_map(|e| self.get(e))
            .filter(|c| c.exact_pose && !c.dark && !c.substitute)
    }

    /// Mean controller time of a light direction's node captures.
    fn light_mean_time(&self, plan: &SamplingPlan, light: usize) -> Option<f64> {
        let (sum, n) = self
            .light_nodes(plan, light)
            .fold((0.0, 0usize), |(s, n), c| (s + c.t, n + 1));
        (n > 0).then(|| sum / n as f64)
    }
}

pub struct Checker {
    plan: SamplingPlan,
    rig: Rig,
    colour: ColourSettings,
    spec: CheckSpec,
    ledger: Ledger,
    capture: CaptureStage,
    pairs: PairStage,
    /// Isotropic samples only.
    isotropy: Option<IsotropyStage>,
    /// Isotropic samples only.
    drift: Option<DriftStage>,
    /// Isotropic samples in a light-outer order only.
    sweeps: Option<SweepMonitor>,
    /// The drift probes and the joint-3 sentinel.
    probes: ProbeStage,
    /// The wagon's last commanded position and direction of motion (+1, −1; 0 before it
    /// first moved), over every capture (probes too: the wagon moves for them as well).
    wagon_last_cmd: Option<f64>,
    wagon_dir: f64,
    alarms: u64,
    /// The re-captures' noise at the design scatter (a probe-taking rig; None without).
    recapture: Option<RecaptureNoise>,
}

impl Checker {
    pub fn new(
        plan: SamplingPlan,
        rig: Rig,
        colour: ColourSettings,
        spec: CheckSpec,
        isotropic: bool,
        probes: ProbeSpec,
    ) -> Self {
        let light_outer = !matches!(plan.order(), AcquisitionOrder::CameraOuter);
        // a probe-taking rig re-captures earlier poses before a slip the sweeps name is
        // alarmed; each capture's noise is the probes' design scatter where the lamp probe's
        // luminance is (`light_seen` sets it)
        let recapture = (probes.cadence() > 0).then_some(RecaptureNoise {
            capture_sd: probes.design_scatter_pct / 100.0,
            y_ref: None,
        });
        let sweeps = (isotropic && spec.sweeps.enabled && light_outer).then(|| {
            let mut s = SweepMonitor::new(spec.sweeps.clone(), rig.clone(), plan.direction_count());
            s.set_recapture(recapture);
            s
        });
        let probes = ProbeStage::new(isotropic, probes, &spec.colour_drift);
        // with probes the lamp's rate is theirs to alarm (a re-capture of one pose sees no
        // stationary pattern of the geometry); the isotropy fit still estimates it
        let drift = isotropic.then(|| {
            let mut d = DriftStage::new(&spec.colour_drift);
            d.set_rate_alarms(!probes.enabled());
            d
        });
        Checker {
            ledger: Ledger::new(&plan),
            capture: CaptureStage::default(),
            pairs: PairStage::default(),
            isotropy: isotropic.then(IsotropyStage::default),
            drift,
            sweeps,
            probes,
            plan,
            rig,
            colour,
            spec,
            wagon_last_cmd: None,
            wagon_dir: 0.0,
            alarms: 0,
            recapture,
        }
    }

    /// Check one capture. Captures must come in index order.
    pub fn check(&mut self, input: &CaptureInput) -> CheckOutput {
        let mut out = CheckOutput::default();
        let ctx = Ctx {
            plan: &self.plan,
            rig: &self.rig,
            colour: &self.colour,
            spec: &self.spec,
        };
        // a probe a waiting slip asked for is its re-capture; a probe of the sentinel's pose is
        // the sentinel's; any other probe is the lamp's, and the sentinel compares only with
        // the lamp probe of its round (the last probe before it)
        let recapture = input.probe
            && self
                .sweeps
                .as_ref()
                .is_some_and(|s| s.awaits_recapture(input.entry));
        let sentinel = !recapture && self.probes.route(input);
        let w = input.cmd[3];
        if w.is_finite() {
            if let Some(last) = self.wagon_last_cmd.filter(|last| *last != w) {
                self.wagon_dir = (w - last).signum();
            }
            self.wagon_last_cmd = Some(w);
        }
        match self.capture.check(&ctx, input, &mut out.alarms) {
            Verdict::NotInPlan => {}
            Verdict::Unusable(mut rec) => {
                rec.sentinel = sentinel;
                out.capture = Some(*rec);
            }
            Verdict::Usable(mut rec, m) => {
                rec.sentinel = sentinel;
                rec.gain_corrected = gain_correction(
                    &self.probes,
                    self.capture.probes,
                    self.drift.as_ref(),
                    input.t / 3600.0,
                    m.checked.xyz,
                );
                if recapture {
                    if !m.checked.dark {
                        self.recaptured(input, m.checked.xyz[1], &mut out);
                    }
                } else if sentinel {
                    self.probes
                        .sentinel_probe(&self.ledger, input, &m, &mut out);
                } else if input.probe {
                    self.lamp_probe(input, &m, &mut out);
                } else {
                    self.regular(input, m, &mut out);
                }
                out.capture = Some(*rec);
            }
        }
        self.light_seen(input, &mut out);
        self.resolve_held_step(&mut out);
        // a waiting substitute is scored once its partner's light direction is complete
        if self.pairs.any_ready(&self.ledger) {
            self.resolve(
                |p, ledger| ledger.light_complete(p.light),
                input.t,
                &mut out,
            );
        }
        self.alarms += out.alarms.len() as u64;
        out
    }

    /// At the end of a session: the substitutes still waiting for their partner's light
    /// direction are scored against what was captured.
    pub(crate) fn finish(&mut self, t: f64) -> CheckOutput {
        let mut out = CheckOutput::default();
        self.resolve(|_, _| true, t, &mut out);
        // a slip still waiting for its re-captures is named from the sweeps alone
        if let Some(o) = self.sweeps.as_mut().map(|s| s.handle_end()) {
            self.apply_sweep_outcome(o, (None, Some(t)), &mut out);
        }
        // a step still waiting for a check of the pose is raised as found
        self.probes.release_held_step(&mut out);
        self.alarms += out.alarms.len() as u64;
        out
    }

    /// After a regular capture is checked (the engine calls this once for each, after
    /// `check`): the probes' poses chosen so far, and the alarms that none qualifies.
    pub(crate) fn after_regular_capture(&mut self, idx: u64, t: f64) -> Vec<ProbeSetup> {
        self.probes
            .after_regular_capture(&self.ledger, &self.plan, &self.rig, (idx, t))
    }

    /// A probe round every this many regular captures announced (`[probes] every`; 0: none).
    pub(crate) fn probe_every(&self) -> u64 {
        self.probes.every()
    }

    /// Whether the sample is checked as isotropic (its isotropy classes watch the lamp).
    pub(crate) fn watches_isotropy(&self) -> bool {
        self.isotropy.is_some()
    }

    /// The re-captures a slip the sweeps named waits for, once: the engine asks the rig for
    /// them back to back.
    pub(crate) fn recapture_wanted(&mut self) -> Option<Vec<usize>> {
        let sweeps = self.sweeps.as_mut()?;
        let entries = sweeps.recapture_wanted()?;
        sweeps.handle_recapture_asked();
        Some(entries)
    }

    /// The controller refused the probes: the lamp is watched without them from now on (the
    /// sweeps' level test is back on; no new sentinel or probe pose is chosen; slips are named
    /// from the sweeps alone, one still waiting once its wait runs out).
    pub(crate) fn withdraw_probes(&mut self) {
        self.probes.withdraw();
        self.recapture = None;
        if let Some(s) = self.sweeps.as_mut() {
            s.set_recapture(None);
        }
        if let Some(d) = self.drift.as_mut() {
            d.set_rate_alarms(true);
        }
    }

    /// The lamp probe's entry, when the configuration names one.
    pub(crate) fn set_probe_entry(&mut self, entry: Option<usize>) {
        self.probes.set_entry(entry);
    }

    /// The entries of a probe round (the lamp probe's, then the sentinel's); None until the
    /// lamp probe's is known.
    pub(crate) fn probe_round(&self) -> Option<(usize, Option<usize>)> {
        self.probes.round()
    }

    /// The pose chosen for the lamp probe.
    pub(crate) fn probe_pose(&self) -> Option<ProbePose> {
        self.probes.pose()
    }

    /// The sentinel's pose, readings and estimate so far.
    pub(crate) fn sentinel(&self) -> Option<SentinelSummary> {
        self.probes.sentinel()
    }

    /// A regular capture through the comparison stages, then into the ledger. A retake of an
    /// entry already checked is reported, not paired or compared again.
    fn regular(&mut self, input: &CaptureInput, m: Measured, out: &mut CheckOutput) {
        let ctx = Ctx {
            plan: &self.plan,
            rig: &self.rig,
            colour: &self.colour,
            spec: &self.spec,
        };
        let c = &m.checked;
        let retake = self.ledger.get(input.entry).is_some();
        if c.substitute && !c.dark && !retake {
            // its partner's light direction is the substitute's camera direction
            self.pairs
                .wait_for_partner(c.clone(), input.entry, m.camera);
        }
        if !retake {
            let mount = self.drift.as_ref().and_then(|d| d.mount());
            out.pairs.extend(self.pairs.pair(
                &ctx,
                &self.ledger,
                input.entry,
                c,
                mount.as_ref(),
                &mut out.alarms,
            ));
        }
        let comparable = c.exact_pose && !c.substitute && !c.dark && !retake;
        if comparable {
            if let Some(iso) = self.isotropy.as_mut() {
                out.isotropy.extend(iso.add(&ctx, input.entry, c));
            }
        }
        if comparable && c.xyz[1] > 0.0 {
            if let Some(drift) = self.drift.as_mut() {
                let key = ctx.geometry_key(m.light, m.camera);
                let at = (Some(input.idx), Some(input.t));
                let mount = mount_coordinates(&m.nominal.omega_i, &m.nominal.omega_o);
                let light_az = m.nominal.omega_i.y.atan2(m.nominal.omega_i.x);
                drift.observe(key, input.t, c.xyz, mount, light_az, at, &mut out.alarms);
                if let Some(sweeps) = self.sweeps.as_mut() {
                    sweeps.add(SweepCapture {
                        idx: input.idx,
                        t: input.t,
                        entry: input.entry,
                        light: m.light,
                        camera: m.camera,
                        class: key,
                        layer: key.0,
                        omega_i: m.nominal.omega_i,
                        omega_o: m.nominal.omega_o,
                        cmd: input.cmd,
                        wagon_dir: self.wagon_dir,
                        y: c.xyz[1],
                        mount,
                    });
                }
            }
        }
        if !self.ledger.keep(input.entry, m.checked) {
            out.alarms.push(
                Alarm::new(
                    crate::checks::alarm::AlarmKind::CaptureQuality,
                    crate::checks::alarm::Severity::Info,
                    AlarmCode::EntryRepeated,
                    format!(
                        "capture {} repeats plan entry {}; the first capture of it is kept for the checks",
                        input.idx, input.entry
                    ),
                )
                .at(Some(input.idx), Some(input.t)),
            );
        }
    }

    /// Note the entry as seen (any outcome); when that completes its light direction, the
    /// sweep is tested, and a gain step it finds becomes a step term of the drift model.
    fn light_seen(&mut self, input: &CaptureInput, out: &mut CheckOutput) {
        if input.probe {
            return;
        }
        self.recapture_wait(input, out);
        let Some(light) = self.plan.entry(input.entry).ok().map(|e| e.light) else {
            return;
        };
        if !self.ledger.see(input.entry, light) {
            return;
        }
        let level_test = !self.probes.enabled();
        let round = self.probes.round();
        let reserved: Vec<usize> = round
            .map(|(lamp, sentinel)| std::iter::once(lamp).chain(sentinel).collect())
            .unwrap_or_default();
        // the re-captures' noise scales from the lamp probe's luminance once it is known, and is
        // at least what the probes measure (their scatter about their trend is one capture's:
        // their original is common to all of them; a flickering lamp scatters both alike)
        let measured = self.probes.drift().scatter().filter(|s| s.is_finite());
        let recapture = self.recapture.map(|n| RecaptureNoise {
            y_ref: round
                .and_then(|(lamp, _)| self.ledger.get(lamp))
                .map(|c| c.xyz[1])
                .filter(|y| *y > 0.0 && y.is_finite()),
            capture_sd: measured.map_or(n.capture_sd, |m| n.capture_sd.max(m)),
        });
        if let Some(sweeps) = self.sweeps.as_mut() {
            let mount = self.drift.as_ref().and_then(|d| d.mount());
            let gain = self.drift.as_ref().and_then(|d| d.gain_path());
            sweeps.reserve_entries(&reserved);
            sweeps.set_recapture(recapture);
            let o = sweeps.light_complete(light, level_test, mount.as_ref(), gain.as_ref());
            self.apply_sweep_outcome(o, (Some(input.idx), Some(input.t)), out);
        }
    }

    /// A lamp probe. A step it finds while the wagon pair can say whether the camera's pose
    /// moved is held for the pair's next reading, asked for at once (`resolve_held_step`): a
    /// lamp probe pose turns with the view, and a degree of wagon can move it as far as a lamp
    /// step of a per cent.
    fn lamp_probe(&mut self, input: &CaptureInput, m: &Measured, out: &mut CheckOutput) {
        let hold = self
            .sweeps
            .as_ref()
            .filter(|s| s.can_check_pose())
            .map(|s| s.wagon_sensitivity_of(input.entry));
        let held = self.probes.lamp_probe(&self.ledger, input, m, hold, out);
        let unstable = self.probes.drift().unstable();
        if let Some(s) = self.sweeps.as_mut() {
            s.set_probes_unstable(unstable);
        }
        if held && !self.sweeps.as_mut().is_some_and(|s| s.request_pose_check()) {
            self.probes.release_held_step(out);
        }
    }

    /// A held probe step gets its pose check's reading once there is one.
    fn resolve_held_step(&mut self, out: &mut CheckOutput) {
        if !self.probes.holds_step() {
            return;
        }
        match self.sweeps.as_mut().map(|s| s.poll_pose_check()) {
            Some(Some(check)) => self.probes.resolve_held_step(check, out),
            Some(None) => {}
            // no sweeps to ask (cannot happen: a step is held only with them)
            None => self.probes.release_held_step(out),
        }
    }

    /// A regular capture was seen: a slip whose re-captures did not come in time is named
    /// from the sweeps alone.
    fn recapture_wait(&mut self, input: &CaptureInput, out: &mut CheckOutput) {
        self.probes.held_step_wait(out);
        if let Some(o) = self.sweeps.as_mut().map(|s| s.handle_regular_capture()) {
            self.apply_sweep_outcome(o, (Some(input.idx), Some(input.t)), out);
        }
    }

    /// A re-capture the sweeps asked for, with its luminance and the wagon's last direction of
    /// motion: once a question's captures are in, a slip is named (its alarm at this capture)
    /// or refuted, the wagon's pair read, or its lag read from both sides.
    fn recaptured(&mut self, input: &CaptureInput, y: f64, out: &mut CheckOutput) {
        let Some(o) = self
            .sweeps
            .as_mut()
            .map(|s| s.handle_recapture(input.entry, y, self.wagon_dir))
        else {
            return;
        };
        let at = (Some(input.idx), Some(input.t));
        let mut found = CheckOutput::default();
        self.apply_sweep_outcome(o, at, &mut found);
        out.alarms
            .extend(found.alarms.into_iter().map(|a| a.at(at.0, at.1)));
    }

    /// What the sweeps found, into the drift model (a step term, a withdrawn step, a pose
    /// break) and the output (the sweep's record and the alarms); `at` stamps the drift
    /// model's own alarms.
    fn apply_sweep_outcome(
        &mut self,
        o: crate::detect::sweeps::SweepOutcome,
        at: (Option<u64>, Option<f64>),
        out: &mut CheckOutput,
    ) {
        if let Some(drift) = self.drift.as_mut() {
            if let Some(t) = o.step_at_s {
                drift.add_step(t);
            }
            for &t in &o.withdrawn_steps_s {
                drift.remove_step(t, at, &mut out.alarms);
            }
            if let Some(t) = o.slip_at_s {
                drift.add_pose_break(t, at, &mut out.alarms);
            }
        }
        out.sweeps.extend(o.record);
        out.alarms.extend(o.findings.iter().map(sweeps::alarm));
    }

    /// Score the waiting substitutes that `ready` selects; their interpolated pairs also go to
    /// the drift stage.
    fn resolve(
        &mut self,
        ready: impl Fn(&pairs::PendingPartner, &Ledger) -> bool,
        t: f64,
        out: &mut CheckOutput,
    ) {
        let ctx = Ctx {
            plan: &self.plan,
            rig: &self.rig,
            colour: &self.colour,
            spec: &self.spec,
        };
        for (p, pair) in self.pairs.resolve(&ctx, &self.ledger, ready, t) {
            if let Some(drift) = self.drift.as_mut() {
                drift.observe_interpolated(&ctx, &self.ledger, &p, &pair, &mut out.alarms);
            }
            out.pairs.push(pair);
        }
    }

    /// The gain drift estimate from the probes, once there are enough.
    pub(crate) fn probe_drift(&self) -> Option<DriftEstimate> {
        self.probes.estimate()
    }

    /// Gain steps in the isotropy drift model (found by the light sweeps).
    pub(crate) fn isotropy_steps(&self) -> Vec<StepEffect> {
        self.drift
            .as_ref()
            .map(|d| d.steps().to_vec())
            .unwrap_or_default()
    }

    /// The light-sweep checks' state (none when they do not run for this session).
    pub fn sweeps(&self) -> Option<SweepSummary> {
        self.sweeps.as_ref().map(|m| m.summary())
    }

    /// What this session's detectors watch and cannot see (sample, order, probes, sweeps).
    pub(crate) fn observability(&self) -> observability::Observability {
        observability::observability(
            self.isotropy.is_some(),
            self.probes.enabled(),
            self.plan.order(),
            self.spec.sweeps.enabled,
            self.probes.watches_joint3(),
            self.spec.sweeps.wagon_watch_sweeps > 0,
        )
    }

    /// The lamp's colour drift, once estimated: from isotropy classes (isotropic samples), else
    /// from the probes.
    pub(crate) fn colour_drift(&self) -> Option<ColourDriftEstimate> {
        self.drift
            .as_ref()
            .and_then(|d| d.colour_estimate())
            .or_else(|| self.probes.colour().and_then(|c| c.estimate()))
    }

    /// The gain drift estimate from isotropy classes (isotropic samples), once there are enough.
    pub fn isotropy_drift(&self) -> Option<DriftEstimate> {
        self.drift.as_ref().and_then(|d| d.estimate())
    }

    /// The off-centre mount's pattern, once the isotropy drift model carries it.
    pub(crate) fn sample_off_centre(&self) -> Option<MountPattern> {
        self.drift.as_ref().and_then(|d| d.mount())
    }

    /// The conditions that hold over captures and are in progress now (pose episodes).
    pub(crate) fn open_conditions(&self) -> Vec<Alarm> {
        self.capture.open_episodes()
    }

    pub(crate) fn plan(&self) -> &SamplingPlan {
        &self.plan
    }
    pub(crate) fn table2(&self) -> &Table2 {
        &self.pairs.table2
    }
    /// Table 2 over the exact pairs with a capture placed by the commanded pose (a subset of
    /// `table2`): they hold only if the arm went where it was told.
    pub(crate) fn by_command_table(&self) -> &Table2 {
        &self.pairs.by_command_table
    }
    pub(crate) fn isotropy_table(&self) -> Table2 {
        self.isotropy
            .as_ref()
            .map(|i| i.table.clone())
            .unwrap_or_default()
    }
    /// Table 2 over the substitutes' interpolated pairs.
    pub(crate) fn interpolated_table(&self) -> &Table2 {
        &self.pairs.interpolated_table
    }

    /// The counters of every stage, and the alarms.
    pub(crate) fn counts(&self) -> CheckCounts {
        let (c, p) = (&self.capture, &self.pairs);
        CheckCounts {
            captures: c.captures,
            ok: c.ok,
            failed: c.failed,
            missing: c.missing,
            probes: c.probes,
            pairs_exact: p.exact,
            pairs_needs_resampling: p.needs_resampling,
            pairs_grazing: p.grazing,
            pairs_interpolated: p.interpolated,
            pairs_unresolved: p.unresolved,
            isotropy_comparisons: self.isotropy.as_ref().map_or(0, |i| i.comparisons),
            drift_interpolated: self.drift.as_ref().map_or(0, |d| d.interpolated),
            drift_left_out_slip: self.drift.as_ref().map_or(0, |d| d.left_out() as u64),
            pose_off_plan: c.off_plan,
            encoder_mismatch: c.encoder_mismatch,
            placed_by_command: c.placed_by_command,
            alarms: self.alarms,
        }
    }
}

/// The gain known now at time `t_h`, divided out of `xyz`: from the probes' current segment
/// when probes run, else from the isotropy drift model (rate and the sweeps' steps).
fn gain_correction(
    probes: &ProbeStage,
    probes_taken: u64,
    drift: Option<&DriftStage>,
    t_h: f64,
    xyz: Xyz,
) -> Option<GainCorrected> {
    let probe_colour = probes.colour();
    // probes the controller refused stop being the lamp's watch: their estimate stands in the
    // summary, the correction goes on from the isotropy drift model
    let probe_gain = probes
        .enabled()
        .then(|| probes.drift().gain_at(t_h))
        .flatten();
    let (gain, sigma_rel, source) = if let Some((g, s)) = probe_gain {
        (g, s, "probes")
    } else if probes.enabled() && probes_taken > 0 {
        // probes are in use but their segment is too short to fit (just after a step): the
        // isotropy rate would leave the step out, so nothing rather than a wrong correction
        return None;
    } else {
        let (ln_g, sigma) = drift?.ln_gain_at(t_h)?;
        (ln_g.exp(), sigma, "isotropy classes")
    };
    if !(gain > 0.0 && gain.is_finite()) {
        return None;
    }
    // the lamp's colour, where it is estimated, leaves X and Z as well
    let colour = drift
        .and_then(|d| d.ln_chromaticity_at(t_h))
        .or_else(|| probe_colour.and_then(|c| c.ln_chromaticity_at(t_h)))
        .filter(|c| c.iter().all(|v| v.is_finite()));
    let [cx, cz] = colour.map_or([1.0, 1.0], |[u, v]| [u.exp(), v.exp()]);
    Some(GainCorrected {
        xyz: [xyz[0] / gain / cx, xyz[1] / gain, xyz[2] / gain / cz],
        gain,
        sigma_rel,
        source: source.into(),
        colour,
    })
}
