//! The fixed parts of a session, built from its configuration once: the sampling plan, the rig
//! model, the colour conversion of the live checks and the lamp probe's entry. `config` stays
//! plain data (the file's types and their validation); everything built from it is built here.

use crate::checks::ColourSettings;
use crate::config::{Config, ConfigError, WhiteSpec};
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
}

impl Setup {
    pub(crate) fn new(cfg: &Config) -> Result<Setup, ConfigError> {
        let plan = plan(cfg)?;
        let probe_entry = match cfg.probes.entry {
            Some(_) => Some(probe_entry(cfg, &plan)?),
            None => None,
        };
        Ok(Setup {
            rig: rig(cfg)?,
            colour: colour_settings(cfg)?,
            probe_entry,
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
