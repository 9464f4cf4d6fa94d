//! The scale from the data: when a config leaves `[colour] rgb_scale` unset, `check` and watch
//! mode take the white from the captures themselves, so that an archive on whatever scale its
//! HDR merge produced is checked as it would be with its white standard's value configured.
//!
//! The factor is resolved once, before the session is made, and written into the session's
//! config: the engine sees a config like any other, and a replay reads the same factor.

use crate::archive::listing::ArchiveCapture;
use crate::config::Config;
use crate::measure::stats::{white_level, WHITE_QUANTILE};
use anyhow::{Context, Result};
use std::path::Path;

/// How many captures, spread evenly over the listing, the white is taken from.
pub(crate) const SAMPLE: usize = 256;

/// The white taken from a folder's captures.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ScaleFromData {
    /// The factor on the mean RGB that puts the white at the config's white luminance.
    pub rgb_scale: f64,
    /// The white's luminance on the files' own scale (Y at rgb_scale 1).
    pub white_y: f64,
    /// The configured white's luminance the white is put at.
    pub target_y: f64,
    /// Captures decoded and used.
    pub used: usize,
    /// Captures looked at.
    pub looked_at: usize,
}

impl ScaleFromData {
    /// The line printed at start: the factor used and how to set it.
    pub(crate) fn describe(&self) -> String {
        format!(
            "goniowatch: [colour] rgb_scale is not set: the white is taken from the data: Y = {:.6} on the files' scale (the {:.0}th percentile of {} of {} captures looked at) is put at the white's Y = {}, so rgb_scale = {:.6}. To fix the scale, set [colour] rgb_scale = {}/(the white standard's Y on the files' scale) in a config",
            self.white_y,
            WHITE_QUANTILE * 100.0,
            self.used,
            self.looked_at,
            self.target_y,
            self.rgb_scale,
            self.target_y
        )
    }
}

/// The white of `captures` (files under `root`): `None` when fewer than
/// `stats::WHITE_MIN_CAPTURES` of the captures looked at decode to a positive luminance.
/// A capture that cannot be read is passed over here; the check reports it as it always does.
pub(crate) fn from_captures(
    root: &Path,
    captures: &[ArchiveCapture],
    cfg: &Config,
) -> Option<ScaleFromData> {
    let limits = super::ingest::decode_limits(&cfg.ingest);
    let to_xyz = crate::setup::rgb_to_xyz(cfg);
    let target_y = crate::setup::live_white(cfg).ok()?.xyz()[1];
    let n = captures.len();
    let take = n.min(SAMPLE);
    let mut ys = Vec::with_capacity(take);
    for k in 0..take {
        let c = &captures[k * n / take];
        let Ok(path) = super::ingest::resolve(root, &c.file) else {
            continue;
        };
        let Ok(crate::checks::Outcome::Ok { stats, .. }) =
            super::ingest::measure_file(root, &path, &cfg.capture, &limits)
        else {
            continue;
        };
        let exposure = c.exposure.unwrap_or(1.0);
        let rgb = stats.mean_rgb.map(|v| v / exposure);
        ys.push(to_xyz.convert_scaled(rgb, 1.0)[1]);
    }
    let used = ys.iter().filter(|y| y.is_finite() && **y > 0.0).count();
    let white_y = white_level(&ys)?;
    Some(ScaleFromData {
        rgb_scale: target_y / white_y,
        white_y,
        target_y,
        used,
        looked_at: take,
    })
}

/// `text` (a config) with `[colour] rgb_scale = scale` set, the rest of the text as it was
/// where it can be (the line goes under an existing `[colour]` header, or a `[colour]` table is
/// added); the result is checked to parse to `scale`.
pub(crate) fn with_scale(text: &str, scale: f64) -> Result<String> {
    let line = format!("rgb_scale = {scale:?}");
    let header = text.lines().position(|l| {
        let l = l.trim();
        l == "[colour]" || (l.starts_with("[colour]") && l[8..].trim_start().starts_with('#'))
    });
    let edited = match header {
        Some(i) => {
            let mut lines: Vec<&str> = text.lines().collect();
            lines.insert(i + 1, &line);
            let mut s = lines.join("\n");
            s.push('\n');
            s
        }
        None => format!("{}\n[colour]\n{line}\n", text.trim_end()),
    };
    let parsed = |t: &str| -> Option<f64> {
        let table: toml::Table = t.parse().ok()?;
        table.get("colour")?.get("rgb_scale")?.as_float()
    };
    if parsed(&edited) == Some(scale) {
        return Ok(edited);
    }
    // a config that spells its colour table another way: rewrite it as a table
    let mut table: toml::Table = text.parse().context("the config does not parse")?;
    let colour = table
        .entry("colour")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let colour = colour
        .as_table_mut()
        .context("the config's colour is not a table")?;
    colour.insert("rgb_scale".into(), toml::Value::Float(scale));
    let rewritten = toml::to_string(&table).context("cannot write the config back")?;
    anyhow::ensure!(
        parsed(&rewritten) == Some(scale),
        "cannot set [colour] rgb_scale in the config"
    );
    Ok(rewritten)
}

/// The scale a session folder's stored config holds, if `text` with that scale is the stored
/// config (a resumed check keeps the factor it was made with instead of taking it again).
pub(crate) fn stored(session_dir: &Path, text: &str) -> Option<f64> {
    let stored = std::fs::read_to_string(session_dir.join("config.toml")).ok()?;
    let table: toml::Table = stored.parse().ok()?;
    let scale = table.get("colour")?.get("rgb_scale")?.as_float()?;
    (with_scale(text, scale).ok()? == stored).then_some(scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_goes_under_the_colour_header_and_the_rest_is_kept() {
        let text = "# mine\n[sample]\nisotropic = true\n\n[colour] # the camera\nprimaries = \"srgb-iec\"\n";
        let out = with_scale(text, 250.5).unwrap();
        assert_eq!(
            out,
            "# mine\n[sample]\nisotropic = true\n\n[colour] # the camera\nrgb_scale = 250.5\nprimaries = \"srgb-iec\"\n"
        );
        let cfg = Config::from_toml_str(&out).unwrap();
        assert_eq!(cfg.colour.rgb_scale, Some(250.5));
    }

    #[test]
    fn a_config_without_a_colour_table_gains_one() {
        let out = with_scale("[sample]\nisotropic = true\n", 1e-5).unwrap();
        assert_eq!(
            out,
            "[sample]\nisotropic = true\n[colour]\nrgb_scale = 1e-5\n"
        );
        assert_eq!(
            Config::from_toml_str(&out).unwrap().colour.rgb_scale,
            Some(1e-5)
        );
        let big = with_scale("", 3.0e11).unwrap();
        assert_eq!(
            Config::from_toml_str(&big).unwrap().colour.rgb_scale,
            Some(3.0e11)
        );
    }

    #[test]
    fn a_dotted_colour_key_is_rewritten_as_a_table() {
        let out = with_scale("colour.primaries = \"srgb-iec\"\n", 2.0).unwrap();
        let cfg = Config::from_toml_str(&out).unwrap();
        assert_eq!(cfg.colour.rgb_scale, Some(2.0));
    }

    #[test]
    fn a_stored_scale_is_kept_only_for_the_same_config() {
        let dir = tempfile::tempdir().unwrap();
        let text = "[sample]\nisotropic = true\n";
        std::fs::write(
            dir.path().join("config.toml"),
            with_scale(text, 42.0).unwrap(),
        )
        .unwrap();
        assert_eq!(stored(dir.path(), text), Some(42.0));
        assert_eq!(stored(dir.path(), "[sample]\nisotropic = false\n"), None);
        assert_eq!(stored(&dir.path().join("none"), text), None);
    }
}
