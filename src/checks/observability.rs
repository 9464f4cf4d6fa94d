//! What the checks can and cannot see for a session's sample, plan and probes: a pure function
//! of the configuration, said at the start (the daemon's log), in the summary, on the status page
//! and in the report, each blind spot with why and what would make it observable. An operator
//! must not read "no alarm" as "no drift" where no detector looks.

use crate::measure::plan::AcquisitionOrder;
use serde::{Deserialize, Serialize};

/// A drift or fault the session cannot observe.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlindSpot {
    pub what: String,
    pub why: String,
    /// What would make it observable.
    pub remedy: String,
}

/// The session's detectors and blind spots.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Observability {
    /// What is watched, and from what.
    pub watched: Vec<String>,
    pub blind: Vec<BlindSpot>,
}

fn blind(what: &str, why: &str, remedy: &str) -> BlindSpot {
    BlindSpot {
        what: what.into(),
        why: why.into(),
        remedy: remedy.into(),
    }
}

/// The detectors a session runs and what they cannot see: `isotropic` as declared in
/// `[sample]`, `probes` whether drift probes are enabled, `sweeps` whether the light-sweep
/// checks are enabled in the config, `sentinel` whether probes of an anisotropic sample are
/// followed by a joint-3 sentinel (`[probes] sentinel`), `wagon_watch` whether a probe-taking
/// rig's sweeps re-capture a pair for the wagon (`[checks.sweeps] wagon_watch_sweeps`).
pub(crate) fn observability(
    isotropic: bool,
    probes: bool,
    order: AcquisitionOrder,
    sweeps: bool,
    sentinel: bool,
    wagon_watch: bool,
) -> Observability {
    let light_outer = !matches!(order, AcquisitionOrder::CameraOuter);
    let sweeps_run = isotropic && sweeps && light_outer;
    let mut o = Observability::default();
    o.watched.push(
        "each capture's pose: encoders against the command and the plan, on every axis".into(),
    );
    o.watched
        .push("reciprocity of every exact pair (Table 2) and capture quality".into());
    if probes {
        o.watched.push(
            "the lamp's gain (rate and steps), its stability (lamp-unstable) and colour (K/h), from the drift probes".into(),
        );
    }
    if isotropic {
        o.watched.push(
            if probes {
                "the lamp's colour (K/h) and its gain rate for the corrections (the probes alarm it), from isotropy classes (the same geometry at other times)"
            } else {
                "the lamp's gain rate, alarmed once it cannot be a stationary pattern of the light's direction (trend-unresolved until then), and its colour (K/h), from isotropy classes (the same geometry at other times)"
            }
            .into(),
        );
    }
    if sweeps_run {
        // with probes the sweeps leave the gain level and the lamp's stability to them
        o.watched.push(
            if probes {
                "arm joints 1 and 2 and the wagon's lag against its direction of motion, from the light sweeps (each light direction against the earlier ones), each joint slip they name confirmed by re-captures of earlier poses before it is alarmed"
            } else {
                "gain steps, the lamp's stability from capture to capture (lamp-unstable, θi ≤ 60° from a layer's fourth light), arm joints 1 and 2 and the wagon's lag against its direction of motion (not its constant offset), from the light sweeps (each light direction against the earlier ones)"
            }
            .into(),
        );
    }
    let probes_remedy =
        "enable drift probes ([probes] every = N): a re-capture of one pose every N captures; `goniowatch plan` prints the N that meets the detection target";
    if sweeps_run && probes && wagon_watch {
        o.watched.push(
            "the wagon's constant offset, from a pair of earlier poses re-captured every few light sweeps (about 1 % of the run), told from a joint-1 slip by the light sweeps".into(),
        );
    } else if sweeps_run {
        o.blind.push(blind(
            "the wagon's constant offset",
            "its pattern across a sweep's cameras is joint 1's along the arc, and the light sweeps' reference takes it up within a few sweeps; a re-capture of an earlier pose shows it",
            if probes {
                "set [checks.sweeps] wagon_watch_sweeps = 3: a pair of earlier poses re-captured every 3 light sweeps"
            } else {
                probes_remedy
            },
        ));
    }
    if !probes && !sweeps_run {
        o.blind.push(blind(
            "the lamp's stability from capture to capture (flicker)",
            "a re-capture of the same pose measures it, or the light sweeps' scatter about the isotropy model; isotropy classes and pairs alone differ by the sample's own pattern, which hides a flicker of a few per cent",
            probes_remedy,
        ));
    }
    if !isotropic {
        let why = "the sample is declared anisotropic ([sample] isotropic = false): it has no isotropy classes, and in a light-outer order a linear drift is confounded with the per-direction non-reciprocity of reciprocal pairs (detect::drift)";
        if !probes {
            o.blind.push(blind(
                "the lamp's gain drift (rate and steps)",
                why,
                probes_remedy,
            ));
        }
        if !probes {
            o.blind
                .push(blind("the lamp's colour drift", why, probes_remedy));
        }
        if probes && sentinel {
            o.watched.push(
                "arm joint 3 (the sample turning about its normal), from a sentinel probe after each drift probe; a tilt or a shift of the sample moves it too and is named as joint 3"
                    .into(),
            );
            o.blind.push(blind(
                "arm joints 1 and 2 slipping without the encoders seeing it, told apart from joint 3",
                "the light sweeps compare repeated geometry, which an anisotropic sample does not have; the sentinel sees a tilt but cannot say which joint",
                "none from the images alone; check the sample's mount and the encoders",
            ));
        } else {
            o.blind.push(blind(
                "arm joints 1, 2 and 3 slipping without the encoders seeing it",
                "the light sweeps compare repeated geometry, which an anisotropic sample does not have",
                if probes {
                    "joint 3: turn the sentinel on ([probes] sentinel = true); joints 1 and 2: none from the images alone, check the sample's mount and the encoders"
                } else {
                    "joint 3: drift probes ([probes] every = N) with their sentinel; joints 1 and 2: none from the images alone, check the sample's mount and the encoders"
                },
            ));
        }
    } else {
        // (arm joint 3 turns an isotropic sample about its normal, which does not change its
        // data: not a blind spot that matters)
        if !sweeps_run {
            o.blind.push(blind(
                "gain steps and arm joints 1 and 2 slipping without the encoders seeing it",
                if light_outer {
                    "the light-sweep checks are off ([checks.sweeps] enabled = false)"
                } else {
                    "the light sweeps need a light-outer acquisition order"
                },
                if probes {
                    "the probes still see gain steps; for the joints, a light-outer order with the sweeps on"
                } else {
                    "a light-outer order with the sweeps on, or drift probes for the gain steps"
                },
            ));
        }
        if !probes && !sweeps_run {
            o.blind.push(blind(
                "lamp gain steps",
                "isotropy classes give a rate only (their observations are too correlated in time for a step test)",
                probes_remedy,
            ));
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_isotropic_light_outer_session_watches_flicker_from_the_sweeps_or_the_probes() {
        let o = observability(true, false, AcquisitionOrder::LightOuter, true, true, true);
        // the one blind spot: the wagon's constant offset, which needs re-captures
        assert!(
            o.blind.len() == 1 && o.blind[0].what.contains("constant offset"),
            "{o:?}"
        );
        assert!(o
            .watched
            .iter()
            .any(|w| w.contains("lamp-unstable") && w.contains("light sweeps")));
        assert!(o.watched.iter().any(|w| w.contains("trend-unresolved")));
        // the sweeps off: flicker is a blind spot, with the probes as the remedy
        let o = observability(true, false, AcquisitionOrder::LightOuter, false, true, true);
        let f = o.blind.iter().find(|b| b.what.contains("flicker")).unwrap();
        assert!(f.remedy.contains("[probes]"));
        let o = observability(true, true, AcquisitionOrder::LightOuter, true, true, true);
        assert!(o.blind.is_empty(), "{o:?}");
        assert!(o.watched.iter().any(|w| w.contains("lamp-unstable")));
        // with probes a slip the sweeps name is confirmed by re-captures; without, it is not
        assert!(o
            .watched
            .iter()
            .any(|w| w.contains("joints 1 and 2") && w.contains("re-captures")));
        let o = observability(true, false, AcquisitionOrder::LightOuter, true, true, true);
        assert!(!o.watched.iter().any(|w| w.contains("re-captures")));
        let o = observability(true, false, AcquisitionOrder::LightOuter, true, true, true);
        assert!(o.watched.iter().any(|w| w.contains("colour")));
        assert!(o.watched.iter().any(|w| w.contains("joints 1 and 2")));
        assert!(o.watched.iter().any(|w| w.contains("the wagon's lag")));
        // without probes the wagon's constant offset is a blind spot with its remedy; with
        // them the re-captured pair watches it
        assert!(o
            .blind
            .iter()
            .any(|b| b.what.contains("constant offset") && b.remedy.contains("[probes] every")));
        let o = observability(true, true, AcquisitionOrder::LightOuter, true, true, true);
        assert!(o
            .watched
            .iter()
            .any(|w| w.contains("the wagon's constant offset")));
        let o = observability(true, true, AcquisitionOrder::LightOuter, true, true, false);
        assert!(
            o.blind
                .iter()
                .any(|b| b.what.contains("constant offset")
                    && b.remedy.contains("wagon_watch_sweeps"))
        );
    }

    #[test]
    fn an_anisotropic_sample_without_probes_says_the_lamp_is_unwatched_and_how_to_watch_it() {
        let o = observability(false, false, AcquisitionOrder::LightOuter, true, true, true);
        let gain = o
            .blind
            .iter()
            .find(|b| b.what.contains("gain drift"))
            .unwrap();
        assert!(gain.remedy.contains("[probes] every"));
        assert!(o.blind.iter().any(|b| b.what.contains("colour")));
        assert!(!o.watched.iter().any(|w| w.contains("lamp")));
        assert!(o
            .blind
            .iter()
            .any(|b| b.what.contains("joints 1, 2 and 3") && b.remedy.contains("sentinel")));
        // with probes the gain and the colour are watched, and joint 3 by the sentinel;
        // joints 1 and 2 still not
        let o = observability(false, true, AcquisitionOrder::LightOuter, true, true, true);
        assert!(!o.blind.iter().any(|b| b.what.contains("gain drift")));
        assert!(!o.blind.iter().any(|b| b.what.contains("colour")));
        assert!(o.watched.iter().any(|w| w.contains("joint 3")));
        assert!(o
            .blind
            .iter()
            .any(|b| b.what.starts_with("arm joints 1 and 2")));
        // the sentinel off: joint 3 is blind again
        let o = observability(false, true, AcquisitionOrder::LightOuter, true, false, true);
        assert!(o.blind.iter().any(|b| b.what.contains("joints 1, 2 and 3")));
        assert!(o
            .watched
            .iter()
            .any(|w| w.contains("probes") && w.contains("colour")));
    }

    #[test]
    fn a_camera_outer_order_loses_the_sweeps() {
        let o = observability(true, false, AcquisitionOrder::CameraOuter, true, true, true);
        assert!(o
            .blind
            .iter()
            .any(|b| b.what.contains("joints 1 and 2") && b.why.contains("light-outer")));
        assert!(o.blind.iter().any(|b| b.what == "lamp gain steps"));
        let o = observability(true, true, AcquisitionOrder::CameraOuter, true, true, true);
        assert!(!o.blind.iter().any(|b| b.what == "lamp gain steps"));
    }
}
