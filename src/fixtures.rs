//! Dev-only fixtures shared by the unit tests, `tests/` and `benches/`: a deterministic random
//! generator, a synthetic UBO session on a reciprocal BRDF, and a scripted controller. Compiled
//! for the crate's own tests and, through the `fixtures` feature (which the crate's
//! dev-dependency on itself turns on), for the integration tests and benchmarks; never in a
//! release build.

use crate::checks::{CaptureInput, CheckSpec, Checker, ColourSettings, Outcome};
use crate::detect::probes::ProbeSpec;
use crate::engine::Input;
use crate::measure::averaging::CaptureStats;
use crate::measure::colour::{RgbPrimaries, RgbToXyz, White};
use crate::measure::geometry::Vec3;
use crate::measure::kinematics::{Rig, RigSpec};
use crate::measure::plan::SamplingPlan;

/// SplitMix64 (the core's generator), so tests need no RNG crate and every run draws the same
/// numbers.
pub use crate::measure::stats::SplitMix64 as Rng;

/// Knuth's MMIX linear congruential generator: the draws behind the benchmarks' published
/// figures and several unit tests' data, kept so that they stay reproducible.
#[derive(Debug, Clone)]
pub struct Lcg(pub u64);

impl Lcg {
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    pub fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// What an ideal rig averages for a reciprocal, smooth BRDF (a grey-brown base and a
/// Blinn–Phong lobe): RGB times cos θi.
pub(crate) fn reciprocal_reading(wi: &Vec3, wo: &Vec3) -> [f64; 3] {
    let h = (wi + wo).normalize();
    let lobe = 0.6 * h.z.powi(40);
    [
        (0.40 + lobe) * wi.z,
        (0.34 + lobe) * wi.z,
        (0.25 + lobe) * wi.z,
    ]
}

/// sRGB primaries, D65 white with Y = 100, readings scaled by 100.
pub(crate) fn ubo_colour() -> ColourSettings {
    ColourSettings {
        to_xyz: RgbToXyz::new(RgbPrimaries::SrgbIec),
        rgb_scale: 100.0,
        white: White::d65_scaled(100.0).expect("D65 is a valid white"),
        min_cos: 1e-3,
    }
}

/// A checker for an isotropic sample on the UBO plan and the default rig, probes off.
pub fn ubo_checker() -> Checker {
    Checker::new(
        SamplingPlan::ubo(),
        Rig::new(RigSpec::default()).expect("the default rig is valid"),
        ubo_colour(),
        CheckSpec::default(),
        true,
        ProbeSpec::default(),
    )
}

/// A successful capture outcome of a 10 × 10 image with this mean.
pub fn ok_outcome(mean_rgb: [f64; 3]) -> Outcome {
    Outcome::Ok {
        stats: CaptureStats {
            mean_rgb,
            pixels: 100,
            nonfinite: 0,
            negative: 0,
            clipped: 0,
            dark: 0,
            max_value: 1.0,
        },
        width: 10,
        height: 10,
        size: 1,
        sha256: String::new(),
    }
}

/// The first `upto` captures of the UBO plan in light-outer order, one every 7 s, as the rig
/// would take them (commanded and encoder poses exact), of `reciprocal_reading` times
/// `gain(t in hours)`.
pub fn ubo_session(upto: usize, gain: impl Fn(f64) -> f64) -> Vec<CaptureInput> {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(RigSpec::default()).expect("the default rig is valid");
    let d = plan.directions();
    (0..upto.min(plan.capture_count()))
        .filter_map(|idx| {
            let e = plan.entry(idx).ok()?;
            let pp = rig
                .plan_pose(d[e.light].spherical(), d[e.camera].spherical())
                .ok()?;
            let r = [
                pp.pose.joints_deg[0],
                pp.pose.joints_deg[1],
                pp.pose.joints_deg[2],
                pp.pose.wagon_deg,
            ];
            let t = idx as f64 * 7.0;
            let g = gain(t / 3600.0);
            Some(CaptureInput {
                idx: idx as u64,
                entry: idx,
                file: format!("c{idx}.hdr"),
                t,
                cmd: r,
                enc: r,
                substitute: pp.substitute.map(|s| s.1),
                probe: false,
                outcome: ok_outcome(
                    reciprocal_reading(&pp.used.omega_i, &pp.used.omega_o).map(|v| v * g),
                ),
            })
        })
        .collect()
}

/// What an ideal rig averages for an anisotropic sample: `reciprocal_reading` times a factor
/// exp(sin²θi cos 2(φi − 20°) + sin²θo cos 2(φo − 20°)) whose lobes turn with the sample
/// (reciprocal, like the real thing).
pub(crate) fn anisotropic_reading(wi: &Vec3, wo: &Vec3) -> [f64; 3] {
    let aniso = |w: &Vec3| {
        let phi = w.y.atan2(w.x) - 20f64.to_radians();
        (1.0 - w.z * w.z) * (2.0 * phi).cos()
    };
    let f = (aniso(wi) + aniso(wo)).exp();
    reciprocal_reading(wi, wo).map(|v| v * f)
}

/// Capture `idx` of plan entry `entry` at `t` seconds, of `anisotropic_reading`, with arm joint
/// 3 turned by `turn_deg` that the encoders do not see (commanded and encoder poses are the
/// plan's). None when the rig cannot take the entry.
pub fn anisotropic_capture(
    idx: u64,
    entry: usize,
    t: f64,
    turn_deg: f64,
    probe: bool,
) -> Option<CaptureInput> {
    let plan = SamplingPlan::ubo();
    let rig = Rig::new(RigSpec::default()).expect("the default rig is valid");
    let d = plan.directions();
    let e = plan.entry(entry).ok()?;
    let pp = rig
        .plan_pose(d[e.light].spherical(), d[e.camera].spherical())
        .ok()?;
    let cmd = [
        pp.pose.joints_deg[0],
        pp.pose.joints_deg[1],
        pp.pose.joints_deg[2],
        pp.pose.wagon_deg,
    ];
    let mut actual = pp.pose;
    actual.joints_deg[2] += turn_deg;
    let seen = rig.forward(&actual).ok()?;
    Some(CaptureInput {
        idx,
        entry,
        file: format!("c{idx}.hdr"),
        t,
        cmd,
        enc: cmd,
        substitute: pp.substitute.map(|s| s.1),
        probe,
        outcome: ok_outcome(anisotropic_reading(&seen.omega_i, &seen.omega_o)),
    })
}

/// A scripted controller: numbers its lines, and writes the lines of docs/protocol.md.
#[derive(Debug, Clone, Default)]
pub struct Controller {
    pub seq: u32,
}

impl Controller {
    /// The next line, as the engine receives it.
    pub fn line(&mut self, verb: &str, fields: &[(&str, String)]) -> Input {
        let l = crate::protocol::format(self.seq, verb, fields);
        self.seq += 1;
        Input::Rx { line: l }
    }
    /// IDENT of a rig with 6,561 captures after boot `boot`.
    pub fn ident(&mut self, boot: u64) -> Input {
        self.line(
            "IDENT",
            &[
                ("rig", "r".into()),
                ("fw", "1".into()),
                ("proto", "1".into()),
                ("session", "s".into()),
                ("captures", "6561".into()),
                ("boot", boot.to_string()),
            ],
        )
    }
    /// CAPTURE of plan entry `idx + 1` as `s/cap_<idx>.hdr`, taken at 7 s × `idx`.
    pub fn capture(&mut self, idx: u64) -> Input {
        self.line(
            "CAPTURE",
            &[
                ("idx", idx.to_string()),
                ("entry", (idx + 1).to_string()),
                ("file", format!("s/cap_{idx}.hdr")),
                ("t", format!("{}", idx as f64 * 7.0)),
                ("cmd", "0,90,-90,15".into()),
                ("enc", "0,90,-90,15".into()),
                ("exp", "x".into()),
            ],
        )
    }
}
