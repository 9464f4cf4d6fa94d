//! The drift stage (isotropic samples only): the lamp's gain over the run from repeated
//! geometry. Every capture at its exact pose is compared with the first capture of the same
//! (θi, θo, |Δφ|), the same geometry at another time, so ln(Y/Y₀) is the gain change; the
//! occlusion substitutes' interpolated pairs join in buckets of their own, weighted by their
//! spread; gain steps found by the light sweeps enter as step terms. Rate alarms only: see
//! `measure::drift` for why steps are left to the sweeps and the probes.

use super::pairs::PendingPartner;
use super::records::{PairRecord, PairStatus};
use super::{Ctx, GeometryKey, Ledger};
use crate::measure::alarm::{Alarm, AlarmKind, Severity};
use crate::measure::drift::{
    DriftDetector, DriftEstimate, DriftEvent, DriftSpec, PairObservation, StepEffect,
};
use serde_json::json;
use std::collections::HashMap;

pub(super) struct DriftStage {
    detector: DriftDetector,
    /// The first capture of each geometry: (time in hours, Y).
    first_of_geometry: HashMap<GeometryKey, (f64, f64)>,
    /// Interpolated pairs fed to the fit.
    pub(super) interpolated: u64,
}

impl DriftStage {
    pub(super) fn new() -> Self {
        DriftStage {
            detector: DriftDetector::new(DriftSpec {
                // about 6,561 − 1,378 observations in a UBO run
                run_pairs: 5200.0,
                // rate only: consecutive observations share neighbouring geometry, so their
                // residuals are correlated and heavy-tailed and the CUSUM's ARL design does not
                // hold; steps are the sweeps' and the probes' job
                step_detection: false,
                ..DriftSpec::default()
            }),
            first_of_geometry: HashMap::new(),
            interpolated: 0,
        }
    }

    /// A capture of `key` at time `t_s` with luminance `y`: an observation against the first
    /// capture of its geometry, or that first capture.
    pub(super) fn observe(
        &mut self,
        key: GeometryKey,
        t_s: f64,
        y: f64,
        at: (Option<u64>, Option<f64>),
        alarms: &mut Vec<Alarm>,
    ) {
        let t_h = t_s / 3600.0;
        match self.first_of_geometry.get(&key) {
            Some(&(t0, y0)) => {
                let obs = PairObservation {
                    t_a_h: t0,
                    t_b_h: t_h,
                    d: (y / y0).ln(),
                    bucket: (key.0, key.1),
                    sigma: 0.0,
                };
                for ev in self.detector.add(obs) {
                    alarms.push(drift_alarm(ev, "isotropy classes", at));
                }
            }
            None => {
                self.first_of_geometry.insert(key, (t_h, y));
            }
        }
    }

    /// A gain step found by the light sweeps, starting at `t_s`, becomes a step term.
    pub(super) fn add_step(&mut self, t_s: f64) {
        self.detector.add_step(t_s / 3600.0);
    }

    /// An interpolated pair in the fit: the substitute against its partner interpolated at the
    /// mirrored pose, timed at the mean time of the partner light's captures, in a bucket of its
    /// own per (θ light, θ camera) so that the pair's stationary non-reciprocity is a fixed
    /// effect, and weighted by the interpolation's relative spread.
    pub(super) fn observe_interpolated(
        &mut self,
        ctx: &Ctx,
        ledger: &Ledger,
        p: &PendingPartner,
        pair: &PairRecord,
        alarms: &mut Vec<Alarm>,
    ) {
        if pair.status != PairStatus::Interpolated {
            return;
        }
        let (Some(a), Some(b), Some(info)) = (pair.xyz_a, pair.xyz_b, &pair.interpolated) else {
            return;
        };
        let Some(spread) = info.spread_xyz else {
            return;
        };
        let Some(t_partner) = ledger.light_mean_time(ctx.plan, p.light) else {
            return;
        };
        if !(a[1] > 0.0 && b[1] > 0.0) {
            return;
        }
        let Ok(pe) = ctx.plan.entry(p.entry) else {
            return;
        };
        let dirs = ctx.plan.directions();
        let bucket = (
            -1 - (dirs[pe.light].theta_deg * 1000.0).round() as i64,
            (dirs[pe.camera].theta_deg * 1000.0).round() as i64,
        );
        let (t_sub, t_par) = (p.capture.t / 3600.0, t_partner / 3600.0);
        // d = ln(Y later / Y earlier)
        let (t_a_h, t_b_h, d) = if t_sub <= t_par {
            (t_sub, t_par, (b[1] / a[1]).ln())
        } else {
            (t_par, t_sub, (a[1] / b[1]).ln())
        };
        let obs = PairObservation {
            t_a_h,
            t_b_h,
            d,
            bucket,
            sigma: (spread[1] / b[1]).abs(),
        };
        if !(obs.d.is_finite() && obs.sigma.is_finite()) {
            return;
        }
        let at = (Some(p.capture.idx), Some(p.capture.t));
        for ev in self.detector.add(obs) {
            alarms.push(drift_alarm(ev, "isotropy classes", at));
        }
        self.interpolated += 1;
    }

    /// ln g(t) and its standard uncertainty at `t_h` hours, once there is an estimate.
    pub(super) fn ln_gain_at(&self, t_h: f64) -> Option<(f64, f64)> {
        self.detector.ln_gain_at(t_h)
    }

    pub(super) fn estimate(&self) -> Option<DriftEstimate> {
        self.detector.estimate()
    }

    pub(super) fn steps(&self) -> &[StepEffect] {
        self.detector.steps()
    }
}

/// The alarm for a drift event of `source` (isotropy classes or probes).
pub(super) fn drift_alarm(ev: DriftEvent, source: &str, at: (Option<u64>, Option<f64>)) -> Alarm {
    match ev {
        DriftEvent::RateSignificant(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            "gain-drift",
            format!(
                "the gain drifts by {:+.2} %/h (± {:.2} %/h standard error, from {} {source}); beyond the tolerance",
                e.rate_pct_per_h, e.se_pct_per_h, e.pairs
            ),
        )
        .at(at.0, at.1)
        .with(json!({"rate_pct_per_h": e.rate_pct_per_h, "se_pct_per_h": e.se_pct_per_h, "n": e.pairs, "source": source})),
        DriftEvent::RateCleared(e) => Alarm::new(
            AlarmKind::Drift,
            Severity::Info,
            "gain-drift-cleared",
            format!(
                "the gain drift estimate is back within the tolerance: {:+.2} ± {:.2} %/h ({source})",
                e.rate_pct_per_h, e.se_pct_per_h
            ),
        )
        .at(at.0, at.1),
        DriftEvent::Step { direction, statistic, threshold, pairs_since_reset } => Alarm::new(
            AlarmKind::Drift,
            Severity::Warning,
            "gain-step",
            format!(
                "the gain stepped {}: the latest of the {source} departs from the trend of the previous {pairs_since_reset} by {statistic:.1} standard deviations (threshold {threshold})",
                if direction > 0 { "up" } else { "down" }
            ),
        )
        .at(at.0, at.1)
        .with(json!({"direction": direction, "statistic": statistic, "threshold": threshold, "source": source})),
    }
}
