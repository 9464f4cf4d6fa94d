//! The fixed parts of a session, built from its configuration once: the sampling plan, the rig
//! model, the colour conversion of the live checks and the lamp probe's entry. `config` stays
//! plain data (the file's types and their validation); everything built from it is built here.

use crate::archive::SourceKind;
use crate::checks::ColourSettings;
use crate::config::{Config, ConfigError, WhiteSpec};
use crate::detect::probe_plan::{design, ColourProbes, DetectionTarget, ProbePlan, ProbeSession};
use crate::detect::probes::{ProbeEvery, ProbeSpec};
use crate::measure::colour::{RgbToXyz, White};
use crate::measure::kinematics::Rig;
use crate::measure::plan::SamplingPlan;

/// What a session's checker is built from.
#[derive(Debug, Clone)]
pub(crate) struct Setup {
    pub plan: SamplingPlan,
    pub rig: Rig,
    pub colour: ColourSettings,
    /// The lamp probe's entry when `[probes] entry` names one (else the daemon chooses it).
    pub probe_entry: Option<usize>,
    /// `[probes]` with the cadence resolved (`probe_cadence`).
    pub probes: ProbeSpec,
}

impl Setup {
    pub(crate) fn new(cfg: &Config) -> Result<Setup, ConfigError> {
        let plan = plan(cfg)?;
        let probe_entry = match cfg.probes.entry {
            Some(_) => Some(probe_entry(cfg, &plan)?),
            None => None,
        };
        let every = probe_cadence(cfg)?.every;
        Ok(Setup {
            rig: rig(cfg)?,
            colour: colour_settings(cfg)?,
            probe_entry,
            probes: ProbeSpec {
                every: ProbeEvery::Captures(every),
                ..cfg.probes.clone()
            },
            plan,
        })
    }
}

/// The sampling plan of `[plan]`.
pub fn plan(cfg: &Config) -> Result<SamplingPlan, ConfigError> {
    Ok(SamplingPlan::new(&cfg.plan)?)
}

/// The rig model of `[rig]`.
pub fn rig(cfg: &Config) -> Result<Rig, ConfigError> {
    Ok(Rig::new(cfg.rig.clone())?)
}

/// Mean linear RGB → XYZ by `[colour] primaries` (scaled by `rgb_scale` before it).
pub(crate) fn rgb_to_xyz(cfg: &Config) -> RgbToXyz {
    RgbToXyz::new(cfg.colour.primaries)
}

/// The white for L*a*b* in the live checks (a reference-capture white is for offline use).
pub(crate) fn live_white(cfg: &Config) -> Result<White, ConfigError> {
    match cfg.colour.white {
        WhiteSpec::ReferenceCapture { .. } => Err(ConfigError::Invalid {
            field: "colour.white",
            message: "kind = \"reference-capture\" is not available to the live checks yet; use \"d65\" or \"xyz\"".into(),
        }),
        w => w.resolve(None).map_err(|source| ConfigError::Colour {
            field: "colour.white",
            source,
        }),
    }
}

/// The colour settings of the live checks.
pub(crate) fn colour_settings(cfg: &Config) -> Result<ColourSettings, ConfigError> {
    Ok(ColourSettings {
        to_xyz: rgb_to_xyz(cfg),
        rgb_scale: cfg.colour.scale(),
        white: live_white(cfg)?,
        min_cos: cfg.reciprocity.min_cos,
    })
}

/// The plan entry re-captured by probes: the configured one, or lamp at the pole and camera at
/// the first direction with θ = 45°.
pub fn probe_entry(cfg: &Config, plan: &SamplingPlan) -> Result<usize, ConfigError> {
    if let Some(e) = cfg.probes.entry {
        if e < plan.capture_count() {
            return Ok(e);
        }
        return Err(ConfigError::Invalid {
            field: "probes.entry",
            message: format!("{e} is not a plan entry (0..{})", plan.capture_count()),
        });
    }
    let dirs = plan.directions();
    let light = dirs.iter().position(|d| d.theta_deg == 0.0);
    let camera = dirs.iter().position(|d| (d.theta_deg - 45.0).abs() < 1e-9);
    match (light, camera) {
        (Some(l), Some(c)) => plan.index_of(l, c).ok_or(ConfigError::Invalid {
            field: "probes.entry",
            message: "no default probe entry in this plan; set one".into(),
        }),
        _ => Err(ConfigError::Invalid {
            field: "probes.entry",
            message: "the plan has no θ = 0 and θ = 45° directions for the default probe; set one"
                .into(),
        }),
    }
}

/// The capture interval the probe design and the identifiability figures assume (the UBO
/// rig's, 7 s).
pub(crate) const SECONDS_PER_CAPTURE: f64 = 7.0;

/// Whether probe rounds carry a joint-3 sentinel (`detect::sentinel`): anisotropic samples.
pub(crate) fn sentinel(cfg: &Config) -> bool {
    !cfg.sample.isotropic && cfg.probes.sentinel
}

/// The probes' scatter against their original capture that the design assumes (% SD).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ProbeScatter {
    /// Of the luminance ratio.
    pub luminance_pct: f64,
    /// Of ln X/Y and of ln Z/Y, each.
    pub chromaticity_pct: f64,
}

impl ProbeScatter {
    /// `[probes] design_scatter_pct` for both.
    pub(crate) fn configured(cfg: &Config) -> Self {
        ProbeScatter {
            luminance_pct: cfg.probes.design_scatter_pct,
            chromaticity_pct: cfg.probes.design_scatter_pct,
        }
    }
}

/// The session the probe design plans for: the plan's captures, the rig's capture interval,
/// the probe's anchor and the colour check the probes feed.
pub(crate) fn probe_session(
    cfg: &Config,
    plan: &SamplingPlan,
    scatter: ProbeScatter,
) -> Result<ProbeSession, ConfigError> {
    Ok(ProbeSession {
        captures: plan.capture_count() as u64,
        seconds_per_capture: SECONDS_PER_CAPTURE,
        // on an anisotropic sample each probe round is a lamp probe and a joint-3 sentinel
        seconds_per_probe: if sentinel(cfg) {
            2.0 * SECONDS_PER_CAPTURE
        } else {
            SECONDS_PER_CAPTURE
        },
        // a pose the daemon chooses is among the first sweep's captures: the default pose, or
        // the middle of the first sweep, stands in for it
        anchor: match cfg.probes.entry {
            Some(_) => probe_entry(cfg, plan)? as u64,
            None => probe_entry(cfg, plan).unwrap_or(plan.direction_count() / 2) as u64,
        },
        probes_from: if cfg.probes.entry.is_some() {
            0
        } else {
            plan.direction_count() as u64
        },
        scatter_pct: scatter.luminance_pct,
        // an isotropic sample's colour is watched by its isotropy classes without probes
        // (BENCHMARKS.md, "The lamp's colour drift"): the probes are not designed for it
        colour: (!cfg.sample.isotropic).then_some(ColourProbes {
            lamp_cct_k: cfg.checks.colour_drift.lamp_cct_k,
            tolerance_k_per_h: cfg.checks.colour_drift.tolerance_k_per_h,
            z: cfg.checks.colour_drift.z,
            scatter_pct: scatter.chromaticity_pct,
        }),
    })
}

/// A session's probe cadence and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ProbeCadence {
    /// A probe round every this many regular captures (0: none).
    pub every: u64,
    pub origin: CadenceOrigin,
    /// The run time the rounds add, hours and % of the run without them (the design's
    /// session: `SECONDS_PER_CAPTURE` a capture).
    pub overhead_h: f64,
    pub overhead_pct: f64,
    /// The wagon's re-captured pair (`detect::sweeps::wagon_watch`) where the session runs it:
    /// about how many re-captures it takes, and the run time they add (hours, %).
    pub wagon_watch: Option<(u64, f64, f64)>,
}

/// Where a session's probe cadence came from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum CadenceOrigin {
    /// `[probes] every = N`.
    Configured,
    /// `every = "auto"`: the sparsest cadence that meets the default detection target.
    Designed,
    /// `every = "auto"` and no candidate meets the target: the densest one tried, and why.
    DesignedShort { reason: String },
    /// `every = "auto"` on a files source, which cannot take probes.
    NoController,
}

/// The probe cadence of a session: `[probes] every` as configured, or for `"auto"` the one
/// `goniowatch plan` designs for the configured sample and the default detection target
/// (deterministic: a replay resolves it to the same cadence).
pub(crate) fn probe_cadence(cfg: &Config) -> Result<ProbeCadence, ConfigError> {
    let plan = plan(cfg)?;
    let session = |every: u64| -> Result<(ProbeSession, f64, f64), ConfigError> {
        let s = probe_session(cfg, &plan, ProbeScatter::configured(cfg))?;
        let run_h = s.captures as f64 * s.seconds_per_capture / 3600.0;
        // rounds asked at every multiple of the cadence from `probes_from` to the last capture
        let rounds = match every {
            0 => 0,
            n => {
                let asked = |upto: u64| upto.saturating_sub(1) / n;
                asked(s.captures) - asked(s.probes_from).min(asked(s.captures))
            }
        };
        let h = rounds as f64 * s.seconds_per_probe / 3600.0;
        Ok((s, h, if run_h > 0.0 { 100.0 * h / run_h } else { 0.0 }))
    };
    let every = match cfg.probes.every {
        ProbeEvery::Captures(every) => {
            let (_, overhead_h, overhead_pct) = session(every)?;
            return Ok(ProbeCadence {
                every,
                origin: CadenceOrigin::Configured,
                overhead_h,
                overhead_pct,
                wagon_watch: wagon_watch_cost(cfg, &plan, every),
            });
        }
        ProbeEvery::Auto if cfg.source.kind == SourceKind::Files => {
            return Ok(ProbeCadence {
                every: 0,
                origin: CadenceOrigin::NoController,
                overhead_h: 0.0,
                overhead_pct: 0.0,
                wagon_watch: None,
            })
        }
        ProbeEvery::Auto => {
            let (s, _, _) = session(0)?;
            design(&s, &cfg.probes, &DetectionTarget::default()).map_err(|e| {
                ConfigError::Invalid {
                    field: "probes.every",
                    message: format!("\"auto\" cannot design the probes: {e}"),
                }
            })?
        }
    };
    let (every, origin) = match every {
        ProbePlan::Recommended { cadence, .. } => (cadence.every, CadenceOrigin::Designed),
        ProbePlan::Unreachable { reason, tried } => match tried.last() {
            Some(densest) => (densest.every, CadenceOrigin::DesignedShort { reason }),
            None => {
                return Err(ConfigError::Invalid {
                    field: "probes.every",
                    message: format!(
                        "\"auto\" finds no cadence for this plan ({reason}); set a number"
                    ),
                })
            }
        },
    };
    let (_, overhead_h, overhead_pct) = session(every)?;
    Ok(ProbeCadence {
        every,
        origin,
        overhead_h,
        overhead_pct,
        wagon_watch: wagon_watch_cost(cfg, &plan, every),
    })
}

/// About how many re-captures the wagon watch takes and the run time they add (hours, % of the run), when
/// a session with probes every `every` captures runs it: an isotropic sample in a light-outer
/// order with the light sweeps and `wagon_watch_sweeps` on.
fn wagon_watch_cost(cfg: &Config, plan: &SamplingPlan, every: u64) -> Option<(u64, f64, f64)> {
    let sw = &cfg.checks.sweeps;
    let runs = every > 0
        && cfg.sample.isotropic
        && sw.enabled
        && sw.wagon_watch_sweeps > 0
        && !matches!(
            plan.order(),
            crate::measure::plan::AcquisitionOrder::CameraOuter
        );
    if !runs {
        return None;
    }
    let captures = 2 * crate::detect::sweeps::wagon_watch_questions(
        plan.direction_count(),
        sw.wagon_watch_sweeps,
    );
    let run_h = plan.capture_count() as f64 * SECONDS_PER_CAPTURE / 3600.0;
    let h = captures as f64 * SECONDS_PER_CAPTURE / 3600.0;
    Some((
        captures,
        h,
        if run_h > 0.0 { 100.0 * h / run_h } else { 0.0 },
    ))
}

impl ProbeCadence {
    /// One line for the operator at the start of a session.
    pub(crate) fn describe(&self) -> String {
        let mut cost = format!(
            "adds {:.2} h, {:.1} % of the run",
            self.overhead_h, self.overhead_pct
        );
        if let Some((n, h, pct)) = self.wagon_watch {
            cost.push_str(&format!(
                "; the wagon's re-captured pair about {n} more captures, {h:.2} h, {pct:.1} %"
            ));
        }
        match (&self.origin, self.every) {
            (CadenceOrigin::NoController, _) => {
                "drift probes: every = \"auto\" → none (a files source cannot take probes; the lamp is watched from the pairs and the sweeps)".into()
            }
            (CadenceOrigin::Configured, 0) => {
                "drift probes: off ([probes] every = 0; the lamp is watched from the pairs and the sweeps)".into()
            }
            (CadenceOrigin::Configured, n) => {
                format!("drift probes: a round every {n} captures ({cost})")
            }
            (CadenceOrigin::Designed, n) => format!(
                "drift probes: every = \"auto\" → a round every {n} captures, the sparsest that meets the default target of `goniowatch plan` ({cost})"
            ),
            (CadenceOrigin::DesignedShort { reason }, n) => format!(
                "drift probes: every = \"auto\" → a round every {n} captures, the densest tried; it does not meet the default target: {reason} ({cost})"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped(name: &str) -> Config {
        let path = format!("{}/config/{name}", env!("CARGO_MANIFEST_DIR"));
        Config::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    #[test]
    fn auto_resolves_to_the_cadence_plan_designs_and_a_count_is_kept() {
        let mut cfg = shipped("sim.toml");
        cfg.probes.every = ProbeEvery::Auto;
        let c = probe_cadence(&cfg).unwrap();
        let plan = plan(&cfg).unwrap();
        let designed = match design(
            &probe_session(&cfg, &plan, ProbeScatter::configured(&cfg)).unwrap(),
            &cfg.probes,
            &DetectionTarget::default(),
        )
        .unwrap()
        {
            ProbePlan::Recommended { cadence, .. } => cadence,
            other => panic!("{other:?}"),
        };
        assert_eq!(c.every, designed.every);
        assert_eq!(c.origin, CadenceOrigin::Designed);
        assert!(
            (c.overhead_pct - designed.overhead_pct).abs() < 1e-9,
            "{c:?}"
        );
        assert!(c.overhead_pct > 0.0 && c.overhead_pct < 1.0, "{c:?}");
        // deterministic: a replay resolves the same cadence
        assert_eq!(probe_cadence(&cfg).unwrap(), c);
        assert!(c
            .describe()
            .contains(&format!("a round every {} captures", c.every)));
        // the engine is built with it
        assert_eq!(Setup::new(&cfg).unwrap().probes.cadence(), c.every);

        cfg.probes.every = ProbeEvery::Captures(75);
        let c = probe_cadence(&cfg).unwrap();
        assert_eq!((c.every, c.origin.clone()), (75, CadenceOrigin::Configured));
        assert!(c.overhead_pct > 0.0);
        cfg.probes.every = ProbeEvery::Captures(0);
        let off = probe_cadence(&cfg).unwrap();
        assert_eq!((off.every, off.overhead_h), (0, 0.0));
        assert!(off.describe().contains("off"));
    }

    #[test]
    fn auto_takes_no_probes_on_a_files_source() {
        let mut cfg = shipped("archive.toml");
        cfg.probes.every = ProbeEvery::Auto;
        let c = probe_cadence(&cfg).unwrap();
        assert_eq!(
            (c.every, c.origin.clone()),
            (0, CadenceOrigin::NoController)
        );
        assert_eq!(Setup::new(&cfg).unwrap().probes.cadence(), 0);
    }

    #[test]
    fn the_real_rig_config_takes_the_designed_probes() {
        let cfg = shipped("ubo.toml");
        assert_eq!(cfg.probes.every, ProbeEvery::Auto);
        let c = probe_cadence(&cfg).unwrap();
        assert!(c.every > 0 && c.overhead_pct < 1.0, "{c:?}");
        // an isotropic sample in the UBO order: the wagon's pair too, under 1 % of the run
        let (n, _, pct) = c.wagon_watch.unwrap();
        assert!(n > 0 && pct < 1.0, "{c:?}");
        assert!(c.describe().contains("the wagon's re-captured pair"));
        let mut off = cfg.clone();
        off.checks.sweeps.wagon_watch_sweeps = 0;
        assert_eq!(probe_cadence(&off).unwrap().wagon_watch, None);
    }
}
