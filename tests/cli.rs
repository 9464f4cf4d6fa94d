//! The binary's commands end to end: JSON output, per-file errors, exit codes, bad configs.

mod common;
use common::reference;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_goniowatch"))
}

#[test]
fn average_json_one_line_per_file_and_errors_inline() {
    let good = reference("images/valid/f32_zip.exr");
    let bad = reference("images/invalid/comp_early_eof_piz.exr");
    let missing = reference("images/valid/does-not-exist.exr");
    let hdr = reference("images/valid/image1.hdr");
    let out = bin()
        .arg("average")
        .arg("--json")
        .args([&good, &bad, &missing, &hdr])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(1),
        "a failed file gives a non-zero exit at the end"
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 4, "the other files are still processed");
    for (l, ok) in lines.iter().zip([true, false, false, true]) {
        assert!(l["file"].is_string());
        if ok {
            for key in ["mean_rgb", "xyz"] {
                assert_eq!(l[key].as_array().unwrap().len(), 3);
            }
            assert!(l["pixels"].as_u64().unwrap() > 0);
            assert!(l["nonfinite"].is_u64());
            assert!(l.get("error").is_none());
        } else {
            assert!(l["error"].as_str().unwrap().len() > 5, "{l}");
        }
    }
    assert!(lines[2]["error"]
        .as_str()
        .unwrap()
        .contains("cannot read file"));
}

#[test]
fn average_roi_and_config() {
    let f = reference("images/valid/Desk.exr");
    let out = bin()
        .args(["average", "--json", "--roi", "margin:10"])
        .arg(&f)
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["pixels"].as_u64().unwrap(), (644 - 20) * (874 - 20));
    let out = bin()
        .args(["average", "--roi", "circle:3"])
        .arg(&f)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--roi"));
    // the shipped config works with average
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/config/ubo.toml");
    let out = bin()
        .args(["average", "--json", "--config", cfg])
        .arg(&f)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn plan_json_has_the_ubo_counts() {
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/config/ubo.toml");
    for args in [
        vec!["plan", "--json"],
        vec!["plan", "--json", "--config", cfg],
    ] {
        let out = bin().args(&args).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["directions"], 81);
        assert_eq!(v["captures"], 6561);
        assert_eq!(v["reciprocal_pairs"], 3240);
        assert_eq!(v["self_pairs"], 81);
        assert_eq!(v["isotropy_classes"], 364);
        assert_eq!(v["occlusion_substitutes"], 81);
        assert_eq!(v["substitutes"].as_array().unwrap().len(), 81);
    }
    let out = bin().arg("plan").output().unwrap();
    assert!(String::from_utf8_lossy(&out.stdout).contains("reciprocal pairs       3240"));
}

#[test]
fn plan_designs_the_probe_cadence_or_says_why_no_cadence_can() {
    let out = bin().args(["plan", "--json"]).output().unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let design = &v["probes"]["design"];
    assert_eq!(design["outcome"], "recommended", "{design}");
    // a −2 % step must be seen within 300 captures: a probe at least every 300
    assert!(
        design["cadence"]["every"].as_u64().unwrap() <= 300,
        "{design}"
    );
    assert!(design["cadence"]["meets"].as_bool().unwrap());
    assert_eq!(
        v["probes"]["configured"],
        serde_json::Value::Null,
        "probes are off"
    );

    // a probe pose that scatters by 2 % cannot show a 2 % step
    let out = bin()
        .args(["plan", "--probe-scatter-pct", "2"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("NO CADENCE MEETS THE TARGET"), "{text}");
    assert!(text.contains("the probe scatter (2 %)"), "{text}");

    // a target the flags make impossible to state is a usage error naming the value
    let out = bin()
        .args(["plan", "--probe-scatter-pct", "0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("scatter_pct"));
}

#[test]
fn plan_designs_anisotropic_probes_for_the_colour_target_too() {
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/config/sim-anisotropic.toml");
    let every = |extra: &[&str]| {
        let out = bin()
            .args(["plan", "--json", "--config", cfg])
            .args(extra)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let design = v["probes"]["design"].clone();
        assert_eq!(design["outcome"], "recommended", "{design}");
        (design["cadence"]["every"].as_u64().unwrap(), design)
    };
    // the default target includes a −20 K/h colour drift before 15 % of the run, which only
    // the probes watch on an anisotropic sample: denser probes than the luminance target asks
    let (with_colour, design) = every(&[]);
    let (luminance_only, _) = every(&["--target-colour-k-per-h", "0"]);
    assert!(
        with_colour < luminance_only,
        "{with_colour} {luminance_only}"
    );
    assert!(
        design["cadence"]["colour_in_time"].as_f64().unwrap() >= 0.9,
        "{design}"
    );
    // the sparser cadences tried missed the colour target
    let tried = design["tried"].as_array().unwrap();
    assert!(tried
        .iter()
        .filter(|c| c["every"].as_u64().unwrap() >= luminance_only)
        .all(|c| c["colour_in_time"].as_f64().unwrap() < 0.9));
    // an isotropic sample's colour is its isotropy classes' job: no colour figures
    let out = bin().args(["plan", "--json"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        v["probes"]["design"]["cadence"]["colour_in_time"],
        serde_json::Value::Null
    );
    // a deadline that cannot be stated is a usage error naming the value
    let out = bin()
        .args(["plan", "--config", cfg, "--target-colour-by", "0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("colour_by_fraction"));
}

#[test]
fn bad_config_names_the_field_and_exits_2() {
    let dir = std::env::temp_dir().join(format!("gw-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (text, field) in [
        ("[rig]\nmin_separation = 3\n", "min_separation"),
        ("[plan]\norder = \"zigzag\"\n", "order"),
        ("[capture]\nclip_level = -1\n", "capture.clip_level"),
        (
            "[capture.roi]\nkind = \"margin-fraction\"\nfraction = 0.7\n",
            "capture.roi.fraction",
        ),
        ("[rig.joints]\n", "joints"),
        ("this is not toml", "expected"),
        // accepted before range checks, then crashed, hung or exhausted memory at run time
        ("[ingest]\ngive_up_s = 1e308\n", "ingest.give_up_s"),
        ("[ingest]\nworkers = 100000000\n", "ingest.workers"),
        (
            "[ingest]\ndecode_threads = 1000000\n",
            "ingest.decode_threads",
        ),
        ("[link]\nbaud = 0\n", "link.baud"),
        (
            "[plan]\nthetas_deg = [0, 15, 30]\ndelta_phi_deg = [0, 1e-9, 30]\n",
            "plan.delta_phi_deg[1]",
        ),
        ("[ingest]\nretry_first_ms = 0\n", "ingest.retry_first_ms"),
        (
            "[ingest]\nretry_first_ms = 5000\nretry_max_ms = 100\n",
            "ingest.retry_max_ms",
        ),
        ("[alarms]\ncrc_window = 0\n", "alarms.crc_window"),
        ("[probes]\nz = nan\n", "probes.z"),
        ("[ingest]\nmax_decode_mib = 1\n", "ingest.max_decode_mib"),
    ] {
        let p = dir.join("bad.toml");
        std::fs::write(&p, text).unwrap();
        let out = bin().args(["plan", "--config"]).arg(&p).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{text}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(field), "{text}: {err}");
    }
    let out = bin()
        .args(["plan", "--config", "/nonexistent/x.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read config"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn average_refuses_a_fifo_at_once() {
    let dir = std::env::temp_dir().join(format!("gw-cli-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("cap.exr");
    let _ = std::fs::remove_file(&fifo);
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a file system entry.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let mut child = bin()
        .args(["average", "--json"])
        .arg(&fifo)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // a guard against a hang, not a timing check: reading a FIFO with no writer never ends
    let mut status = None;
    for _ in 0..600 {
        if let Some(s) = child.try_wait().unwrap() {
            status = Some(s);
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let Some(status) = status else {
        child.kill().ok();
        panic!("average hung on a FIFO");
    };
    let mut text = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().unwrap(), &mut text).unwrap();
    assert_eq!(status.code(), Some(1), "{text}");
    assert!(text.contains("FIFO"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_configured_decode_budget_refuses_a_hostile_header() {
    let dir = std::env::temp_dir().join(format!("gw-cli-budget-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("small.toml");
    std::fs::write(&cfg, "[ingest]\nmax_decode_mib = 16\n").unwrap();
    let crafted = reference("images/crafted/channels200_half_zip.exr");
    let out = bin()
        .args(["average", "--json", "--config"])
        .arg(&cfg)
        .arg(&crafted)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("over the budget"), "{text}");
    // the 5,003-channel header is refused even under the default budget
    let out = bin()
        .args(["average", "--json"])
        .arg(reference("images/crafted/channels5000_half_piz.exr"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("over the budget"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A corpus session's expected results as a session folder of their own, for `report`.
fn corpus_results(name: &str) -> std::path::PathBuf {
    let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/sessions")
        .join(name);
    let dir = std::env::temp_dir().join(format!("gw-cli-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for f in ["config.toml", "session.json"] {
        std::fs::copy(src.join(f), dir.join(f)).unwrap();
    }
    for e in std::fs::read_dir(src.join("expected")).unwrap().flatten() {
        std::fs::copy(e.path(), dir.join(e.file_name())).unwrap();
    }
    dir
}

#[test]
fn the_report_plots_the_isotropy_gain_estimate_when_there_are_no_probes() {
    for (name, isotropy_line) in [("decay", true), ("probe-step", false), ("clean", false)] {
        let dir = corpus_results(name);
        let r = bin().arg("report").arg(&dir).output().unwrap();
        assert_eq!(
            r.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
        assert_eq!(
            html.contains("isotropy-class gain estimate, as known at each capture"),
            isotropy_line,
            "{name}"
        );
        assert!(
            !html.contains("No gain estimate") || name == "clean",
            "{name}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}

#[test]
fn the_report_says_what_to_do_about_each_alarm_and_which_captures_it_affects() {
    // joint 2 slipped at capture 2,000 of the joint-slip session
    let dir = corpus_results("joint-slip");
    let r = bin().arg("report").arg(&dir).output().unwrap();
    assert_eq!(
        r.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
    assert!(
        html.contains("<th>what to do</th><th>captures affected</th>"),
        "no advice columns"
    );
    assert!(html.contains("check the sample clamp and arm joint 2"));
    let csv = std::fs::read_to_string(dir.join("report/alarms.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("idx,t_s,severity,kind,code,message,action,affects")
    );
    let slip = lines
        .find(|l| l.contains("joint-offset-suspected"))
        .expect("the slip's row");
    // the affected captures start at or before the slip, and the retake list agrees
    let from: u64 = slip
        .rsplit("captures ")
        .next()
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{slip}"));
    assert!(slip.ends_with(" on: retake"), "{slip}");
    assert!((1900..=2000).contains(&from), "{slip}");
    let retakes = std::fs::read_to_string(dir.join("report/retakes.csv")).unwrap();
    let first_slipped = retakes
        .lines()
        .find(|l| l.contains("joint 2"))
        .and_then(|l| l.split(',').next())
        .and_then(|s| s.parse::<u64>().ok());
    assert_eq!(first_slipped, Some(from), "{retakes}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `report` of a session whose captures.jsonl was cut, mid-line or at a line boundary, is
/// refused with exit 3 and a message naming the file and how to rebuild it; nothing is written.
#[test]
fn a_report_of_a_cut_result_file_is_refused_not_read_short() {
    for (name, cut) in [("torn", true), ("short", false)] {
        let dir = corpus_results("decay");
        let path = dir.join("captures.jsonl");
        let text = std::fs::read(&path).unwrap();
        let lines: Vec<usize> = text
            .iter()
            .enumerate()
            .filter(|(_, b)| **b == b'\n')
            .map(|(i, _)| i)
            .collect();
        let keep = if cut {
            lines[lines.len() - 8] + 40
        } else {
            lines[lines.len() - 9] + 1
        };
        std::fs::write(&path, &text[..keep]).unwrap();
        let r = bin().arg("report").arg(&dir).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(3), "{name}: {err}");
        assert!(
            err.contains("captures.jsonl")
                && err.contains(if cut { "torn line" } else { "incomplete" })
                && err.contains("replay"),
            "{name}: {err}"
        );
        assert!(!dir.join("report").exists(), "{name}: a report was written");
        std::fs::remove_dir_all(&dir).ok();
    }
}
