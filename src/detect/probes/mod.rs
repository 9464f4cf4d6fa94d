//! Drift from probes: periodic re-captures of one reference pose (docs/protocol.md `PROBE`, off
//! unless the operator enables `[probes] every`). A probe and the original capture of its plan
//! entry share the geometry exactly, so ln(Y_probe / Y_original) is the gain change between the
//! two times with no geometric nuisance: the confounding that reciprocal pairs suffer (see
//! `detect::drift`) does not arise.
//!
//! Model: d(t) = a + r·(t − t₀) on the current segment (ordinary least squares; r in ln-gain per
//! hour). A rate alarm when |r| − z·SE(r) exceeds the tolerance (with hysteresis). A step alarm
//! when a new probe departs from the segment's prediction by more than `step_sigmas` residual
//! standard deviations and `step_pct`, while the segment's residual SD is within what
//! `lamp-unstable` allows (a segment that scatters more is the stability test's); the segment
//! then restarts at that probe.

use super::drift::{DriftEstimate, DriftEvent, DriftSpec};
use crate::measure::geometry::{angle_between, mirror, Vec3};
use serde::{Deserialize, Serialize};

/// How often the lamp probe is asked for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProbeEvery {
    /// The cadence `goniowatch plan` designs for the session's sample and the default target
    /// (resolved once by `setup`; none on a files source, which cannot take probes).
    Auto,
    /// Every this many checked captures; 0 = never.
    Captures(u64),
}

impl ProbeEvery {
    /// The configured cadence, or `None` for one left to the design.
    pub fn fixed(self) -> Option<u64> {
        match self {
            ProbeEvery::Auto => None,
            ProbeEvery::Captures(n) => Some(n),
        }
    }
}

impl Serialize for ProbeEvery {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            ProbeEvery::Auto => s.serialize_str("auto"),
            ProbeEvery::Captures(n) => s.serialize_u64(*n),
        }
    }
}

impl<'de> Deserialize<'de> for ProbeEvery {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = ProbeEvery;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number of captures (0 = never) or \"auto\"")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ProbeEvery, E> {
                Ok(ProbeEvery::Captures(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ProbeEvery, E> {
                u64::try_from(v)
                    .map(ProbeEvery::Captures)
                    .map_err(|_| E::custom(format!("{v} is not a number of captures")))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ProbeEvery, E> {
                match v {
                    "auto" => Ok(ProbeEvery::Auto),
                    _ => Err(E::custom(format!(
                        "{v:?}: give a number of captures (0 = never) or \"auto\""
                    ))),
                }
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProbeSpec {
    /// Ask for a probe every this many checked captures; 0 = never (the default of a config
    /// that leaves it out: probes move the rig); "auto" = the cadence `goniowatch plan`
    /// designs (the shipped protocol configs).
    pub every: ProbeEvery,
    /// The plan entry to re-capture; unset, the daemon chooses it (`choose_probe_pose`) once a
    /// light sweep's worth of captures is checked.
    pub entry: Option<usize>,
    pub rate_tolerance_pct_per_h: f64,
    pub z: f64,
    /// Probes on a segment before its rate is judged.
    pub min_probes: usize,
    pub step_sigmas: f64,
    /// Smallest step reported (%).
    pub step_pct: f64,
    /// The probes' scatter (% SD of one probe against its original capture) the cadence was
    /// designed for: `goniowatch plan` assumes it, and `lamp-unstable` is raised when the
    /// measured scatter exceeds it by `UNSTABLE_FACTOR`.
    pub design_scatter_pct: f64,
    /// On an anisotropic sample, follow each probe with a sentinel probe of a pose chosen to
    /// be sensitive to arm joint 3 (`detect::sentinel`); it doubles the probes' run time.
    pub sentinel: bool,
    /// Smallest turn of joint 3 the sentinel reports (degrees).
    pub sentinel_min_deg: f64,
}

impl ProbeSpec {
    /// The cadence in captures: the configured one, 0 for one left to the design that nothing
    /// resolved (`setup::probe_cadence` resolves it before a session starts).
    pub fn cadence(&self) -> u64 {
        self.every.fixed().unwrap_or(0)
    }
}

impl Default for ProbeSpec {
    fn default() -> Self {
        ProbeSpec {
            every: ProbeEvery::Captures(0),
            entry: None,
            rate_tolerance_pct_per_h: 0.25,
            z: 4.0,
            min_probes: 4,
            step_sigmas: 5.0,
            step_pct: 1.0,
            design_scatter_pct: 0.3,
            sentinel: true,
            sentinel_min_deg: 0.5,
        }
    }
}

/// A checked capture offered to the probe-pose choice: its plan entry, its light and camera
/// direction indices, both directions in the sample frame, and its luminance.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PoseSample {
    pub entry: usize,
    pub light: usize,
    pub camera: usize,
    pub omega_i: Vec3,
    pub omega_o: Vec3,
    pub y: f64,
}

/// The chosen probe pose, with the figures it was chosen by.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ProbePose {
    pub entry: usize,
    pub theta_i_deg: f64,
    pub theta_o_deg: f64,
    /// Angle between the camera and the light's mirror direction (°).
    pub specular_distance_deg: f64,
    /// Its luminance at the original capture.
    pub luminance: f64,
    /// The change of its luminance per degree of pose error (%/°): the steepest slope of ln Y to
    /// a neighbouring capture within `PROBE_NEIGHBOUR_DEG` (same light, camera moved; or same
    /// camera, light moved), plus the cosine term's 100·tan θi·π/180 when no light-side
    /// neighbour was measured.
    pub sensitivity_pct_per_deg: f64,
}

/// A probe pose is far from grazing: θi at most this ...
pub(crate) const PROBE_MAX_THETA_I_DEG: f64 = 30.0;
/// ... and θo at most this.
pub(crate) const PROBE_MAX_THETA_O_DEG: f64 = 45.0;
/// It is off the specular peak (where a pose error changes the luminance most) by at least this.
pub(crate) const PROBE_MIN_SPECULAR_DEG: f64 = 25.0;
/// Neighbours within this angle measure its sensitivity to a pose error.
pub(crate) const PROBE_NEIGHBOUR_DEG: f64 = 25.0;
/// Any candidate at most this sensitive (%/°) is quiet enough to be chosen for its brightness.
pub(crate) const PROBE_QUIET_PCT_PER_DEG: f64 = 0.5;

/// Chooses the probe pose among checked captures (pass them in entry order): far from grazing
/// and off the specular peak (the limits above), with at least two neighbours to measure its
/// sensitivity to a pose error (a slipped joint moves the probe as much as any capture), the
/// brightest of those whose sensitivity is at most twice the least one's, or
/// `PROBE_QUIET_PCT_PER_DEG`, whichever is larger. Brightness keeps the probe's own noise low
/// (camera noise and quantisation are relative to the signal); the sensitivity bound keeps a
/// joint's slip from looking like a lamp step. Ties go to the lower entry; None when no capture
/// qualifies.
pub(crate) fn choose_probe_pose(samples: &[PoseSample]) -> Option<ProbePose> {
    let usable = |s: &PoseSample| s.y > 0.0 && s.y.is_finite();
    let theta = |v: &Vec3| v.z.clamp(-1.0, 1.0).acos().to_degrees();
    // neighbours share the light or the camera: index both ways (a session has thousands)
    let mut by_light: std::collections::BTreeMap<usize, Vec<&PoseSample>> = Default::default();
    let mut by_camera: std::collections::BTreeMap<usize, Vec<&PoseSample>> = Default::default();
    for s in samples.iter().filter(|s| usable(s)) {
        by_light.entry(s.light).or_default().push(s);
        by_camera.entry(s.camera).or_default().push(s);
    }
    let mut candidates = Vec::new();
    for s in samples.iter().filter(|s| usable(s)) {
        let (ti, to) = (theta(&s.omega_i), theta(&s.omega_o));
        let spec = angle_between(&mirror(&s.omega_i), &s.omega_o).to_degrees();
        // the limits hold to a micro-degree: poses from the kinematics are not exact
        let eps = 1e-6;
        if !(ti <= PROBE_MAX_THETA_I_DEG + eps
            && to <= PROBE_MAX_THETA_O_DEG + eps
            && spec >= PROBE_MIN_SPECULAR_DEG - eps)
        {
            continue;
        }
        let mut slope: f64 = 0.0;
        let mut neighbours = 0usize;
        let mut light_side = false;
        let camera_moved = by_light
            .get(&s.light)
            .into_iter()
            .flatten()
            .map(|n| (n, angle_between(&s.omega_o, &n.omega_o), false));
        let light_moved = by_camera
            .get(&s.camera)
            .into_iter()
            .flatten()
            .filter(|n| n.light != s.light)
            .map(|n| (n, angle_between(&s.omega_i, &n.omega_i), true));
        for (n, moved, light) in camera_moved.chain(light_moved) {
            let moved = moved.to_degrees();
            if n.entry != s.entry && moved > 1e-6 && moved <= PROBE_NEIGHBOUR_DEG {
                slope = slope.max(100.0 * (n.y / s.y).ln().abs() / moved);
                neighbours += 1;
                light_side |= light;
            }
        }
        if neighbours < 2 {
            continue;
        }
        if !light_side {
            slope += 100.0 * ti.to_radians().tan() * std::f64::consts::PI / 180.0;
        }
        candidates.push(ProbePose {
            entry: s.entry,
            theta_i_deg: ti,
            theta_o_deg: to,
            specular_distance_deg: spec,
            luminance: s.y,
            sensitivity_pct_per_deg: slope,
        });
    }
    let least = candidates
        .iter()
        .map(|p| p.sensitivity_pct_per_deg)
        .fold(f64::INFINITY, f64::min);
    let bound = (2.0 * least).max(PROBE_QUIET_PCT_PER_DEG);
    let mut best: Option<ProbePose> = None;
    for p in candidates
        .into_iter()
        .filter(|p| p.sensitivity_pct_per_deg <= bound)
    {
        if best.is_none_or(|b| p.luminance > b.luminance) {
            best = Some(p);
        }
    }
    best
}

/// `lamp-unstable` when the probes' robust scatter exceeds the design scatter by this factor ...
pub(crate) const UNSTABLE_FACTOR: f64 = 2.0;
/// ... and clears below this one (hysteresis).
pub(crate) const UNSTABLE_CLEAR_FACTOR: f64 = 1.5;
/// The scatter is judged over the last this many probes of a segment (the original capture
/// that anchors the first segment left out): the MAD of fewer is too coarse, and a window keeps
/// a flicker that starts late in a long steady segment from being outvoted.
pub(crate) const UNSTABLE_WINDOW: usize = 8;

#[derive(Debug, Clone)]
pub(crate) struct ProbeDrift {
    spec: ProbeSpec,
    /// (t in hours, ln ratio) of the current segment.
    segment: Vec<(f64, f64)>,
    /// The capture index of each point of the segment (None: the original capture).
    segment_idx: Vec<Option<u64>>,
    rate_alarm: bool,
    unstable: bool,
    /// The last scatter measured by `stability` (ln units).
    scatter: Option<f64>,
    estimate: Option<DriftEstimate>,
}

struct Fit {
    a: f64,
    r: f64,
    t0: f64,
    se: f64,
    sd: f64,
}

fn fit(points: &[(f64, f64)]) -> Option<Fit> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let nf = n as f64;
    let t0 = points[0].0;
    let tm = points.iter().map(|p| p.0 - t0).sum::<f64>() / nf;
    let dm = points.iter().map(|p| p.1).sum::<f64>() / nf;
    let sxx: f64 = points.iter().map(|p| (p.0 - t0 - tm).powi(2)).sum();
    if !(sxx > 0.0) {
        return None;
    }
    let sxy: f64 = points.iter().map(|p| (p.0 - t0 - tm) * (p.1 - dm)).sum();
    let r = sxy / sxx;
    let a = dm - r * tm;
    let sse: f64 = points
        .iter()
        .map(|p| (p.1 - a - r * (p.0 - t0)).powi(2))
        .sum();
    let var = sse / (nf - 2.0);
    Some(Fit {
        a,
        r,
        t0,
        se: (var / sxx).sqrt(),
        sd: var.sqrt(),
    })
}

impl ProbeDrift {
    pub(crate) fn new(spec: ProbeSpec) -> Self {
        ProbeDrift {
            spec,
            segment: Vec::new(),
            segment_idx: Vec::new(),
            rate_alarm: false,
            unstable: false,
            scatter: None,
            estimate: None,
        }
    }

    /// Whether `lamp-unstable` stands.
    pub(crate) fn unstable(&self) -> bool {
        self.unstable
    }

    /// The probes' scatter (ln units, one probe against its original) over the last
    /// `UNSTABLE_WINDOW` probes of a segment, from one probe to the next (`stability`), once
    /// measured.
    pub(crate) fn scatter(&self) -> Option<f64> {
        self.scatter
    }

    pub(crate) fn estimate(&self) -> Option<DriftEstimate> {
        self.estimate
    }

    /// The gain at `t_h` relative to the original capture of the probe pose, from the current
    /// segment's line (its level includes any step since the start), and its relative standard
    /// uncertainty (intercept and slope). None until the segment has three points.
    pub(crate) fn gain_at(&self, t_h: f64) -> Option<(f64, f64)> {
        let f = fit(&self.segment)?;
        let n = self.segment.len() as f64;
        let tm = self.segment.iter().map(|p| p.0).sum::<f64>() / n;
        let ln_g = f.a + f.r * (t_h - f.t0);
        let sigma = (f.sd * f.sd / n + (f.se * (t_h - tm)).powi(2)).sqrt();
        (ln_g.is_finite() && sigma.is_finite()).then(|| (ln_g.exp(), sigma))
    }

    /// One probe, capture `idx`: its time and luminance, and the original capture's time and
    /// luminance.
    pub(crate) fn add(
        &mut self,
        idx: u64,
        t_orig_h: f64,
        y_orig: f64,
        t_h: f64,
        y: f64,
    ) -> Vec<DriftEvent> {
        let mut ev = Vec::new();
        if !(y_orig > 0.0 && y > 0.0 && t_h.is_finite() && t_orig_h.is_finite()) {
            return ev;
        }
        let d = (y / y_orig).ln();
        if self.segment.is_empty() {
            // the original capture anchors the first segment at ratio 1
            self.segment.push((t_orig_h, 0.0));
            self.segment_idx.push(None);
        }
        if self.segment.len() > self.spec.min_probes {
            if let Some(f) = fit(&self.segment) {
                let e = d - (f.a + f.r * (t_h - f.t0));
                let sd = f.sd.max(1e-4);
                // a step is a lamp's that was steady: a segment that already scatters beyond
                // what `lamp-unstable` allows (a flicker the stability window has not judged
                // yet) makes departures of its own, which its few residuals under-scale by chance
                let design = self.spec.design_scatter_pct / 100.0;
                let steady = !(design > 0.0 && sd > UNSTABLE_FACTOR * design);
                if steady
                    && e.abs() > self.spec.step_sigmas * sd
                    && e.abs() > self.spec.step_pct / 100.0
                {
                    ev.push(DriftEvent::Step {
                        direction: if e > 0.0 { 1 } else { -1 },
                        statistic: e.abs() / sd,
                        threshold: self.spec.step_sigmas,
                        pairs_since_reset: self.segment.len(),
                    });
                    self.segment.clear();
                    self.segment_idx.clear();
                    self.rate_alarm = false;
                }
            }
        }
        self.segment.push((t_h, d));
        self.segment_idx.push(Some(idx));
        if let Some(f) = fit(&self.segment) {
            let est = DriftEstimate {
                pairs: self.segment.len() - 1,
                rate_pct_per_h: 100.0 * f.r,
                se_pct_per_h: 100.0 * f.se,
                residual_scale: f.sd,
            };
            self.estimate = Some(est);
            if self.segment.len() > self.spec.min_probes {
                let lower = est.rate_pct_per_h.abs() - self.spec.z * est.se_pct_per_h;
                let upper = est.rate_pct_per_h.abs() + self.spec.z * est.se_pct_per_h;
                if !self.rate_alarm && lower > self.spec.rate_tolerance_pct_per_h {
                    self.rate_alarm = true;
                    ev.push(DriftEvent::RateSignificant(est));
                } else if self.rate_alarm && upper < self.spec.rate_tolerance_pct_per_h {
                    self.rate_alarm = false;
                    ev.push(DriftEvent::RateCleared(est));
                }
            }
            ev.extend(self.stability(&f));
        }
        ev
    }

    /// The lamp's stability at the probes, over the last `UNSTABLE_WINDOW` probes, by two robust
    /// scales: from one probe to the next (1.4826 · median |Δr − median Δr| / √2, r a probe's
    /// residual about the current segment's line) and about the line (1.4826 · median |r|). A
    /// flicker moves each probe on its own and raises both; a step of the lamp or of the probe's
    /// pose (a slipped wagon moves a probe whose luminance turns with the view) is one
    /// difference, which the first leaves out, and a drift is the line. `lamp-unstable` is
    /// raised when both exceed `UNSTABLE_FACTOR` × the design scatter, and cleared when both are
    /// below `UNSTABLE_CLEAR_FACTOR` ×: eight probes give a coarse scale, and neither a chance
    /// window of one scale nor a flicker's lucky window must raise or clear it.
    fn stability(&mut self, f: &Fit) -> Option<DriftEvent> {
        let design = self.spec.design_scatter_pct / 100.0;
        let probes: Vec<(usize, u64)> = self
            .segment_idx
            .iter()
            .enumerate()
            .filter_map(|(k, i)| i.map(|i| (k, i)))
            .collect();
        if probes.len() < UNSTABLE_WINDOW || !(design > 0.0) {
            return None;
        }
        let window = &probes[probes.len() - UNSTABLE_WINDOW..];
        let from_idx = window[0].1;
        let residual = |k: usize| {
            let p = self.segment[k];
            p.1 - f.a - f.r * (p.0 - f.t0)
        };
        let mad = |mut v: Vec<f64>, centre: bool| {
            v.sort_by(f64::total_cmp);
            let c = if centre {
                crate::measure::stats::median_sorted(&v)
            } else {
                0.0
            };
            let mut dev: Vec<f64> = v.iter().map(|x| (x - c).abs()).collect();
            dev.sort_by(f64::total_cmp);
            1.4826 * crate::measure::stats::median_sorted(&dev)
        };
        let about_line = mad(window.iter().map(|&(k, _)| residual(k)).collect(), false);
        let step_to_step = mad(
            window
                .windows(2)
                .map(|w| residual(w[1].0) - residual(w[0].0))
                .collect(),
            true,
        ) / std::f64::consts::SQRT_2;
        let high = about_line.max(step_to_step);
        if !(step_to_step.is_finite() && high.is_finite()) {
            return None;
        }
        self.scatter = Some(step_to_step);
        let low = about_line.min(step_to_step);
        if !self.unstable && low > UNSTABLE_FACTOR * design {
            self.unstable = true;
            Some(DriftEvent::Unstable {
                scatter: low,
                design,
                probes: UNSTABLE_WINDOW,
                from_idx,
            })
        } else if self.unstable && high < UNSTABLE_CLEAR_FACTOR * design {
            self.unstable = false;
            Some(DriftEvent::UnstableCleared {
                scatter: high,
                design,
                probes: UNSTABLE_WINDOW,
            })
        } else {
            None
        }
    }
}

/// The drift probes' two colour fits (ln X/Y and ln Z/Y against the probe pose's original
/// capture): one geometry, so one bucket; refit at every probe once there are `min_probes`
/// (at least 3); rate only, and no rate alarm of their own: the colour alarm is decided on the
/// combined colour-temperature rate (`CctRate::exceeds`). The residual scale is floored at the
/// probes' design scatter (`scale_floor`, ln units), which the chromaticity ratios are assumed
/// to share: with 4 probes a fit has 2 degrees of freedom, and a scale estimated from so few
/// residuals is often small enough to make a steady lamp's rate look significant. Shared by the daemon's colour
/// check and `goniowatch plan`'s simulation of it.
pub(crate) fn colour_fit_spec(min_probes: usize, scale_floor: f64) -> DriftSpec {
    DriftSpec {
        scale_floor,
        min_pairs: min_probes.max(3),
        refit_every: 1,
        step_detection: false,
        rate_tolerance_pct_per_h: f64::INFINITY,
        mount_terms: false,
        ..DriftSpec::default()
    }
}

#[cfg(test)]
mod tests;
