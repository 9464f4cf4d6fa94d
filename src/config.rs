//! The rig/session configuration file (TOML, `deny_unknown_fields` everywhere).
//!
//! Parsing is pure ([`Config::from_toml_str`]); reading the file is the caller's job. Errors name
//! the offending field (serde's message plus the TOML key path and line).

use crate::daemon::ingest::IngestSpec;
use crate::daemon::link::LinkSpec;
use crate::engine::EngineSpec;
use crate::measure::averaging::AverageOptions;
use crate::measure::checks::CheckSpec;
use crate::measure::colour::{ColourError, RgbPrimaries, RgbToXyz, White, Xyz};
use crate::measure::kinematics::{KinematicsError, Rig, RigSpec};
use crate::measure::plan::{PlanError, PlanSpec, SamplingPlan};
use crate::measure::reciprocity::DEFAULT_MIN_COS;
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ConfigError {
    #[error("cannot read config {path}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("config: {0}")]
    Parse(String),
    #[error("config: {0}")]
    Plan(#[from] PlanError),
    #[error("config: {0}")]
    Rig(#[from] KinematicsError),
    #[error("config: {field}: {source}")]
    Colour {
        field: &'static str,
        source: ColourError,
    },
    #[error("config: {field}: {message}")]
    Invalid {
        field: &'static str,
        message: String,
    },
}

/// How the L*a*b* white is chosen. Uncalibrated HDR data has no absolute white, so the white is
/// a convention that must be the same for both captures of every comparison; ΔE values scale
/// with it. See ARCHITECTURE.md ("Choosing the white").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum WhiteSpec {
    /// D65 chromaticity at luminance `y` (default: y = 100, with `rgb_scale` bringing the
    /// captures to the paper's 0–100 scale).
    D65 {
        #[serde(default = "hundred")]
        y: f64,
    },
    /// An explicit XYZ white.
    Xyz { xyz: Xyz },
    /// The XYZ of a reference capture (e.g. a white standard photographed first), given by
    /// its capture index; resolved by the daemon once that capture is in.
    ReferenceCapture { index: usize },
}

fn hundred() -> f64 {
    100.0
}

impl Default for WhiteSpec {
    fn default() -> Self {
        WhiteSpec::D65 { y: 100.0 }
    }
}

impl WhiteSpec {
    /// The white, given the reference capture's XYZ when the spec asks for one.
    pub fn resolve(&self, reference: Option<Xyz>) -> Result<White, ColourError> {
        match *self {
            WhiteSpec::D65 { y } => White::d65_scaled(y),
            WhiteSpec::Xyz { xyz } => White::new(xyz),
            WhiteSpec::ReferenceCapture { .. } => White::new(reference.unwrap_or([0.0; 3])),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourSpec {
    #[serde(default)]
    pub primaries: RgbPrimaries,
    /// Multiplies the mean RGB before conversion (brings uncalibrated HDR values to a 0–100
    /// scale like the paper's).
    #[serde(default = "one")]
    pub rgb_scale: f64,
    #[serde(default)]
    pub white: WhiteSpec,
}

fn one() -> f64 {
    1.0
}

impl Default for ColourSpec {
    fn default() -> Self {
        ColourSpec {
            primaries: RgbPrimaries::default(),
            rgb_scale: 1.0,
            white: WhiteSpec::default(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampleSpec {
    /// Declared isotropic: isotropy classes are checked. An anisotropic sample skips them.
    #[serde(default = "yes")]
    pub isotropic: bool,
    /// Free text for reports.
    #[serde(default)]
    pub name: String,
}

fn yes() -> bool {
    true
}

impl Default for SampleSpec {
    fn default() -> Self {
        SampleSpec {
            isotropic: true,
            name: String::new(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReciprocitySpec {
    /// Pairs with cos θᵢ below this are not compared (grazing).
    #[serde(default = "default_min_cos")]
    pub min_cos: f64,
}

fn default_min_cos() -> f64 {
    DEFAULT_MIN_COS
}

impl Default for ReciprocitySpec {
    fn default() -> Self {
        ReciprocitySpec {
            min_cos: DEFAULT_MIN_COS,
        }
    }
}

/// `[alarms]`: where alarms go besides the log and `alarms.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AlarmSpec {
    /// A command run for every alarm, with the alarm as JSON on its standard input, e.g.
    /// `["/usr/local/bin/notify-lab", "--channel", "rig"]`. Empty: none.
    pub hook: Vec<String>,
    /// Ask the controller to pause on a critical alarm (off by default; the rig may refuse).
    pub pause_on_critical: bool,
    /// A link alarm when this many of the last `crc_window` lines are corrupt.
    pub crc_errors_alarm: usize,
    pub crc_window: usize,
}

impl Default for AlarmSpec {
    fn default() -> Self {
        let e = EngineSpec::default();
        AlarmSpec {
            hook: Vec::new(),
            pause_on_critical: e.pause_on_critical,
            crc_errors_alarm: e.crc_errors_alarm,
            crc_window: e.crc_window,
        }
    }
}

impl AlarmSpec {
    pub fn engine(&self) -> EngineSpec {
        EngineSpec {
            pause_on_critical: self.pause_on_critical,
            crc_errors_alarm: self.crc_errors_alarm,
            crc_window: self.crc_window,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Config {
    #[serde(default)]
    pub sample: SampleSpec,
    #[serde(default)]
    pub plan: PlanSpec,
    #[serde(default)]
    pub rig: RigSpec,
    #[serde(default)]
    pub colour: ColourSpec,
    #[serde(default)]
    pub capture: AverageOptions,
    #[serde(default)]
    pub reciprocity: ReciprocitySpec,
    #[serde(default)]
    pub checks: CheckSpec,
    #[serde(default)]
    pub probes: crate::measure::probes::ProbeSpec,
    #[serde(default)]
    pub alarms: AlarmSpec,
    #[serde(default)]
    pub link: LinkSpec,
    #[serde(default)]
    pub ingest: IngestSpec,
    #[serde(default)]
    pub http: HttpSpec,
}

/// `[http]`: the status page of `run --http ADDR`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct HttpSpec {
    /// Serve on a non-loopback address (the page has no authentication). Off by default.
    pub allow_remote: bool,
}

impl Config {
    /// Read, parse and validate a config file; also returns its text.
    pub fn load(path: &std::path::Path) -> Result<(Config, String), ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Ok((Self::from_toml_str(&text)?, text))
    }

    /// Parse and validate a config file's text.
    pub fn from_toml_str(text: &str) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| ConfigError::Parse(e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        SamplingPlan::new(&self.plan)?;
        Rig::new(self.rig.clone())?;
        if !(self.colour.rgb_scale.is_finite() && self.colour.rgb_scale > 0.0) {
            return Err(ConfigError::Invalid {
                field: "colour.rgb_scale",
                message: format!("{} is not a finite positive number", self.colour.rgb_scale),
            });
        }
        if !matches!(self.colour.white, WhiteSpec::ReferenceCapture { .. }) {
            self.colour
                .white
                .resolve(None)
                .map_err(|source| ConfigError::Colour {
                    field: "colour.white",
                    source,
                })?;
        }
        if !(self.capture.clip_level.is_finite() && self.capture.clip_level > 0.0) {
            return Err(ConfigError::Invalid {
                field: "capture.clip_level",
                message: format!(
                    "{} is not a finite positive number",
                    self.capture.clip_level
                ),
            });
        }
        if let crate::measure::averaging::Roi::MarginFraction { fraction } = self.capture.roi {
            if !(0.0..0.5).contains(&fraction) {
                return Err(ConfigError::Invalid {
                    field: "capture.roi.fraction",
                    message: format!("{fraction} is not in [0, 0.5)"),
                });
            }
        }
        if !(self.reciprocity.min_cos > 0.0 && self.reciprocity.min_cos < 1.0) {
            return Err(ConfigError::Invalid {
                field: "reciprocity.min_cos",
                message: format!("{} is not in (0, 1)", self.reciprocity.min_cos),
            });
        }
        if self.ingest.workers == 0 || self.ingest.queue == 0 {
            return Err(ConfigError::Invalid {
                field: "ingest.workers",
                message: "workers and queue must be at least 1".into(),
            });
        }
        if !(self.ingest.give_up_s.is_finite() && self.ingest.give_up_s >= 0.0) {
            return Err(ConfigError::Invalid {
                field: "ingest.give_up_s",
                message: format!(
                    "{} is not a finite non-negative number",
                    self.ingest.give_up_s
                ),
            });
        }
        if self.probes.every > 0 {
            self.probe_entry()?;
        }
        if self.alarms.crc_window == 0 {
            return Err(ConfigError::Invalid {
                field: "alarms.crc_window",
                message: "must be at least 1".into(),
            });
        }
        for (field, v) in [
            ("checks.pair_tolerance_deg", self.checks.pair_tolerance_deg),
            ("checks.pose_tolerance_deg", self.checks.pose_tolerance_deg),
            (
                "checks.encoder_tolerance_deg",
                self.checks.encoder_tolerance_deg,
            ),
            ("checks.outlier_k", self.checks.outlier_k),
            (
                "checks.clipped_fraction_max",
                self.checks.clipped_fraction_max,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ConfigError::Invalid {
                    field,
                    message: format!("{v} is not a finite non-negative number"),
                });
            }
        }
        let sw = &self.checks.sweeps;
        for (field, v, min) in [
            (
                "checks.sweeps.joint_tolerance_deg",
                sw.joint_tolerance_deg,
                0.0,
            ),
            (
                "checks.sweeps.level_tolerance_pct",
                sw.level_tolerance_pct,
                0.0,
            ),
            ("checks.sweeps.cusum_k", sw.cusum_k, 0.0),
            ("checks.sweeps.clip", sw.clip, f64::MIN_POSITIVE),
            ("checks.sweeps.false_alarm_runs", sw.false_alarm_runs, 1.0),
            (
                "checks.sweeps.sensitivity_step_deg",
                sw.sensitivity_step_deg,
                0.01,
            ),
        ] {
            if !(v.is_finite() && v >= min) {
                return Err(ConfigError::Invalid {
                    field,
                    message: format!("{v} is not a finite number ≥ {min}"),
                });
            }
        }
        if sw.sensitivity_step_deg > 10.0 {
            return Err(ConfigError::Invalid {
                field: "checks.sweeps.sensitivity_step_deg",
                message: format!("{} is larger than 10°", sw.sensitivity_step_deg),
            });
        }
        if sw.min_captures < 4 {
            return Err(ConfigError::Invalid {
                field: "checks.sweeps.min_captures",
                message: format!(
                    "{} is below 4 (the fit has three coefficients)",
                    sw.min_captures
                ),
            });
        }
        Ok(())
    }

    /// The white for L*a*b* in the live checks (a reference-capture white is for offline use).
    pub fn live_white(&self) -> Result<White, ConfigError> {
        match self.colour.white {
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

    /// The checker and engine for a session with this configuration.
    pub fn engine(&self) -> Result<crate::engine::Engine, ConfigError> {
        use crate::measure::checks::{Checker, ColourSettings};
        let checker = Checker::new(
            self.plan()?,
            self.rig()?,
            ColourSettings {
                to_xyz: self.rgb_to_xyz(),
                rgb_scale: self.colour.rgb_scale,
                white: self.live_white()?,
                min_cos: self.reciprocity.min_cos,
            },
            self.checks.clone(),
            self.sample.isotropic,
            self.probes.clone(),
        );
        let mut engine = crate::engine::Engine::new(checker, self.alarms.engine());
        if self.probes.every > 0 {
            engine.set_probes(self.probes.every, self.probe_entry()?);
        }
        Ok(engine)
    }

    /// The plan entry re-captured by probes: the configured one, or lamp at the pole and camera
    /// at the first direction with θ = 45°.
    pub fn probe_entry(&self) -> Result<usize, ConfigError> {
        let plan = self.plan()?;
        if let Some(e) = self.probes.entry {
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
                message:
                    "the plan has no θ = 0 and θ = 45° directions for the default probe; set one"
                        .into(),
            }),
        }
    }

    pub fn plan(&self) -> Result<SamplingPlan, ConfigError> {
        Ok(SamplingPlan::new(&self.plan)?)
    }
    pub fn rig(&self) -> Result<Rig, ConfigError> {
        Ok(Rig::new(self.rig.clone())?)
    }
    pub fn rgb_to_xyz(&self) -> RgbToXyz {
        RgbToXyz::new(self.colour.primaries)
    }
    /// Mean RGB of a capture → XYZ on the configured scale.
    pub fn xyz_of(&self, mean_rgb: [f64; 3]) -> Xyz {
        let s = self.colour.rgb_scale;
        self.rgb_to_xyz()
            .convert([mean_rgb[0] * s, mean_rgb[1] * s, mean_rgb[2] * s])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_config_is_the_ubo_default() {
        let c = Config::from_toml_str("").unwrap();
        assert_eq!(c, Config::default());
        assert_eq!(c.plan().unwrap().capture_count(), 6561);
    }

    #[test]
    fn unknown_field_is_named() {
        let e = Config::from_toml_str("[rig]\nmin_separation = 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("min_separation"), "{e}");
        let e = Config::from_toml_str("[plan]\norder = \"spiral\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("spiral") && e.contains("order"), "{e}");
        let e = Config::from_toml_str("[colour]\nrgb_scale = -1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour.rgb_scale"), "{e}");
        let e = Config::from_toml_str("[colour.white]\nkind = \"xyz\"\nxyz = [1, 0, 1]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour.white"), "{e}");
        let e = Config::from_toml_str("[plan]\nthetas_deg = [0, 15]\ndelta_phi_deg = [0, 7]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("plan.delta_phi_deg[1]"), "{e}");
        let e = Config::from_toml_str("[rig]\nmin_separation_deg = 95\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("rig.min_separation_deg"), "{e}");
        let e = Config::from_toml_str("[rig]\nmin_separation_deg = \"ten\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("min_separation_deg"), "{e}");
        for (text, field) in [
            ("[checks.sweeps]\nclip = 0\n", "checks.sweeps.clip"),
            ("[checks.sweeps]\ncusum_k = -1\n", "checks.sweeps.cusum_k"),
            (
                "[checks.sweeps]\nfalse_alarm_runs = 0.5\n",
                "checks.sweeps.false_alarm_runs",
            ),
            (
                "[checks.sweeps]\nmin_captures = 2\n",
                "checks.sweeps.min_captures",
            ),
            (
                "[checks.sweeps]\nsensitivity_step_deg = 45\n",
                "checks.sweeps.sensitivity_step_deg",
            ),
            (
                "[checks.sweeps]\nsensitivity_step_deg = 0.001\n",
                "checks.sweeps.sensitivity_step_deg",
            ),
            ("[checks.sweeps]\njoint_tolerance = 1\n", "joint_tolerance"),
        ] {
            let e = Config::from_toml_str(text).unwrap_err().to_string();
            assert!(e.contains(field), "{text}: {e}");
        }
    }

    #[test]
    fn the_shipped_configs_parse_and_keep_the_sweep_defaults() {
        for name in ["ubo.toml", "sim.toml"] {
            let path = format!("{}/config/{name}", env!("CARGO_MANIFEST_DIR"));
            let c = Config::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap();
            assert_eq!(c.checks.sweeps, Default::default(), "{name}");
        }
    }
}
