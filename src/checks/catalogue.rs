//! The alarm catalogue: for every [`AlarmCode`], its kind, the severities it is raised at, what
//! it means, the evidence it carries and what the operator should do. `goniowatch alarms`
//! prints it, docs/alarms.md is generated from it, and the recorded sessions' alarms are tested
//! against it, so a new code cannot ship undocumented.

use crate::checks::alarm::{AlarmCode, AlarmKind, Severity};
use serde::Serialize;

/// One code's entry.
#[derive(Debug, Clone, Serialize)]
pub struct CodeEntry {
    pub code: AlarmCode,
    pub kind: AlarmKind,
    /// Every severity it is raised at (a storm's aggregate keeps the worst of those held).
    pub severities: &'static [Severity],
    pub meaning: &'static str,
    /// The fields of its `evidence`, when it has any.
    pub evidence: &'static [&'static str],
    /// What to do.
    pub action: &'static str,
}

impl CodeEntry {
    /// Whether it can be critical: a critical alarm makes the run exit 4 and, with
    /// `[alarms] pause_on_critical`, asks the rig to PAUSE.
    pub fn can_be_critical(&self) -> bool {
        self.severities.contains(&Severity::Critical)
    }
}

const INFO: &[Severity] = &[Severity::Info];
const WARNING: &[Severity] = &[Severity::Warning];
const CRITICAL: &[Severity] = &[Severity::Critical];
const WARNING_OR_CRITICAL: &[Severity] = &[Severity::Warning, Severity::Critical];
const INFO_OR_WARNING: &[Severity] = &[Severity::Info, Severity::Warning];

/// The entry of `code`.
pub fn entry(code: AlarmCode) -> CodeEntry {
    use AlarmCode as C;
    use AlarmKind as K;
    let (kind, severities, evidence, action): (_, _, &'static [&'static str], _) = match code {
        C::AnnouncementRefused => (K::CaptureQuality, WARNING, &["idx", "reason"], "Check the controller's CAPTURE line for that index (the reason says which field); the capture is left out of the checks and counted."),
        C::BadAnnouncement => (K::Link, WARNING, &[], "Nothing, if it is rare: the line is asked for again. If it repeats, check the controller's output for that capture."),
        C::BadEntry => (K::CaptureQuality, WARNING, &[], "Check the controller's plan and the config's [plan]: they must describe the same acquisition."),
        C::BadLine => (K::Link, WARNING, &[], "Nothing, if it is rare. If it repeats, check the serial cable, its shielding and the baud rate."),
        C::BadPose => (K::Positioning, WARNING, &[], "Check the controller's pose fields (four finite angles) and the rig model in [rig]."),
        C::CaptureFailed => (K::CaptureQuality, WARNING_OR_CRITICAL, &[], "Look at the file (camera, disk, transfer); the capture is on the retake list. Critical after `failures_critical` in a row: stop and fix the camera or the disk."),
        C::MissingCapture => (K::CaptureQuality, WARNING_OR_CRITICAL, &["file", "consecutive_failures"], "Check where the camera writes and that the capture root is the right folder; the capture is on the retake list. Critical after `failures_critical` in a row."),
        C::CaptureNeverAnnounced => (K::CaptureQuality, WARNING_OR_CRITICAL, &["count", "first", "last"], "The controller's capture log lacks these indices: check the controller's log; the captures are on the retake list."),
        C::CapturesPending => (K::CaptureQuality, INFO, &[], "Nothing: announced captures wait to be decoded (a slow disk or a burst)."),
        C::ClippedPixels => (K::CaptureQuality, WARNING, &["clipped", "pixels", "max_value"], "Shorten the exposure or add an exposure to the bracket; the capture is on the retake list."),
        C::ColourDrift => (K::Drift, WARNING, &["k_per_h", "se_k_per_h", "de00_per_h", "lamp_cct_k", "x_rate_pct_per_h", "z_rate_pct_per_h", "n", "source"], "Let the lamp settle or check its supply voltage; the corrected colours divide the drift out."),
        C::ColourDriftCleared => (K::Drift, INFO, &[], "Nothing: the colour drift no longer holds."),
        C::ControllerFault => (K::Link, CRITICAL, &[], "Go to the rig: the controller reported a fault; the run is stopped until it is cleared."),
        C::ControllerReboot => (K::Link, WARNING, &[], "Check why the controller restarted (power, watchdog); goniowatch asks it where it stands and goes on."),
        C::CrcErrors => (K::Link, WARNING, &["bad_lines", "window"], "Check the serial cable, its shielding and grounding, and the baud rate."),
        C::DaemonRestart => (K::Link, INFO, &[], "Nothing: goniowatch resumed the session from its journal."),
        C::DarkCapture => (K::CaptureQuality, WARNING, &["y"], "Check the lamp, the shutter and the lens cap; if every capture is dark, the files are on another scale than [colour] rgb_scale. The capture is on the retake list."),
        C::DuplicateFiles => (K::CaptureQuality, WARNING, &["groups"], "Move copies and rejected files out of the capture folder so that each plan entry has one file; the evidence names the file checked for each entry."),
        C::DuplicateIndex => (K::CaptureQuality, WARNING, &["kept", "ignored"], "Check the controller's capture numbering: two different captures carry one index; the first is kept."),
        C::EncoderMismatch => (K::Positioning, WARNING, &["axis", "enc", "cmd"], "Check the axis's encoder, motor and coupling; the alarm's own advice says whether the captures must be retaken."),
        C::EncoderMismatchCleared => (K::Positioning, INFO, &["axis", "captures", "first_idx", "last_idx", "worst_deg", "by_command"], "Nothing more: the episode ended; its captures are judged as the opening alarm said."),
        C::EntryRepeated => (K::CaptureQuality, INFO, &[], "Nothing: a plan entry was taken again; the first usable capture of it is used."),
        C::GainDrift => (K::Drift, WARNING, &["rate_pct_per_h", "se_pct_per_h", "n", "source"], "Let the lamp warm up and settle, or check its supply; the corrected colours divide the drift out, so no capture needs taking again."),
        C::GainDriftCleared => (K::Drift, INFO, &[], "Nothing: the drift rate is back within the tolerance."),
        C::GainStep => (K::Drift, WARNING, &["source", "level_pct", "sweeps", "since_idx", "since_t", "statistic", "threshold", "direction"], "Check the lamp, its supply and anything that may shade or reflect onto the sample; the step is divided out of the corrected colours. Recurring steps mean an unstable lamp."),
        C::GainStepWithdrawn => (K::Positioning, INFO, &["source", "joint", "step_idx", "level_pct", "slip_from_idx"], "Nothing: a step was explained by a named joint slip instead."),
        C::JointOffsetSuspected => (K::Positioning, WARNING, &["joint", "offset_deg", "source", "since_idx", "statistic", "threshold", "entry", "sensitivity_pct_per_deg", "recapture", "axis"], "Check the named joint (or the wagon): re-home it or re-seat the sample; the captures since the slip are on the retake list."),
        C::Joint3SentinelUnavailable => (K::Positioning, INFO, &[], "Nothing to do now: no pose of this sample moves enough with arm joint 3 to watch it; its slips go unseen."),
        C::LampUnstable => (K::Drift, WARNING, &["scatter_pct", "design_scatter_pct", "probes", "limit_pct", "sweeps", "source"], "Check the lamp's supply and connections; a flickering lamp makes every capture noisier, and the correction cannot divide flicker out."),
        C::LampUnstableCleared => (K::Drift, INFO, &["scatter_pct", "design_scatter_pct", "probes", "limit_pct", "sweeps", "source"], "Nothing: the probes (or the light sweeps) scatter within the design again."),
        C::LevelAfterSlip => (K::Positioning, INFO, &["source", "joint", "level_pct", "sweeps", "since_idx", "slip_from_idx", "statistic", "threshold"], "Nothing: the level change after a named slip is recorded for the drift fits."),
        C::NonFinitePixels => (K::CaptureQuality, WARNING, &["nonfinite", "pixels"], "Check the HDR merge that wrote the file; the non-finite pixels are left out of the average."),
        C::PortBack => (K::Link, INFO, &[], "Nothing: the serial port is open again and the session goes on."),
        C::PortLost => (K::Link, WARNING, &[], "Check the USB-serial adapter and its cable; goniowatch reopens the port with backoff and asks for what it missed."),
        C::PoseOffPlan => (K::Positioning, WARNING, &["pose_error_deg", "enc", "cmd"], "Check the rig's positioning; captures placed off the plan are on the retake list."),
        C::PoseOffPlanCleared => (K::Positioning, INFO, &["axis", "captures", "first_idx", "last_idx", "worst_deg", "by_command"], "Nothing more: the episode ended; its captures are on the retake list."),
        C::ProbesRefused => (K::Drift, WARNING, &["reason", "probes_taken"], "Enable remote actions at the rig (its PROBE command) and restart goniowatch to get the probes back. Meanwhile the lamp is watched from the reciprocal pairs and the sweeps: slower to flag a step, blind to an anisotropic sample's lamp colour, and with no joint-3 sentinel."),
        C::ProbeMovedWithPose => (K::Drift, INFO, &["direction", "statistic", "threshold", "probe_idx", "pose_z", "wagon_deg", "probe_sensitivity_pct_per_deg"], "Nothing for the lamp: the probe moved with the camera's pose, which the positioning checks name (wagon-offset-suspected, wagon-backlash-suspected, joint-offset-suspected); the probes' trend starts again at this probe."),
        C::ProbePoseUnavailable => (K::Drift, WARNING, &[], "Configure [probes] entry with a pose the rig can take, or leave probes off; the lamp is then watched without probes."),
        C::ReciprocityOutlier => (K::ReciprocityOutlier, WARNING, &["de2000", "limit", "median", "mad", "pairs", "a", "b", "theta_pair_deg"], "Look at the two captures (a reflection, a shadow, dust); both are on the retake list."),
        C::SampleOffCentre => (K::Isotropy, WARNING, &["camera_pct", "camera_azimuth_deg", "camera_se_pct", "light_pct", "light_azimuth_deg", "light_se_pct", "rate_inflation", "source"], "Re-centre the sample in its holder at the next chance; the drift checks model the pattern from now on."),
        C::SessionChanged => (K::Link, CRITICAL, &[], "The controller started another session: start goniowatch on a new session folder for it."),
        C::SkippedFiles => (K::CaptureQuality, INFO_OR_WARNING, &["counts", "files"], "Give captures among them names the pattern places (or sidecar rows); other files can stay. Info when they are only files of other types."),
        C::SlipUnresolved => (K::Positioning, INFO, &["joint", "offset_deg", "layer_deg", "light", "sweeps_before", "before_deg", "before_se_deg", "change_z", "threshold_z", "source"], "Nothing now: no alarm is raised and no capture is put on the retake list. Without re-captures a pattern present since its θi layer began is as much the new θi's geometry (a lamp beam or a holder that follows the pose) as a slip at the layer's start; a slip later in the layer is still named against it. Drift probes ([probes] every) re-capture earlier poses and tell the two apart; if the joint may have slipped, check it before the next layer."),
        C::SlipUnverifiable => (K::Positioning, INFO, &["joint", "offset_deg", "checkable_deg", "layer_deg", "light", "source"], "Nothing now: no alarm is raised and no capture is put on the retake list. The sweeps alone cannot tell a pattern this small from the geometry's (a lamp beam or a holder that follows the pose), and re-captures of earlier poses would not show it; if it grows to checkable_deg the sweeps ask for re-captures and name the slip they confirm. Later patterns of this θi layer below that size are not reported again."),
        C::SlipRefuted => (K::Positioning, INFO, &["joint", "offset_deg", "recapture", "source"], "Nothing: no alarm is raised. The sweeps' pattern is the geometry's (a lamp beam or a holder that follows the pose), not a slip; the eight re-captures are probes of the run."),
        C::StepUnresolved => (K::Drift, INFO, &["level_pct", "sweeps", "since_idx", "statistic", "threshold", "layer_deg", "light", "below_deg", "below_pct", "below_se_pct", "growth", "threshold_z", "source"], "Nothing now: no alarm is raised and nothing is corrected. Without probes a level that follows the layer below's departure from its pattern is as much a stationary pattern of the light's direction (a holder's shadow, a bowed sample) as a lamp step; the step is raised if the level stays off as the light turns on. Drift probes ([probes] every) tell the two apart at once; if the lamp may have stepped, check it."),
        C::TrendUnresolved => (K::Drift, INFO, &["rate_pct_per_h", "se_pct_per_h", "robust_rate_pct_per_h", "robust_se_pct_per_h", "n", "source"], "Nothing yet: no alarm is raised. Probes ([probes] every) would tell a drift from the pattern at once; without them the isotropy classes decide as the light turns through more of its layers, and a drift they confirm is raised as gain-drift."),
        C::TimeSteppedBack => (K::Link, WARNING, &["step_s", "announced_t", "previous_t", "shift_s"], "Check the clock of the rig's computer and keep it from stepping during a run; the step is removed from the times."),
        C::UnannouncedFiles => (K::CaptureQuality, WARNING, &["files"], "Check the controller's capture log against the folder: files the controller never announced are not checked."),
        C::WagonBacklashSuspected => (K::Positioning, WARNING, &["backlash_deg", "se_deg", "offset_deg", "source", "approach", "since_idx", "statistic", "threshold"], "Check the wagon's drive for play (belt, gear, coupling): take it up, or have the controller approach every camera position from one side; the captures since the lag began are on the retake list."),
        C::WagonOffsetSuspected => (K::Positioning, WARNING, &["offset_deg", "se_deg", "entries", "change_pct", "sensitivity_pct_per_deg", "joint_leak", "originals_lights", "readings", "sweeps_z", "approach", "axis", "source", "since_idx", "statistic", "threshold"], "Pause the run; check the wagon against its reference mark on the arc (re-home it if it slipped), then resume; the captures since the last reading in control are on the retake list."),
        C::CameraPoseMoved => (K::Positioning, WARNING, &["offset_deg", "se_deg", "entries", "change_pct", "sensitivity_pct_per_deg", "joint_leak", "originals_lights", "readings", "sweeps_z", "approach", "axis", "source", "since_idx", "statistic", "threshold"], "Pause the run; check both the wagon against its reference mark on the arc and arm joint 1 (re-home whichever slipped, re-seat the sample if it moved), then resume; the captures since the last reading in control are on the retake list."),
        C::UnsupportedVersion => (K::Link, CRITICAL, &[], "Update the controller's firmware or goniowatch so that both speak the same protocol version."),
    };
    CodeEntry {
        code,
        kind,
        severities,
        meaning: code.meaning(),
        evidence,
        action,
    }
}

/// Every code's entry, by name.
pub(crate) fn catalogue() -> Vec<CodeEntry> {
    let mut v: Vec<CodeEntry> = AlarmCode::ALL.iter().map(|c| entry(*c)).collect();
    v.sort_by_key(|e| e.code);
    v
}

/// The catalogue as a Markdown table (docs/alarms.md holds it between markers).
pub fn markdown() -> String {
    let mut s = String::from(
        "| code | kind | severity | meaning | evidence | what to do |\n|---|---|---|---|---|---|\n",
    );
    for e in catalogue() {
        let sev: Vec<&str> = e
            .severities
            .iter()
            .map(|s| match s {
                Severity::Info => "info",
                Severity::Warning => "warning",
                Severity::Critical => "**critical**",
            })
            .collect();
        let ev = if e.evidence.is_empty() {
            "–".to_string()
        } else {
            e.evidence
                .iter()
                .map(|f| format!("`{f}`"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        s.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} |\n",
            e.code,
            e.kind.as_str(),
            sev.join(", "),
            e.meaning,
            ev,
            e.action
        ));
    }
    s
}

/// The anchor of `code`'s entry, `alarm-<code>`: the report's alarm table links to it within the
/// report, and the status page to `/alarms#alarm-<code>`, so its form is part of the contract.
/// Codes are kebab-case ASCII, so the anchor is a valid id and URL fragment as it stands.
pub(crate) fn anchor(code: AlarmCode) -> String {
    format!("alarm-{code}")
}

/// The style of the entries [`entry_html`] writes, for the pages that show them (the report's
/// appendix and the status server's `/alarms`), so that both read alike; a page adds it to its
/// own style sheet.
pub(crate) const ENTRY_STYLE: &str = "\
.alarm-entry{margin:10px 0 14px;break-inside:avoid;scroll-margin-top:12px}
.alarm-entry h3{font-size:15px;margin:0 0 4px}
.alarm-entry:target{outline:2px solid #1f5fa8;outline-offset:4px}
.alarm-entry dl{display:grid;grid-template-columns:9em minmax(0,1fr);gap:2px 12px;margin:0}
.alarm-entry dt{color:#5d6b78} .alarm-entry dd{margin:0;overflow-wrap:anywhere}
.alarm-entry .sev-critical{color:#c62828;font-weight:600}
.alarm-entry .sev-warning{color:#b86e00;font-weight:600} .alarm-entry .sev-info{color:#5d6b78}
";

/// `s` escaped for HTML text and for a double-quoted attribute value.
fn escape_html(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// The catalogue's words as HTML: escaped, each `backquoted` run (a config key or a command, as
/// docs/alarms.md shows it) in `<code>`; an unpaired backquote stays as it is.
fn words_html(s: &str) -> String {
    let parts: Vec<&str> = s.split('`').collect();
    // an even number of parts means an odd number of backquotes: the last one is unpaired
    let paired = parts.len() - (1 - parts.len() % 2);
    let mut out = String::with_capacity(s.len() + 16);
    for (i, part) in parts.iter().enumerate() {
        if i >= paired {
            out.push('`');
            out.push_str(&escape_html(part));
        } else if i % 2 == 1 {
            out.push_str("<code>");
            out.push_str(&escape_html(part));
            out.push_str("</code>");
        } else {
            out.push_str(&escape_html(part));
        }
    }
    out
}

fn severity_name(s: Severity) -> &'static str {
    match s {
        Severity::Info => "info",
        Severity::Warning => "warning",
        Severity::Critical => "critical",
    }
}

/// One code's entry as HTML: a `<section class="alarm-entry" id="alarm-<code>">` with the code
/// as its `<h3>` and a definition list of its severities, kind, meaning, evidence fields, what
/// to do and whether it can be critical. Every word from the catalogue is escaped.
pub(crate) fn entry_html(e: &CodeEntry) -> String {
    let code = escape_html(e.code.as_str());
    let severities = e
        .severities
        .iter()
        .map(|s| {
            let name = severity_name(*s);
            format!("<span class=\"sev-{name}\">{name}</span>")
        })
        .collect::<Vec<_>>()
        .join(", ");
    let evidence = if e.evidence.is_empty() {
        "none".to_string()
    } else {
        e.evidence
            .iter()
            .map(|f| format!("<code>{}</code>", escape_html(f)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let critical = if e.can_be_critical() {
        "yes: a critical alarm ends the run with exit status 4 and, with <code>[alarms] pause_on_critical</code>, asks the rig to PAUSE"
    } else {
        "no"
    };
    format!(
        "<section class=\"alarm-entry\" id=\"{id}\"><h3><code>{code}</code></h3><dl>\
         <dt>severity</dt><dd>{severities}</dd>\
         <dt>kind</dt><dd>{kind}</dd>\
         <dt>meaning</dt><dd>{meaning}</dd>\
         <dt>evidence</dt><dd>{evidence}</dd>\
         <dt>what to do</dt><dd>{action}</dd>\
         <dt>can be critical</dt><dd>{critical}</dd>\
         </dl></section>\n",
        id = escape_html(&anchor(e.code)),
        kind = escape_html(e.kind.as_str()),
        meaning = words_html(e.meaning),
        action = words_html(e.action),
    )
}

/// The entries of `codes` as HTML, each code once and in name order (the catalogue's order),
/// so that each anchor occurs once on a page that shows them.
pub(crate) fn entries_html(codes: impl IntoIterator<Item = AlarmCode>) -> String {
    let codes: std::collections::BTreeSet<AlarmCode> = codes.into_iter().collect();
    codes.into_iter().map(|c| entry_html(&entry(c))).collect()
}

/// Every code's entry as HTML (the status server's `/alarms`).
pub(crate) fn catalogue_html() -> String {
    entries_html(AlarmCode::ALL)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The values of every `id="…"` in `html`.
    fn ids(html: &str) -> Vec<&str> {
        html.split(" id=\"")
            .skip(1)
            .filter_map(|rest| rest.split('"').next())
            .collect()
    }

    #[test]
    fn every_code_renders_with_one_unique_anchor() {
        let html = catalogue_html();
        let anchors = ids(&html);
        assert_eq!(anchors.len(), AlarmCode::ALL.len());
        let unique: std::collections::BTreeSet<&str> = anchors.iter().copied().collect();
        assert_eq!(unique.len(), anchors.len(), "an anchor occurs twice");
        for code in AlarmCode::ALL {
            let e = entry(code);
            let one = entry_html(&e);
            assert_eq!(ids(&one), [anchor(code).as_str()]);
            assert!(html.contains(&one), "{code} is not in the catalogue's HTML");
            // each of the entry's parts is there, escaped as HTML text
            assert!(
                one.contains(&format!("<h3><code>{code}</code></h3>")),
                "{one}"
            );
            assert!(one.contains(&escape_html(e.kind.as_str())), "{one}");
            for field in e.evidence {
                assert!(one.contains(&format!("<code>{field}</code>")), "{one}");
            }
            for s in e.severities {
                assert!(
                    one.contains(&format!(">{}</span>", severity_name(*s))),
                    "{one}"
                );
            }
            assert_eq!(
                one.contains("yes: a critical alarm"),
                e.can_be_critical(),
                "{code}"
            );
            assert!(one.contains(&words_html(e.meaning)) && one.contains(&words_html(e.action)));
            // no raw quote or angle bracket of the words survives: the only markup is ours
            let text_only = strip_known_markup(&one);
            assert!(
                !text_only.contains(['<', '>', '"']),
                "{code}: unescaped markup in {text_only}"
            );
        }
        // a set renders each code once, in name order, whatever order and repeats it is given
        let some = entries_html([
            AlarmCode::GainStep,
            AlarmCode::DarkCapture,
            AlarmCode::GainStep,
        ]);
        assert_eq!(ids(&some), ["alarm-dark-capture", "alarm-gain-step"]);
        assert!(entries_html([]).is_empty());
    }

    /// `html` with the tags [`entry_html`] writes removed (and their attributes with them).
    fn strip_known_markup(html: &str) -> String {
        let mut out = String::new();
        let mut rest = html;
        while let Some(start) = rest.find('<') {
            out.push_str(&rest[..start]);
            let tag_end = rest[start..].find('>').map(|k| start + k + 1);
            let Some(end) = tag_end else {
                out.push_str(&rest[start..]);
                return out;
            };
            let tag = &rest[start + 1..end - 1];
            let name = tag
                .trim_start_matches('/')
                .split([' ', '>'])
                .next()
                .unwrap_or("");
            if ["section", "h3", "code", "dl", "dt", "dd", "span"].contains(&name) {
                rest = &rest[end..];
            } else {
                out.push_str(&rest[start..end]);
                rest = &rest[end..];
            }
        }
        out.push_str(rest);
        out
    }

    #[test]
    fn entries_escape_their_words() {
        let e = CodeEntry {
            code: AlarmCode::DarkCapture,
            kind: AlarmKind::CaptureQuality,
            severities: &[Severity::Warning],
            meaning: "<script>alert(\"x\")</script> & 'more'",
            evidence: &["a<b"],
            action: "set `[x] y = \"<z>\"` then `unpaired",
        };
        let html = entry_html(&e);
        assert!(
            !html.contains("<script>") && !html.contains("a<b"),
            "{html}"
        );
        assert!(
            html.contains("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &#39;more&#39;"),
            "{html}"
        );
        assert!(html.contains("<code>a&lt;b</code>"), "{html}");
        assert!(
            html.contains("set <code>[x] y = &quot;&lt;z&gt;&quot;</code> then `unpaired"),
            "{html}"
        );
        assert_eq!(words_html("no quotes"), "no quotes");
        assert_eq!(
            words_html("`a` and `b`"),
            "<code>a</code> and <code>b</code>"
        );
        assert_eq!(words_html("`"), "`");
    }

    #[test]
    fn every_code_has_an_entry_with_words() {
        let all = catalogue();
        assert_eq!(all.len(), AlarmCode::ALL.len());
        for e in &all {
            assert!(
                !e.severities.is_empty() && !e.action.is_empty(),
                "{}",
                e.code
            );
            assert!(!e.action.contains('|') && !e.meaning.contains('|'));
        }
        // the ones a run can end on with exit 4
        let critical: Vec<String> = all
            .iter()
            .filter(|e| e.can_be_critical())
            .map(|e| e.code.to_string())
            .collect();
        assert_eq!(
            critical,
            [
                "capture-failed",
                "capture-never-announced",
                "controller-fault",
                "missing-capture",
                "session-changed",
                "unsupported-version"
            ]
        );
    }
}
