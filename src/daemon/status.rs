//! Shell: the live status model behind `run --http` (the page, `/status.json`, `/events`,
//! `/metrics`). It holds nothing of its own: it is fed the same result records the daemon writes
//! (and, on resume, reads them back from the session folder), plus the engine's summary.
//!
//! The run loop publishes a snapshot through a `tokio::sync::watch` channel: publishing never
//! waits for a reader, and a slow reader only ever sees the latest snapshot.

use crate::checks::alarm::{Alarm, AlarmKind};
use crate::checks::{CaptureRecord, PairRecord};
use crate::detect::sweeps::SweepRecord;
use crate::engine::{Output, Summary};
use crate::measure::plan::SamplingPlan;
use serde::Serialize;
use std::collections::VecDeque;
use std::path::Path;

/// How many recent pairs and alarms the page shows.
const RECENT_PAIRS: usize = 400;
const RECENT_ALARMS: usize = 100;
/// How many drift, positioning and isotropy alarms the time plots mark (from the start: an
/// early slip must stay on the plots of a long run).
const TICKED_ALARMS: usize = 1000;

#[derive(Debug, Clone, Serialize)]
pub(crate) struct Direction {
    pub theta_deg: f64,
    pub phi_deg: f64,
}

#[derive(Debug, Clone, Serialize)]
pub(crate) struct RecentPair {
    pub idx: u64,
    pub t_h: f64,
    pub status: String,
    pub de2000: f64,
}

#[derive(Debug, Clone, Serialize)]
pub(crate) struct DriftPoint {
    pub t_h: f64,
    pub rate_pct_per_h: f64,
    pub se_pct_per_h: f64,
}

/// The lamp's colour-temperature drift estimate at a point of the run.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct ColourPoint {
    pub t_h: f64,
    pub k_per_h: f64,
    pub se_k_per_h: f64,
}

/// A completed light sweep: its level against what its layer's pattern predicts, and the
/// fitted offsets of joints 1 and 2.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct SweepPoint {
    pub t_h: f64,
    pub light: usize,
    /// The sweep's gain level less the layer's prediction (%), and its standard error.
    pub level_pct: f64,
    pub level_se_pct: f64,
    /// (joint, offset °, standard error °) per fitted joint.
    pub joints: Vec<(usize, f64, f64)>,
}

#[derive(Debug, Clone, Serialize)]
pub(crate) struct GainPoint {
    pub t_h: f64,
    /// Probe luminance over the original capture's.
    pub gain: f64,
}

/// What the page and the endpoints show.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Snapshot {
    pub summary: Summary,
    /// Captures checked (regular and probes), and those that failed or went missing.
    pub checked: u64,
    pub remaining: u64,
    /// Wall-clock rate over the last minutes and the estimated time to the end (seconds).
    pub rate_per_h: Option<f64>,
    pub eta_s: Option<f64>,
    /// Controller time of the last checked capture (hours).
    pub t_h: f64,
    pub state: String,
    pub directions: Vec<Direction>,
    /// Per plan direction used as the light: captures checked of its plan entries.
    pub done_per_light: Vec<u32>,
    pub per_light: u32,
    pub current_light: Option<usize>,
    pub recent_pairs: Vec<RecentPair>,
    pub alarms: Vec<Alarm>,
    /// The drift, positioning and isotropy alarms, from the start of the run, for the time
    /// plots' ticks.
    pub ticked: Vec<Alarm>,
    pub drift: Vec<DriftPoint>,
    pub colour: Vec<ColourPoint>,
    pub gain: Vec<GainPoint>,
    pub sweeps: Vec<SweepPoint>,
}

/// The aggregator.
pub(crate) struct StatusModel {
    directions: Vec<Direction>,
    done_per_light: Vec<u32>,
    current_light: Option<usize>,
    probe_gain: crate::checks::ProbeGainCurve,
    recent_pairs: VecDeque<RecentPair>,
    alarms: VecDeque<Alarm>,
    ticked: Vec<Alarm>,
    drift: Vec<DriftPoint>,
    colour: Vec<ColourPoint>,
    gain: Vec<GainPoint>,
    sweeps: Vec<SweepPoint>,
    last_t: f64,
    last_drift_n: usize,
    last_colour_n: usize,
    /// (wall seconds, captures checked) samples for the rate.
    rate_window: VecDeque<(f64, u64)>,
}

impl StatusModel {
    /// The model of a session with this plan; probes at or below `dark_y` are no gain points.
    pub(crate) fn new(plan: &SamplingPlan, dark_y: f64) -> Self {
        let n = plan.direction_count();
        StatusModel {
            directions: plan
                .directions()
                .iter()
                .map(|d| Direction {
                    theta_deg: d.theta_deg,
                    phi_deg: d.phi_deg,
                })
                .collect(),
            done_per_light: vec![0; n],
            current_light: None,
            probe_gain: crate::checks::ProbeGainCurve::new(dark_y),
            recent_pairs: VecDeque::new(),
            alarms: VecDeque::new(),
            ticked: Vec::new(),
            drift: Vec::new(),
            colour: Vec::new(),
            gain: Vec::new(),
            sweeps: Vec::new(),
            last_t: 0.0,
            last_drift_n: 0,
            last_colour_n: 0,
            rate_window: VecDeque::new(),
        }
    }

    /// Rebuild from a session folder's result files (on resume).
    pub(crate) fn load(&mut self, dir: &Path) {
        // the files were just rebuilt from the journal; one that cannot be read leaves its
        // part of the page empty, with a warning, rather than the run without a page
        fn each<T: serde::de::DeserializeOwned>(path: &Path, f: impl FnMut(T)) {
            match crate::session::folder::read_records::<T>(path) {
                Ok(v) => v.into_iter().for_each(f),
                Err(e) => tracing::warn!("status page: {e:#}"),
            }
        }
        each(&dir.join("captures.jsonl"), |c: CaptureRecord| {
            self.capture(&c)
        });
        each(&dir.join("pairs.jsonl"), |p: PairRecord| self.pair(&p));
        each(&dir.join("alarms.jsonl"), |a: Alarm| self.alarm(&a));
        each(&dir.join("sweeps.jsonl"), |r: SweepRecord| self.sweep(&r));
    }

    fn sweep(&mut self, r: &SweepRecord) {
        self.sweeps.push(SweepPoint {
            t_h: r.t / 3600.0,
            light: r.light,
            level_pct: r.level_pct - r.level_expected_pct,
            level_se_pct: r.level_se_pct,
            joints: r
                .joints
                .iter()
                .map(|j| (j.joint, j.offset_deg, j.se_deg))
                .collect(),
        });
    }

    fn capture(&mut self, c: &CaptureRecord) {
        self.last_t = c.t;
        if let Some((t_h, gain)) = self.probe_gain.add(c) {
            self.gain.push(GainPoint { t_h, gain });
        }
        if c.probe {
            return;
        }
        if let Some(slot) = self.done_per_light.get_mut(c.light) {
            *slot += 1;
        }
        self.current_light = Some(c.light);
    }

    fn pair(&mut self, p: &PairRecord) {
        let Some(d) = &p.diff else { return };
        self.recent_pairs.push_back(RecentPair {
            idx: p.b,
            t_h: p.t / 3600.0,
            status: p.status.as_str().to_string(),
            de2000: d.de2000,
        });
        while self.recent_pairs.len() > RECENT_PAIRS {
            self.recent_pairs.pop_front();
        }
    }

    fn alarm(&mut self, a: &Alarm) {
        if matches!(
            a.kind,
            AlarmKind::Drift | AlarmKind::Positioning | AlarmKind::Isotropy
        ) && self.ticked.len() < TICKED_ALARMS
        {
            self.ticked.push(a.clone());
        }
        self.alarms.push_back(a.clone());
        while self.alarms.len() > RECENT_ALARMS {
            self.alarms.pop_front();
        }
    }

    /// Take in one engine output.
    pub(crate) fn record(&mut self, o: &Output) {
        match o {
            Output::Capture(c) => self.capture(c),
            Output::Pair(p) => self.pair(p),
            Output::Alarm(a) => self.alarm(a),
            Output::Sweep(r) => self.sweep(r),
            Output::Send(_)
            | Output::Ingest { .. }
            | Output::Isotropy(_)
            | Output::Manifest(_)
            | Output::ProbePose(_)
            | Output::SentinelPose(_)
            | Output::Finished => {}
        }
    }

    /// The snapshot for the page; `wall_s` is the shell's clock (seconds, any origin).
    pub(crate) fn snapshot(&mut self, summary: &Summary, wall_s: f64) -> Snapshot {
        let checked = summary.checked.captures;
        // a new drift point when the probe estimate changed
        if let Some(d) = summary
            .probe_drift
            .as_ref()
            .or(summary.isotropy_drift.as_ref())
        {
            if d.pairs != self.last_drift_n {
                self.last_drift_n = d.pairs;
                self.drift.push(DriftPoint {
                    t_h: self.last_t / 3600.0,
                    rate_pct_per_h: d.rate_pct_per_h,
                    se_pct_per_h: d.se_pct_per_h,
                });
            }
        }
        if let Some(c) = &summary.colour_drift {
            if c.observations != self.last_colour_n {
                self.last_colour_n = c.observations;
                self.colour.push(ColourPoint {
                    t_h: self.last_t / 3600.0,
                    k_per_h: c.k_per_h,
                    se_k_per_h: c.se_k_per_h,
                });
            }
        }
        self.rate_window.push_back((wall_s, checked));
        while self
            .rate_window
            .front()
            .is_some_and(|(w, _)| wall_s - w > 300.0)
        {
            self.rate_window.pop_front();
        }
        let regular = checked.saturating_sub(summary.checked.probes);
        let remaining = summary.captures_planned.saturating_sub(regular);
        let rate_per_s = self.rate_window.front().and_then(|(w0, c0)| {
            let dt = wall_s - w0;
            (dt >= 2.0 && checked > *c0).then(|| (checked - c0) as f64 / dt)
        });
        let state = if summary.finished {
            "finished"
        } else if summary.link.connects > summary.link.disconnects {
            "running"
        } else {
            "waiting for the controller"
        };
        Snapshot {
            summary: summary.clone(),
            checked,
            remaining,
            rate_per_h: rate_per_s.map(|r| r * 3600.0),
            eta_s: rate_per_s.map(|r| remaining as f64 / r),
            t_h: self.last_t / 3600.0,
            state: state.into(),
            directions: self.directions.clone(),
            done_per_light: self.done_per_light.clone(),
            per_light: self.directions.len() as u32,
            current_light: self.current_light,
            recent_pairs: self.recent_pairs.iter().cloned().collect(),
            alarms: self.alarms.iter().cloned().collect(),
            ticked: self.ticked.clone(),
            drift: self.drift.clone(),
            colour: self.colour.clone(),
            gain: self.gain.clone(),
            sweeps: self.sweeps.clone(),
        }
    }
}

/// A published snapshot: the value (for `/metrics`) and its JSON, serialised once per version
/// rather than once per reader.
pub(crate) struct Published {
    pub snapshot: Snapshot,
    pub json: String,
}

impl Published {
    pub(crate) fn new(snapshot: Snapshot) -> Self {
        let json = serde_json::to_string(&snapshot).unwrap_or_else(|_| "{}".into());
        Published { snapshot, json }
    }
}

/// Prometheus text exposition of a snapshot.
pub(crate) fn metrics(s: &Snapshot) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let mut g = |name: &str, help: &str, v: f64| {
        let _ = writeln!(out, "# HELP goniowatch_{name} {help}\n# TYPE goniowatch_{name} gauge\ngoniowatch_{name} {v}");
    };
    let c = &s.summary.checked;
    g(
        "captures_planned",
        "Captures in the sampling plan.",
        s.summary.captures_planned as f64,
    );
    g(
        "captures_checked",
        "Captures checked (including probes).",
        c.captures as f64,
    );
    g(
        "captures_failed",
        "Captures that could not be used.",
        c.failed as f64,
    );
    g(
        "captures_missing",
        "Announced captures whose file never appeared.",
        c.missing as f64,
    );
    g(
        "captures_remaining",
        "Plan captures not yet checked.",
        s.remaining as f64,
    );
    g(
        "pairs_exact",
        "Reciprocal pairs compared at the exact mirrored pose.",
        c.pairs_exact as f64,
    );
    g(
        "pairs_interpolated",
        "Occlusion substitutes compared with an interpolated partner.",
        c.pairs_interpolated as f64,
    );
    g(
        "table2_de2000_mean",
        "Mean CIEDE2000 over exact reciprocal pairs.",
        s.summary.table2.de2000,
    );
    g(
        "table2_de76_mean",
        "Mean CIE 1976 colour difference over exact reciprocal pairs.",
        s.summary.table2.de76,
    );
    g(
        "alarms_total",
        "Alarms raised in this session (every occurrence, repeats included).",
        s.summary.alarms.values().sum::<u64>() as f64,
    );
    g(
        "link_lines",
        "Lines received from the controller.",
        s.summary.link.lines as f64,
    );
    g(
        "link_crc_errors",
        "Lines with a bad checksum.",
        s.summary.link.crc_errors as f64,
    );
    g(
        "link_connects",
        "Times the serial port was opened.",
        s.summary.link.connects as f64,
    );
    g(
        "link_controller_reboots",
        "Controller reboots seen.",
        s.summary.link.reboots as f64,
    );
    g(
        "captures_encoder_mismatch",
        "Captures whose encoders disagreed with the commanded pose.",
        s.summary.checked.encoder_mismatch as f64,
    );
    g(
        "captures_placed_by_command",
        "Of those, captures placed by the commanded pose (a steady encoder offset).",
        s.summary.checked.placed_by_command as f64,
    );
    g(
        "table2_by_command_pairs",
        "Of the exact pairs, those with a capture placed by the commanded pose.",
        s.summary.by_command.pairs as f64,
    );
    g(
        "table2_by_command_de2000_mean",
        "Mean CIEDE2000 over the exact pairs with a capture placed by the commanded pose (0 without any).",
        s.summary.by_command.de2000,
    );
    g(
        "captures_pose_off_plan",
        "Captures whose pose was off the plan.",
        s.summary.checked.pose_off_plan as f64,
    );
    if let Some(r) = s.rate_per_h {
        g(
            "rate_captures_per_hour",
            "Captures checked per hour of wall time (last 5 min).",
            r,
        );
    }
    if let Some(d) = &s.summary.isotropy_drift {
        g(
            "isotropy_drift_rate_pct_per_h",
            "Gain drift estimated from isotropy classes.",
            d.rate_pct_per_h,
        );
        g(
            "isotropy_drift_rate_se_pct_per_h",
            "Standard error of that rate.",
            d.se_pct_per_h,
        );
    }
    if let Some(m) = &s.summary.sample_off_centre {
        g(
            "sample_off_centre_camera_pct",
            "The off-centre mount's pattern on the camera's side (% per unit tan θo), once modelled.",
            m.camera_pct().0,
        );
        g(
            "sample_off_centre_light_pct",
            "The same on the light's side (% per unit tan θi).",
            m.light_pct().0,
        );
    }
    if let Some(c) = &s.summary.colour_drift {
        g(
            "colour_drift_k_per_h",
            "The lamp's colour-temperature drift (K/h), from isotropy classes or else the probes (status.json names the source).",
            c.k_per_h,
        );
        g(
            "colour_drift_se_k_per_h",
            "Standard error of that rate (K/h).",
            c.se_k_per_h,
        );
        g(
            "colour_drift_de00_per_h",
            "ΔE00 per hour of a white surface at that rate.",
            c.de00_per_h,
        );
    }
    if let Some(sw) = &s.summary.sweeps {
        g(
            "sweeps_tested",
            "Light sweeps tested against the earlier ones.",
            sw.tested as f64,
        );
        if let Some(r) = &sw.last {
            g(
                "sweep_level_pct",
                "The last light sweep's gain level against the earlier ones (%).",
                r.level_pct,
            );
            g(
                "sweep_level_expected_pct",
                "The level its θ layer's earlier lights predict for it (%); the step test judges the difference.",
                r.level_expected_pct,
            );
            g(
                "sweep_level_se_pct",
                "Standard error of the last sweep's level (%).",
                r.level_se_pct,
            );
            for j in &r.joints {
                g(
                    &format!("sweep_joint{}_offset_deg", j.joint),
                    "The last light sweep's fitted offset of this arm joint (degrees; biased towards zero).",
                    j.offset_deg,
                );
                g(
                    &format!("sweep_joint{}_se_deg", j.joint),
                    "Standard error of that offset (degrees).",
                    j.se_deg,
                );
            }
        }
    }
    if let Some(d) = &s.summary.probe_drift {
        g(
            "drift_rate_pct_per_h",
            "Gain drift estimated from the probes.",
            d.rate_pct_per_h,
        );
        g(
            "drift_rate_se_pct_per_h",
            "Standard error of the drift rate.",
            d.se_pct_per_h,
        );
        g(
            "probe_scatter_pct",
            "The probes' scatter about their trend (% least-squares SD of the current segment; lamp-unstable judges two robust scales of its last 8 probes, about the trend and from one to the next, given in that alarm).",
            100.0 * d.residual_scale,
        );
    }
    if let Some(j) = &s.summary.joint3_sentinel {
        g(
            "sentinel_joint3_offset_deg",
            "Arm joint 3's turn from the sentinel probe's latest reading against the run's start (degrees; anisotropic samples).",
            j.offset_deg,
        );
        g(
            "sentinel_readings",
            "Sentinel probes read.",
            j.readings as f64,
        );
    }
    g(
        "finished",
        "1 when the run is over.",
        if s.summary.finished { 1.0 } else { 0.0 },
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::checks::alarm::{AlarmCode, Severity};

    fn capture(idx: u64, entry: usize, light: usize, probe: bool, y: f64) -> CaptureRecord {
        CaptureRecord {
            idx,
            entry,
            light,
            camera: 0,
            probe,
            sentinel: false,
            t: idx as f64 * 7.0,
            file: format!("c{idx}.hdr"),
            status: crate::checks::CaptureStatus::Ok,
            error: None,
            mean_rgb: None,
            xyz: Some([y, y, y]),
            lab: None,
            pixels: None,
            nonfinite: None,
            clipped: None,
            negative: None,
            angles: None,
            substitute: None,
            pose_error_deg: None,
            by_command: false,
            gain_corrected: None,
        }
    }

    #[test]
    fn snapshot_counts_coverage_probes_and_alarms_and_reloads_from_files() {
        let plan = SamplingPlan::ubo();
        let mut m = StatusModel::new(&plan, 0.5);
        let mut outputs = Vec::new();
        for idx in 0..100u64 {
            let e = plan.entry(idx as usize).unwrap();
            outputs.push(Output::Capture(capture(
                idx,
                idx as usize,
                e.light,
                false,
                50.0,
            )));
        }
        // a probe of entry 19 at 2 % less light
        outputs.push(Output::Capture(capture(100, 19, 0, true, 49.0)));
        outputs.push(Output::Alarm(
            Alarm::new(
                AlarmKind::CaptureQuality,
                Severity::Warning,
                AlarmCode::DarkCapture,
                "capture 7 is dark".to_string(),
            )
            .at(Some(7), Some(49.0)),
        ));
        // a completed light sweep 0.3 % above its layer's prediction, joint 2 fitted at +0.4°
        let sweep: SweepRecord = serde_json::from_str(
            r#"{"light":1,"idx":161,"t":1134.0,"captures":60,"level_pct":0.5,"level_expected_pct":0.2,"level_se_pct":0.1,"level_z":null,"level_cusum":0.0,"joints":[{"joint":2,"offset_deg":0.4,"se_deg":0.1,"z":null,"cusum":0.0}],"residual_sd":0.0,"thresholds":[3.2,3.5],"model_layers":1,"model_builds":1}"#,
        )
        .unwrap();
        outputs.push(Output::Sweep(sweep));
        for o in &outputs {
            m.record(o);
        }
        let mut summary = Summary::default();
        summary.captures_planned = 6561;
        summary.checked.captures = 101;
        summary.checked.probes = 1;
        let s = m.snapshot(&summary, 0.0);
        assert_eq!(s.remaining, 6561 - 100);
        assert_eq!(s.done_per_light[0], 81);
        assert_eq!(s.done_per_light[1], 19);
        assert_eq!(s.current_light, Some(1));
        assert_eq!(s.gain.len(), 1);
        assert!((s.gain[0].gain - 0.98).abs() < 1e-12);
        assert_eq!(s.alarms.len(), 1);
        // a capture-quality alarm is not ticked on the time plots
        assert!(s.ticked.is_empty());
        assert_eq!(s.sweeps.len(), 1);
        assert!((s.sweeps[0].level_pct - 0.3).abs() < 1e-12);
        assert_eq!(s.sweeps[0].joints, [(2, 0.4, 0.1)]);
        assert!((s.sweeps[0].t_h - 0.315).abs() < 1e-12);
        assert!(s.rate_per_h.is_none(), "no rate from one sample");
        summary.checked.captures = 201;
        let s2 = m.snapshot(&summary, 10.0);
        assert!((s2.rate_per_h.unwrap() - 36_000.0).abs() < 1e-6);

        // the same state read back from result files
        let dir = std::env::temp_dir().join(format!("gw-status-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut caps = String::new();
        let mut alarms = String::new();
        let mut sweeps = String::new();
        for o in &outputs {
            match o {
                Output::Capture(c) => caps += &(serde_json::to_string(c).unwrap() + "\n"),
                Output::Alarm(a) => alarms += &(serde_json::to_string(a).unwrap() + "\n"),
                Output::Sweep(r) => sweeps += &(serde_json::to_string(r).unwrap() + "\n"),
                _ => {}
            }
        }
        std::fs::write(dir.join("sweeps.jsonl"), sweeps).unwrap();
        std::fs::write(dir.join("captures.jsonl"), caps).unwrap();
        std::fs::write(dir.join("alarms.jsonl"), alarms + "{torn line").unwrap();
        let mut r = StatusModel::new(&plan, 0.5);
        r.load(&dir);
        let s3 = r.snapshot(&summary, 0.0);
        assert_eq!(s3.done_per_light, s.done_per_light);
        assert_eq!(s3.alarms.len(), 1);
        assert_eq!(s3.gain.len(), 1);
        assert_eq!(s3.sweeps.len(), 1);
        let _ = std::fs::remove_dir_all(&dir);

        let text = metrics(&s2);
        assert!(
            text.contains("goniowatch_captures_remaining 6361\n")
                && text.contains("goniowatch_captures_placed_by_command 0\n")
                && text.contains("goniowatch_table2_by_command_pairs 0\n"),
            "{text}"
        );
        assert!(text.contains("# TYPE goniowatch_rate_captures_per_hour gauge"));
        assert!(
            !text.contains("sweep"),
            "no sweep metrics where no sweep ran"
        );

        // the light sweeps' state, when they run
        let mut s4 = s2.clone();
        s4.summary.sweeps = Some(crate::detect::sweeps::SweepSummary {
            tested: 12,
            last: Some(crate::detect::sweeps::SweepRecord {
                light: 13,
                idx: 1133,
                t: 7931.0,
                captures: 70,
                level_pct: -0.4,
                level_expected_pct: 0.1,
                level_se_pct: 0.2,
                level_z: Some(-1.0),
                level_cusum: 0.0,
                joints: vec![crate::detect::sweeps::JointFit {
                    joint: 2,
                    offset_deg: 0.75,
                    se_deg: 0.1,
                    z: Some(2.0),
                    cusum: 1.0,
                }],
                residual_sd: 0.01,
                thresholds: [3.23, 3.57],
                wagon: None,
                model_layers: 2,
                model_builds: 3,
            }),
            wagon_watch: None,
        });
        let text = metrics(&s4);
        assert!(text.contains("goniowatch_sweeps_tested 12\n"), "{text}");
        assert!(
            text.contains("goniowatch_sweep_joint2_offset_deg 0.75\n"),
            "{text}"
        );
        assert!(text.contains("goniowatch_sweep_level_pct -0.4\n"), "{text}");
        assert!(text.contains("goniowatch_sweep_joint2_se_deg "), "{text}");
        assert!(
            text.contains("goniowatch_sweep_level_expected_pct "),
            "{text}"
        );

        // the probes' scatter and the joint-3 sentinel, when they run
        let mut s5 = s2.clone();
        s5.summary.probe_drift = Some(crate::detect::drift::DriftEstimate {
            pairs: 10,
            rate_pct_per_h: 0.1,
            se_pct_per_h: 0.05,
            residual_scale: 0.0025,
        });
        s5.summary.joint3_sentinel = Some(crate::detect::sentinel::SentinelSummary {
            pose: crate::detect::sentinel::SentinelPose {
                entry: 33,
                theta_o_deg: 45.0,
                phi_o_deg: 280.0,
                luminance: 30.0,
                sensitivity_pct_per_deg: -3.1,
            },
            readings: 12,
            offset_deg: 0.5,
        });
        let text = metrics(&s5);
        assert!(
            text.contains("goniowatch_probe_scatter_pct 0.25\n"),
            "{text}"
        );
        assert!(
            text.contains("goniowatch_sentinel_joint3_offset_deg 0.5\n"),
            "{text}"
        );
        assert!(text.contains("goniowatch_sentinel_readings 12\n"), "{text}");
    }
}
