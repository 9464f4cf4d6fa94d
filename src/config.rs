//! The rig/session configuration file (TOML, `deny_unknown_fields` everywhere).
//!
//! Parsing is pure ([`Config::from_toml_str`]); reading the file is the caller's job. Errors name
//! the offending field (serde's message plus the TOML key path and line).

use crate::measure::averaging::AverageOptions;
use crate::measure::colour::{ColourError, RgbPrimaries, RgbToXyz, White, Xyz};
use crate::measure::kinematics::{KinematicsError, Rig, RigSpec};
use crate::measure::plan::{PlanError, PlanSpec, SamplingPlan};
use crate::measure::reciprocity::DEFAULT_MIN_COS;
use serde::{Deserialize, Serialize};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum ConfigError {
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
}

impl Config {
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
        Ok(())
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
    }
}
