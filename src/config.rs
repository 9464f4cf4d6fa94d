//! The rig/session configuration file (TOML, `deny_unknown_fields` everywhere).
//!
//! Parsing is pure ([`Config::from_toml_str`]); reading the file is the caller's job. Errors name
//! the offending field (serde's message plus the TOML key path and line).

use crate::checks::CheckSpec;
use crate::measure::averaging::AverageOptions;
use crate::measure::colour::{ColourError, RgbPrimaries, White, Xyz};
use crate::measure::kinematics::{KinematicsError, Rig, RigSpec};
use crate::measure::plan::{PlanError, PlanSpec, SamplingPlan};
use crate::measure::reciprocity::DEFAULT_MIN_COS;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
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
    pub(crate) fn resolve(&self, reference: Option<Xyz>) -> Result<White, ColourError> {
        match *self {
            WhiteSpec::D65 { y } => White::d65_scaled(y),
            WhiteSpec::Xyz { xyz } => White::new(xyz),
            WhiteSpec::ReferenceCapture { .. } => White::new(reference.unwrap_or([0.0; 3])),
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourSpec {
    #[serde(default)]
    pub primaries: RgbPrimaries,
    /// Multiplies the mean RGB before conversion (brings uncalibrated HDR values to the
    /// white's scale, 0–100 like the paper's). Not set: `check` and watch mode take it from
    /// the data (the white at a high percentile of the captures' Y, printed at start and
    /// written into the session's config); a run over serial takes the values as they are (1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rgb_scale: Option<f64>,
    #[serde(default)]
    pub white: WhiteSpec,
    /// The reflectance of the white that the white's luminance stands for (default 1: a
    /// perfect reflector, as when `rgb_scale` already holds the standard's reflectance). Only
    /// the export uses it: a BRDF is (Y / the white's Y) × this / (π cos θi).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_reflectance: Option<f64>,
}

impl ColourSpec {
    /// The white's reflectance (1 when not set).
    pub fn white_reflectance(&self) -> f64 {
        self.white_reflectance.unwrap_or(1.0)
    }

    /// The factor on the mean RGB: the configured one, or 1 when the config leaves it to the
    /// data and nothing resolved it.
    pub fn scale(&self) -> f64 {
        self.rgb_scale.unwrap_or(1.0)
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
        AlarmSpec {
            hook: Vec::new(),
            pause_on_critical: false,
            crc_errors_alarm: 5,
            crc_window: 200,
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
    pub probes: crate::detect::probes::ProbeSpec,
    #[serde(default)]
    pub alarms: AlarmSpec,
    #[serde(default)]
    pub link: LinkSpec,
    #[serde(default)]
    pub ingest: IngestSpec,
    #[serde(default)]
    pub http: HttpSpec,
    #[serde(default)]
    pub source: crate::archive::SourceSpec,
}

/// `[link]` in the config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkSpec {
    /// The controller's serial port (a stable path; the simulator makes it a symlink).
    pub port: PathBuf,
    pub baud: u32,
    /// Character size, 5 to 8 bits.
    pub data_bits: u8,
    pub parity: Parity,
    /// 1 or 2.
    pub stop_bits: u8,
    pub flow_control: FlowControl,
    pub reconnect_min_ms: u64,
    pub reconnect_max_ms: u64,
}

/// `link.parity`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Parity {
    #[default]
    None,
    Odd,
    Even,
}

/// `link.flow_control`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum FlowControl {
    #[default]
    None,
    /// Hardware handshake on the RTS/CTS lines.
    RtsCts,
    /// Software handshake with XON/XOFF characters.
    XonXoff,
}

impl Default for LinkSpec {
    fn default() -> Self {
        LinkSpec {
            port: PathBuf::from("/tmp/goniowatch-rig"),
            baud: 115_200,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
            flow_control: FlowControl::None,
            reconnect_min_ms: 100,
            reconnect_max_ms: 2000,
        }
    }
}

/// Retry policy (`[ingest]` in the config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IngestSpec {
    /// Where the camera PC writes; announced names are relative to it. Relative to the config
    /// file's folder.
    pub capture_root: PathBuf,
    /// Worker threads decoding captures.
    pub workers: usize,
    /// Jobs queued for the workers before the daemon holds further ones back.
    pub queue: usize,
    /// First retry delay; it doubles up to `retry_max_ms`.
    pub retry_first_ms: u64,
    pub retry_max_ms: u64,
    /// Give up on a file that is absent, growing or undecodable after this long.
    pub give_up_s: f64,
    /// A file that fails to decode this many times at an unchanged size is failed at once.
    pub stable_failures: u32,
    /// Threads per EXR decode (1 inside the pool).
    pub decode_threads: usize,
    /// A capture is accepted once it decodes and has not changed for this long (last modified
    /// this long ago, or seen unchanged this long apart). 0: accept as soon as it decodes at a
    /// stable size, for writers that rename finished files into place.
    pub settle_ms: u64,
    /// Memory one decode may use, from the file's header (channels × pixels × bytes), checked
    /// before any pixel buffer is allocated.
    pub max_decode_mib: u64,
}

impl Default for IngestSpec {
    fn default() -> Self {
        IngestSpec {
            capture_root: PathBuf::from("captures"),
            workers: 2,
            queue: 8,
            retry_first_ms: 50,
            retry_max_ms: 1000,
            give_up_s: 30.0,
            stable_failures: 3,
            decode_threads: 1,
            settle_ms: 500,
            max_decode_mib: 1024,
        }
    }
}

/// The largest accepted `ingest.give_up_s` (a day).
pub(crate) const MAX_GIVE_UP_S: f64 = 86_400.0;

/// `[http]`: the status page of `run --http ADDR`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct HttpSpec {
    /// Serve on a non-loopback address (the page has no authentication). Off by default.
    pub allow_remote: bool,
}

/// A numeric key's valid range, checked at load (`Config::validate`) and listed in
/// docs/configuration.md. Integers are compared as f64 (exact below 2⁵³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct KeyRange {
    pub field: &'static str,
    pub min: f64,
    pub max: f64,
    /// The value must be strictly above `min`.
    pub min_open: bool,
    /// The value must be strictly below `max`.
    pub max_open: bool,
}

const fn closed(field: &'static str, min: f64, max: f64) -> KeyRange {
    KeyRange {
        field,
        min,
        max,
        min_open: false,
        max_open: false,
    }
}

const fn above(field: &'static str, min: f64, max: f64) -> KeyRange {
    KeyRange {
        field,
        min,
        max,
        min_open: true,
        max_open: false,
    }
}

impl KeyRange {
    /// The range as documented, e.g. `(0, 1e12]`.
    pub(crate) fn interval(&self) -> String {
        let num = |v: f64| {
            if v.abs() >= 1e7 {
                format!("{v:e}")
            } else {
                format!("{v}")
            }
        };
        format!(
            "{}{}, {}{}",
            if self.min_open { "(" } else { "[" },
            num(self.min),
            num(self.max),
            if self.max_open { ")" } else { "]" }
        )
    }

    fn check(&self, v: f64) -> Result<(), ConfigError> {
        let low_ok = if self.min_open {
            v > self.min
        } else {
            v >= self.min
        };
        let high_ok = if self.max_open {
            v < self.max
        } else {
            v <= self.max
        };
        if v.is_finite() && low_ok && high_ok {
            Ok(())
        } else {
            Err(ConfigError::Invalid {
                field: self.field,
                message: format!("{v} is not in {}", self.interval()),
            })
        }
    }
}

/// Every numeric key's valid range. The bounds keep a 13-hour run safe: durations fit a
/// `Duration`, thread and queue counts fit the machine, counts fit memory.
pub(crate) const KEY_RANGES: &[KeyRange] = &[
    above("colour.rgb_scale", 0.0, 1e12),
    above("colour.white_reflectance", 0.0, 2.0),
    above("capture.clip_level", 0.0, f32::MAX as f64),
    closed("capture.dark_level", 0.0, f32::MAX as f64),
    KeyRange {
        field: "reciprocity.min_cos",
        min: 0.0,
        max: 1.0,
        min_open: true,
        max_open: true,
    },
    closed("checks.pair_tolerance_deg", 0.0, 90.0),
    closed("checks.pose_tolerance_deg", 0.0, 90.0),
    closed("checks.encoder_tolerance_deg", 0.0, 90.0),
    closed("checks.outlier_k", 0.0, 1000.0),
    closed("checks.outlier_floor_de2000", 0.0, 1000.0),
    closed("checks.outlier_min_pairs", 1.0, 1e6),
    closed("checks.nonfinite_max", 0.0, 1e12),
    closed("checks.clipped_fraction_max", 0.0, 1.0),
    closed("checks.dark_y", 0.0, 1e12),
    closed("checks.failures_critical", 1.0, 1e6),
    closed("checks.sweeps.joint_tolerance_deg", 0.0, 90.0),
    closed("checks.sweeps.level_tolerance_pct", 0.0, 100.0),
    closed("checks.sweeps.cusum_k", 0.0, 10.0),
    above("checks.sweeps.clip", 0.0, 100.0),
    closed("checks.sweeps.false_alarm_runs", 1.0, 1e6),
    closed("checks.sweeps.min_sweeps", 1.0, 1e4),
    closed("checks.sweeps.min_layer_sweeps", 1.0, 1e4),
    closed("checks.sweeps.min_captures", 4.0, 1e4),
    closed("checks.sweeps.sensitivity_step_deg", 0.01, 10.0),
    above("checks.sweeps.unstable_scatter_pct", 0.0, 100.0),
    closed("checks.sweeps.wagon_watch_sweeps", 0.0, 1e4),
    closed("checks.colour_drift.lamp_cct_k", 1000.0, 20_000.0),
    closed("checks.colour_drift.tolerance_k_per_h", 0.0, 10_000.0),
    above("checks.colour_drift.z", 0.0, 100.0),
    closed("probes.every", 0.0, 1e6),
    closed("probes.entry", 0.0, 1e6),
    closed("probes.rate_tolerance_pct_per_h", 0.0, 100.0),
    above("probes.z", 0.0, 100.0),
    closed("probes.min_probes", 2.0, 1e6),
    above("probes.step_sigmas", 0.0, 1000.0),
    closed("probes.step_pct", 0.0, 100.0),
    above("probes.design_scatter_pct", 0.0, 100.0),
    above("probes.sentinel_min_deg", 0.0, 90.0),
    closed("alarms.crc_errors_alarm", 1.0, 1e6),
    closed("alarms.crc_window", 1.0, 1e6),
    closed("link.baud", 50.0, 12_000_000.0),
    closed("link.data_bits", 5.0, 8.0),
    closed("link.stop_bits", 1.0, 2.0),
    closed("link.reconnect_min_ms", 1.0, 60_000.0),
    closed("link.reconnect_max_ms", 1.0, 3_600_000.0),
    closed("ingest.workers", 1.0, 64.0),
    closed("ingest.queue", 1.0, 10_000.0),
    closed("ingest.retry_first_ms", 1.0, 60_000.0),
    closed("ingest.retry_max_ms", 1.0, 600_000.0),
    closed("ingest.give_up_s", 0.0, MAX_GIVE_UP_S),
    closed("ingest.stable_failures", 1.0, 1000.0),
    closed("ingest.decode_threads", 1.0, 16.0),
    closed("ingest.settle_ms", 0.0, 600_000.0),
    closed("ingest.max_decode_mib", 16.0, 65_536.0),
    above("source.seconds_per_capture", 0.0, 86_400.0),
    closed("source.angle_tolerance_deg", 0.0, 10.0),
    closed("source.poll_ms", 10.0, 600_000.0),
    closed("rig.joints[0].offset_deg", -360.0, 360.0),
    closed("rig.joints[1].offset_deg", -360.0, 360.0),
    closed("rig.joints[2].offset_deg", -360.0, 360.0),
    closed("rig.wagon.offset_deg", -360.0, 360.0),
];

/// The keys that set how the daemon runs but never what it computes.
pub(crate) const RUNTIME_KEYS: &[&str] = &[
    "link.baud",
    "link.reconnect_min_ms",
    "link.reconnect_max_ms",
    "ingest.workers",
    "ingest.queue",
    "ingest.retry_first_ms",
    "ingest.retry_max_ms",
    "ingest.give_up_s",
    "ingest.stable_failures",
    "ingest.decode_threads",
    "ingest.settle_ms",
    "ingest.max_decode_mib",
];

/// A numeric config value of any width, as f64.
enum RuntimeSlot<'a> {
    U32(&'a mut u32),
    U64(&'a mut u64),
    Usize(&'a mut usize),
    F64(&'a mut f64),
}

impl RuntimeSlot<'_> {
    fn get(&self) -> f64 {
        match self {
            RuntimeSlot::U32(v) => **v as f64,
            RuntimeSlot::U64(v) => **v as f64,
            RuntimeSlot::Usize(v) => **v as f64,
            RuntimeSlot::F64(v) => **v,
        }
    }
    /// Set from a value already within the key's range (so the casts are exact).
    fn set(self, x: f64) {
        match self {
            RuntimeSlot::U32(v) => *v = x as u32,
            RuntimeSlot::U64(v) => *v = x as u64,
            RuntimeSlot::Usize(v) => *v = x as usize,
            RuntimeSlot::F64(v) => *v = x,
        }
    }
}

impl Config {
    /// Read, parse and validate a config file; also returns its text.
    pub(crate) fn load(path: &std::path::Path) -> Result<(Config, String), ConfigError> {
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

    /// Parse and validate a session's stored config. The keys that only set how the daemon
    /// runs (link timing, worker and retry counts, decode budget), never what it computes, are
    /// brought into their current ranges with a warning each, so that a session created under
    /// older, wider ranges can still be resumed, replayed and reported; every other key must be
    /// valid as it stands, since the results were computed with it.
    pub(crate) fn from_stored_toml_str(text: &str) -> Result<(Config, Vec<String>), ConfigError> {
        let mut cfg: Config =
            toml::from_str(text).map_err(|e| ConfigError::Parse(e.to_string()))?;
        let mut notes = Vec::new();
        let mut defaults = Config::default();
        for field in RUNTIME_KEYS {
            let Some(r) = KEY_RANGES.iter().find(|r| r.field == *field) else {
                continue;
            };
            let Some(slot) = cfg.runtime_value(field) else {
                continue;
            };
            let v = slot.get();
            if r.check(v).is_err() {
                // NaN has no nearest bound: the documented default stands in for it
                let fixed = if v.is_nan() {
                    defaults.runtime_value(field).map_or(r.min, |d| d.get())
                } else {
                    v.clamp(r.min, r.max)
                };
                slot.set(fixed);
                let effect = if *field == "ingest.max_decode_mib" {
                    " (captures larger than the budget are refused, so a replay that decodes the files again may differ from the live run)"
                } else {
                    ""
                };
                notes.push(format!(
                    "stored config: {field} = {v} is outside {}; {fixed} is used{effect}",
                    r.interval()
                ));
            }
        }
        if cfg.ingest.retry_max_ms < cfg.ingest.retry_first_ms {
            notes.push(format!(
                "stored config: ingest.retry_max_ms = {} is below ingest.retry_first_ms = {}; {} is used",
                cfg.ingest.retry_max_ms, cfg.ingest.retry_first_ms, cfg.ingest.retry_first_ms
            ));
            cfg.ingest.retry_max_ms = cfg.ingest.retry_first_ms;
        }
        if cfg.link.reconnect_max_ms < cfg.link.reconnect_min_ms {
            notes.push(format!(
                "stored config: link.reconnect_max_ms = {} is below link.reconnect_min_ms = {}; {} is used",
                cfg.link.reconnect_max_ms, cfg.link.reconnect_min_ms, cfg.link.reconnect_min_ms
            ));
            cfg.link.reconnect_max_ms = cfg.link.reconnect_min_ms;
        }
        cfg.validate()?;
        Ok((cfg, notes))
    }

    /// A runtime key's value, to read and overwrite.
    fn runtime_value(&mut self, field: &str) -> Option<RuntimeSlot<'_>> {
        let (l, i) = (&mut self.link, &mut self.ingest);
        Some(match field {
            "link.baud" => RuntimeSlot::U32(&mut l.baud),
            "link.reconnect_min_ms" => RuntimeSlot::U64(&mut l.reconnect_min_ms),
            "link.reconnect_max_ms" => RuntimeSlot::U64(&mut l.reconnect_max_ms),
            "ingest.workers" => RuntimeSlot::Usize(&mut i.workers),
            "ingest.queue" => RuntimeSlot::Usize(&mut i.queue),
            "ingest.retry_first_ms" => RuntimeSlot::U64(&mut i.retry_first_ms),
            "ingest.retry_max_ms" => RuntimeSlot::U64(&mut i.retry_max_ms),
            "ingest.give_up_s" => RuntimeSlot::F64(&mut i.give_up_s),
            "ingest.stable_failures" => RuntimeSlot::U32(&mut i.stable_failures),
            "ingest.decode_threads" => RuntimeSlot::Usize(&mut i.decode_threads),
            "ingest.settle_ms" => RuntimeSlot::U64(&mut i.settle_ms),
            "ingest.max_decode_mib" => RuntimeSlot::U64(&mut i.max_decode_mib),
            _ => return None,
        })
    }

    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        SamplingPlan::new(&self.plan)?;
        Rig::new(self.rig.clone())?;
        for (field, v) in self.numeric_values() {
            let r = KEY_RANGES
                .iter()
                .find(|r| r.field == field)
                .ok_or_else(|| ConfigError::Invalid {
                    field,
                    message: "has no documented range".into(),
                })?;
            r.check(v)?;
        }
        for (field, lower, lower_field, v) in [
            (
                "ingest.retry_max_ms",
                self.ingest.retry_first_ms as f64,
                "ingest.retry_first_ms",
                self.ingest.retry_max_ms as f64,
            ),
            (
                "link.reconnect_max_ms",
                self.link.reconnect_min_ms as f64,
                "link.reconnect_min_ms",
                self.link.reconnect_max_ms as f64,
            ),
        ] {
            if v < lower {
                return Err(ConfigError::Invalid {
                    field,
                    message: format!("{v} is below {lower_field} = {lower}"),
                });
            }
        }
        if self.alarms.crc_errors_alarm > self.alarms.crc_window {
            return Err(ConfigError::Invalid {
                field: "alarms.crc_errors_alarm",
                message: format!(
                    "{} is larger than alarms.crc_window = {}: the alarm could never fire",
                    self.alarms.crc_errors_alarm, self.alarms.crc_window
                ),
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
        if let crate::measure::averaging::Roi::Rect { width, height, .. } = self.capture.roi {
            if width == 0 || height == 0 {
                return Err(ConfigError::Invalid {
                    field: "capture.roi",
                    message: format!("a rect of {width}×{height} pixels holds no pixel"),
                });
            }
        }
        if let crate::measure::averaging::Roi::MarginFraction { fraction } = self.capture.roi {
            if !(0.0..0.5).contains(&fraction) {
                return Err(ConfigError::Invalid {
                    field: "capture.roi.fraction",
                    message: format!("{fraction} is not in [0, 0.5)"),
                });
            }
        }
        if let (true, Some(e)) = (
            self.probes.every != crate::detect::probes::ProbeEvery::Captures(0),
            self.probes.entry,
        ) {
            let n = SamplingPlan::new(&self.plan)?.capture_count();
            if e >= n {
                return Err(ConfigError::Invalid {
                    field: "probes.entry",
                    message: format!("{e} is not a plan entry (0..{n})"),
                });
            }
        }
        if self.source.kind == crate::archive::SourceKind::Files {
            self.validate_files_source()?;
        }
        Ok(())
    }

    /// A files source has no controller: what needs one must be off.
    fn validate_files_source(&self) -> Result<(), ConfigError> {
        if self.source.sidecar.is_none() {
            crate::archive::listing::compile_pattern(&self.source.pattern).map_err(|e| {
                ConfigError::Invalid {
                    field: "source.pattern",
                    message: e.to_string(),
                }
            })?;
        }
        if self.probes.every.fixed().is_some_and(|n| n > 0) {
            return Err(ConfigError::Invalid {
                field: "probes.every",
                message: "drift probes need a controller that takes them (source.kind = \"protocol\"); set it to 0 for a files source".into(),
            });
        }
        if self.alarms.pause_on_critical {
            return Err(ConfigError::Invalid {
                field: "alarms.pause_on_critical",
                message: "pausing needs a controller (source.kind = \"protocol\")".into(),
            });
        }
        if self.source.extensions.is_empty() {
            return Err(ConfigError::Invalid {
                field: "source.extensions",
                message: "no file type is taken as a capture".into(),
            });
        }
        Ok(())
    }

    /// Every numeric key of the file with its value, for the range check.
    fn numeric_values(&self) -> Vec<(&'static str, f64)> {
        let (c, sw, p, l, i, a) = (
            &self.checks,
            &self.checks.sweeps,
            &self.probes,
            &self.link,
            &self.ingest,
            &self.alarms,
        );
        let mut v = vec![
            ("capture.clip_level", self.capture.clip_level as f64),
            ("capture.dark_level", self.capture.dark_level as f64),
            ("reciprocity.min_cos", self.reciprocity.min_cos),
            ("checks.pair_tolerance_deg", c.pair_tolerance_deg),
            ("checks.pose_tolerance_deg", c.pose_tolerance_deg),
            ("checks.encoder_tolerance_deg", c.encoder_tolerance_deg),
            ("checks.outlier_k", c.outlier_k),
            ("checks.outlier_floor_de2000", c.outlier_floor_de2000),
            ("checks.outlier_min_pairs", c.outlier_min_pairs as f64),
            ("checks.nonfinite_max", c.nonfinite_max as f64),
            ("checks.clipped_fraction_max", c.clipped_fraction_max),
            ("checks.dark_y", c.dark_y),
            ("checks.failures_critical", c.failures_critical as f64),
            ("checks.sweeps.joint_tolerance_deg", sw.joint_tolerance_deg),
            ("checks.sweeps.level_tolerance_pct", sw.level_tolerance_pct),
            ("checks.sweeps.cusum_k", sw.cusum_k),
            ("checks.sweeps.clip", sw.clip),
            ("checks.sweeps.false_alarm_runs", sw.false_alarm_runs),
            ("checks.sweeps.min_sweeps", sw.min_sweeps as f64),
            ("checks.sweeps.min_layer_sweeps", sw.min_layer_sweeps as f64),
            ("checks.sweeps.min_captures", sw.min_captures as f64),
            (
                "checks.sweeps.sensitivity_step_deg",
                sw.sensitivity_step_deg,
            ),
            (
                "checks.sweeps.unstable_scatter_pct",
                sw.unstable_scatter_pct,
            ),
            (
                "checks.sweeps.wagon_watch_sweeps",
                sw.wagon_watch_sweeps as f64,
            ),
            ("checks.colour_drift.lamp_cct_k", c.colour_drift.lamp_cct_k),
            (
                "checks.colour_drift.tolerance_k_per_h",
                c.colour_drift.tolerance_k_per_h,
            ),
            ("checks.colour_drift.z", c.colour_drift.z),
            (
                "probes.rate_tolerance_pct_per_h",
                p.rate_tolerance_pct_per_h,
            ),
            ("probes.z", p.z),
            ("probes.min_probes", p.min_probes as f64),
            ("probes.step_sigmas", p.step_sigmas),
            ("probes.step_pct", p.step_pct),
            ("probes.design_scatter_pct", p.design_scatter_pct),
            ("probes.sentinel_min_deg", p.sentinel_min_deg),
            ("alarms.crc_errors_alarm", a.crc_errors_alarm as f64),
            ("alarms.crc_window", a.crc_window as f64),
            ("link.baud", l.baud as f64),
            ("link.data_bits", l.data_bits as f64),
            ("link.stop_bits", l.stop_bits as f64),
            ("link.reconnect_min_ms", l.reconnect_min_ms as f64),
            ("link.reconnect_max_ms", l.reconnect_max_ms as f64),
            ("ingest.workers", i.workers as f64),
            ("ingest.queue", i.queue as f64),
            ("ingest.retry_first_ms", i.retry_first_ms as f64),
            ("ingest.retry_max_ms", i.retry_max_ms as f64),
            ("ingest.give_up_s", i.give_up_s),
            ("ingest.stable_failures", i.stable_failures as f64),
            ("ingest.decode_threads", i.decode_threads as f64),
            ("ingest.settle_ms", i.settle_ms as f64),
            ("ingest.max_decode_mib", i.max_decode_mib as f64),
            ("rig.wagon.offset_deg", self.rig.wagon.offset_deg),
            (
                "source.seconds_per_capture",
                self.source.seconds_per_capture,
            ),
            (
                "source.angle_tolerance_deg",
                self.source.angle_tolerance_deg,
            ),
            ("source.poll_ms", self.source.poll_ms as f64),
        ];
        if let Some(every) = self.probes.every.fixed() {
            v.push(("probes.every", every as f64));
        }
        if let Some(scale) = self.colour.rgb_scale {
            v.push(("colour.rgb_scale", scale));
        }
        if let Some(r) = self.colour.white_reflectance {
            v.push(("colour.white_reflectance", r));
        }
        for (k, j) in self.rig.joints.iter().enumerate() {
            v.push((
                [
                    "rig.joints[0].offset_deg",
                    "rig.joints[1].offset_deg",
                    "rig.joints[2].offset_deg",
                ][k],
                j.offset_deg,
            ));
        }
        if let Some(e) = p.entry {
            v.push(("probes.entry", e as f64));
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_config_is_the_ubo_default() {
        let c = Config::from_toml_str("").unwrap();
        assert_eq!(c, Config::default());
        assert_eq!(SamplingPlan::new(&c.plan).unwrap().capture_count(), 6561);
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
    fn every_numeric_key_has_a_range_and_out_of_range_values_name_it() {
        let c = Config::default();
        let keys: Vec<&str> = c.numeric_values().iter().map(|(k, _)| *k).collect();
        let mut with_entry = c.clone();
        with_entry.probes.entry = Some(3);
        with_entry.colour.rgb_scale = Some(1.0);
        with_entry.colour.white_reflectance = Some(1.0);
        with_entry.probes.every = crate::detect::probes::ProbeEvery::Captures(1);
        let all: Vec<&str> = with_entry
            .numeric_values()
            .iter()
            .map(|(k, _)| *k)
            .collect();
        for r in KEY_RANGES {
            assert!(
                all.contains(&r.field),
                "{} has a range but no value",
                r.field
            );
        }
        for k in &keys {
            assert!(KEY_RANGES.iter().any(|r| r.field == *k), "{k} has no range");
        }
        // one past each end of every range is refused with the field's name
        for r in KEY_RANGES {
            for v in [f64::NAN, f64::INFINITY, r.max * 2.0 + 1.0] {
                let e = r.check(v).unwrap_err().to_string();
                assert!(e.contains(r.field), "{e}");
            }
            assert!(r.check(r.max).is_ok() || r.max_open, "{}", r.field);
            assert!(r.check(r.min).is_ok() || r.min_open, "{}", r.field);
            assert!(r.check(r.min).is_err() || !r.min_open, "{}", r.field);
        }
        for (text, field) in [
            ("[ingest]\ngive_up_s = 1e308\n", "ingest.give_up_s"),
            ("[ingest]\nworkers = 100000000\n", "ingest.workers"),
            (
                "[ingest]\ndecode_threads = 1000000\n",
                "ingest.decode_threads",
            ),
            ("[link]\nbaud = 0\n", "link.baud"),
            ("[link]\nreconnect_min_ms = 0\n", "link.reconnect_min_ms"),
            (
                "[link]\nreconnect_min_ms = 500\nreconnect_max_ms = 100\n",
                "link.reconnect_max_ms",
            ),
            (
                "[alarms]\ncrc_errors_alarm = 300\n",
                "alarms.crc_errors_alarm",
            ),
            (
                "[rig]\nwagon = { offset_deg = 1e300 }\n",
                "rig.wagon.offset_deg",
            ),
            ("[probes]\nevery = 10\nentry = 99999999\n", "probes.entry"),
        ] {
            let e = Config::from_toml_str(text).unwrap_err().to_string();
            assert!(e.contains(field), "{text}: {e}");
        }
    }

    #[test]
    fn a_stored_config_from_wider_ranges_still_loads_its_runtime_keys_clamped() {
        let text = "[ingest]\ndecode_threads = 0\nworkers = 100000000\ngive_up_s = 1e308\nsettle_ms = 0\n[link]\nbaud = 0\n";
        assert!(
            Config::from_toml_str(text).is_err(),
            "a new config is refused"
        );
        let (c, notes) = Config::from_stored_toml_str(text).unwrap();
        assert_eq!(c.ingest.decode_threads, 1);
        assert_eq!(c.ingest.workers, 64);
        assert_eq!(c.ingest.give_up_s, MAX_GIVE_UP_S);
        assert_eq!(c.link.baud, 50);
        assert_eq!(notes.len(), 4, "{notes:?}");
        assert!(notes.iter().any(|n| n.contains("ingest.decode_threads")));
        // a key that shapes the results is never changed: the session is refused, named
        let e = Config::from_stored_toml_str("[checks]\noutlier_k = -1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("checks.outlier_k"), "{e}");
        for k in RUNTIME_KEYS {
            assert!(KEY_RANGES.iter().any(|r| r.field == *k), "{k}");
            assert!(Config::default().runtime_value(k).is_some(), "{k}");
        }
    }

    #[test]
    fn a_stored_nan_takes_the_default_and_swapped_bounds_are_said() {
        let text = "[ingest]\ngive_up_s = nan\nretry_first_ms = 5000\nretry_max_ms = 100\n[link]\nreconnect_min_ms = 4000\nreconnect_max_ms = 1000\n";
        let (c, notes) = Config::from_stored_toml_str(text).unwrap();
        assert_eq!(c.ingest.give_up_s, Config::default().ingest.give_up_s);
        assert_eq!(c.ingest.retry_max_ms, 5000);
        assert_eq!(c.link.reconnect_max_ms, 4000);
        assert!(
            notes.iter().any(|n| n.contains("ingest.give_up_s")),
            "{notes:?}"
        );
        assert!(
            notes.iter().any(|n| n.contains("ingest.retry_max_ms")),
            "{notes:?}"
        );
        assert!(
            notes.iter().any(|n| n.contains("link.reconnect_max_ms")),
            "{notes:?}"
        );
        let (_, notes) = Config::from_stored_toml_str("[ingest]\nmax_decode_mib = 1\n").unwrap();
        assert!(notes.iter().any(|n| n.contains("replay")), "{notes:?}");
    }

    #[test]
    fn serial_line_settings_parse_and_bad_ones_are_named() {
        let c = Config::from_toml_str(
            "[link]\ndata_bits = 7\nparity = \"even\"\nstop_bits = 2\nflow_control = \"rts-cts\"\n",
        )
        .unwrap();
        assert_eq!(
            (
                c.link.data_bits,
                c.link.parity,
                c.link.stop_bits,
                c.link.flow_control
            ),
            (7, Parity::Even, 2, FlowControl::RtsCts)
        );
        let d = Config::default().link;
        assert_eq!((d.data_bits, d.parity, d.stop_bits), (8, Parity::None, 1));
        for (text, key) in [
            ("[link]\ndata_bits = 9\n", "link.data_bits"),
            ("[link]\nstop_bits = 3\n", "link.stop_bits"),
            ("[link]\nparity = \"mark\"\n", "parity"),
            ("[link]\nflow_control = \"dtr\"\n", "flow_control"),
        ] {
            let e = Config::from_toml_str(text).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }

    #[test]
    fn a_files_source_refuses_what_needs_a_controller_and_names_the_key() {
        let ok = Config::from_toml_str("[source]\nkind = \"files\"\n").unwrap();
        assert_eq!(ok.source.kind, crate::archive::SourceKind::Files);
        for (text, key) in [
            (
                "[source]\nkind = \"files\"\n[probes]\nevery = 50\n",
                "probes.every",
            ),
            (
                "[source]\nkind = \"files\"\n[alarms]\npause_on_critical = true\n",
                "alarms.pause_on_critical",
            ),
            (
                "[source]\nkind = \"files\"\npattern = \"(?P<x>1)\"\n",
                "source.pattern",
            ),
            (
                "[source]\nkind = \"files\"\nextensions = []\n",
                "source.extensions",
            ),
            (
                "[source]\nkind = \"files\"\nangle_tolerance_deg = 11\n",
                "source.angle_tolerance_deg",
            ),
            ("[source]\nkind = \"tape\"\n", "kind"),
        ] {
            let e = Config::from_toml_str(text).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
        // a sidecar needs no pattern
        Config::from_toml_str("[source]\nkind = \"files\"\npattern = \"x\"\nsidecar = \"c.csv\"\n")
            .unwrap();
    }

    #[test]
    fn a_rect_roi_without_pixels_is_refused_and_fast_links_are_accepted() {
        let e = Config::from_toml_str(
            "[capture]\nroi = { kind = \"rect\", x = 0, y = 0, width = 0, height = 8 }\n",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("capture.roi"), "{e}");
        assert!(Config::from_toml_str("[link]\nbaud = 12000000\n").is_ok());
    }

    #[test]
    fn the_documented_ranges_are_the_checked_ones() {
        let doc = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/docs/configuration.md"
        ))
        .unwrap();
        for r in KEY_RANGES {
            let row = format!("| `{}` | {} |", r.field, r.interval());
            assert!(
                doc.contains(&row),
                "docs/configuration.md lacks the row {row}"
            );
        }
    }

    #[test]
    fn the_shipped_configs_parse_and_keep_the_sweep_defaults() {
        for name in [
            "ubo.toml",
            "sim.toml",
            "archive.toml",
            "sim-anisotropic.toml",
        ] {
            let path = format!("{}/config/{name}", env!("CARGO_MANIFEST_DIR"));
            let c = Config::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap();
            assert_eq!(c.checks.sweeps, Default::default(), "{name}");
        }
    }

    /// config/ubo.toml is the documented default a real rig starts from: it shows every section
    /// and every key the configuration has (set, or as a commented-out `# key =` line for a key
    /// whose default is "unset"), so that a key added to the code cannot ship undocumented there.
    #[test]
    fn the_real_rigs_config_shows_every_section_and_key() {
        fn keys(prefix: &str, t: &toml::Table, out: &mut Vec<String>) {
            for (k, v) in t {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                if let toml::Value::Table(inner) = v {
                    keys(&path, inner, out);
                }
                out.push(path);
            }
        }
        let read = |name: &str| {
            std::fs::read_to_string(format!("{}/config/{name}", env!("CARGO_MANIFEST_DIR")))
                .unwrap()
        };
        let shows = |text: &str, key: &str| {
            let mut documented = Vec::new();
            keys("", &text.parse::<toml::Table>().unwrap(), &mut documented);
            let leaf = key.rsplit('.').next().unwrap_or(key);
            documented.iter().any(|k| k == key)
                || text
                    .lines()
                    .any(|l| l.trim_start().starts_with(&format!("# {leaf} =")))
        };
        let (ubo, files) = (read("ubo.toml"), read("archive.toml"));
        let defaults = toml::Table::try_from(Config::default()).unwrap();
        let mut all = Vec::new();
        keys("", &defaults, &mut all);
        // keys whose default is unset do not serialise: these are shown commented out
        all.extend(
            [
                "colour.rgb_scale",
                "colour.white_reflectance",
                "probes.entry",
                "source.sidecar",
            ]
            .map(String::from),
        );
        for key in all {
            // a table's inner keys of another variant (roi, white) are compared by their table
            if key.starts_with("capture.roi.") || key.starts_with("colour.white.") {
                continue;
            }
            // a files source's keys are shown by the config a watched folder starts from
            let (name, text) = if key.starts_with("source.") && key != "source.kind" {
                ("archive.toml", &files)
            } else {
                ("ubo.toml", &ubo)
            };
            assert!(shows(text, &key), "config/{name} does not show `{key}`");
        }
    }

    #[test]
    fn probes_every_takes_a_count_or_auto_and_names_the_field_otherwise() {
        use crate::detect::probes::ProbeEvery;
        let with = |v: &str| Config::from_toml_str(&format!("[probes]\nevery = {v}\n"));
        assert_eq!(with("\"auto\"").unwrap().probes.every, ProbeEvery::Auto);
        assert_eq!(with("150").unwrap().probes.every, ProbeEvery::Captures(150));
        assert_eq!(with("0").unwrap().probes.every, ProbeEvery::Captures(0));
        assert_eq!(
            Config::from_toml_str("").unwrap().probes.every,
            ProbeEvery::Captures(0),
            "a config that leaves it out takes no probes"
        );
        for bad in ["\"often\"", "-5", "2.5", "true"] {
            let e = with(bad).unwrap_err().to_string();
            assert!(e.contains("every"), "{bad}: {e}");
        }
        // "auto" on a files source resolves to none instead of being refused
        let files =
            Config::from_toml_str("[source]\nkind = \"files\"\n[probes]\nevery = \"auto\"\n");
        assert!(files.is_ok(), "{files:?}");
        let fixed = Config::from_toml_str("[source]\nkind = \"files\"\n[probes]\nevery = 10\n");
        assert!(fixed.unwrap_err().to_string().contains("probes.every"));
    }
}
