//! `goniowatch export` end to end on the recorded corpus sessions (tests/sessions): the MERL
//! file read back by a reader written here from the format's description (not from the
//! writer), the table's columns and corrections, the sidecar's verdict, and every refusal with
//! its exit status.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_goniowatch"))
}

/// A session folder in a temporary directory made from a corpus session's recorded results
/// (the corpus itself is never written to).
fn session(name: &str, tmp: &Path) -> PathBuf {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/sessions")
        .join(name);
    let dir = tmp.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    for f in ["config.toml", "session.json"] {
        std::fs::copy(src.join(f), dir.join(f)).unwrap();
    }
    for e in std::fs::read_dir(src.join("expected")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dir.join(e.file_name())).unwrap();
    }
    dir
}

fn export(dir: &Path, args: &[&str]) -> Output {
    bin().arg("export").arg(dir).args(args).output().unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The MERL reader: three little-endian int32 dimensions, then 3 × n little-endian float64,
/// channel by channel; value × (1/1500, 1.15/1500, 1.66/1500) is the BRDF, negative: none.
struct Merl {
    dims: [usize; 3],
    values: Vec<f64>,
}

impl Merl {
    fn read(path: &Path) -> Merl {
        let b = std::fs::read(path).unwrap();
        let int = |k: usize| i32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap()) as usize;
        let dims = [int(0), int(1), int(2)];
        let n = dims[0] * dims[1] * dims[2];
        assert_eq!(
            b.len(),
            12 + 3 * n * 8,
            "the file holds exactly three channels of n doubles"
        );
        let values = b[12..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        Merl { dims, values }
    }

    /// The BRDF (R, G, B) a reader gets for a direction pair, by the format's nearest-cell
    /// lookup; None where the file has no value.
    fn lookup(&self, wi: [f64; 3], wo: [f64; 3]) -> Option<[f64; 3]> {
        use std::f64::consts::{FRAC_PI_2, PI};
        let norm = |v: [f64; 3]| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / n, v[1] / n, v[2] / n]
        };
        let (wi, wo) = (norm(wi), norm(wo));
        let h = norm([wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]]);
        let theta_h = h[2].clamp(-1.0, 1.0).acos();
        let phi_h = h[1].atan2(h[0]);
        // rotate wi by −φh about z, then by −θh about y
        let (s, c) = (-phi_h).sin_cos();
        let a = [c * wi[0] - s * wi[1], s * wi[0] + c * wi[1], wi[2]];
        let (s, c) = (-theta_h).sin_cos();
        let d = [c * a[0] + s * a[2], a[1], -s * a[0] + c * a[2]];
        let theta_d = d[2].clamp(-1.0, 1.0).acos();
        let mut phi_d = d[1].atan2(d[0]);
        if phi_d < 0.0 {
            phi_d += PI;
        }
        let ih = ((theta_h / FRAC_PI_2).sqrt() * 90.0) as usize;
        let id = (theta_d / FRAC_PI_2 * 90.0) as usize;
        let ip = (phi_d / PI * 180.0) as usize;
        let cell = ip.min(179) + 180 * (id.min(89) + 90 * ih.min(89));
        let n = self.dims.iter().product::<usize>();
        let scale = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];
        let v = [0, 1, 2].map(|ch| self.values[ch * n + cell]);
        if v.iter().any(|x| *x < 0.0) {
            return None;
        }
        Some([v[0] * scale[0], v[1] * scale[1], v[2] * scale[2]])
    }
}

fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

fn jsonl(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn a_merl_export_reads_back_at_the_captures_directions_and_its_sidecar_says_what_it_is() {
    let tmp = tempfile::tempdir().unwrap();
    let s = session("decay", tmp.path());
    let out = export(&s, &["--format", "table"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let file = tmp.path().join("brdf.binary");
    let sigma = tmp.path().join("brdf.sigma");
    let out = export(
        &s,
        &[
            "--format",
            "merl",
            "--out",
            file.to_str().unwrap(),
            "--sigma",
            sigma.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("cells filled") && stdout.contains("isotropy classes' rate"),
        "{stdout}"
    );
    let merl = Merl::read(&file);
    assert_eq!(merl.dims, [90, 90, 180]);
    let sig = Merl::read(&sigma);
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(format!("{}.json", file.display())).unwrap())
            .unwrap();
    // one capture's own scatter about its isotropy class (the realistic preset's nuisances)
    let scatter = side["capture_scatter"]["relative_pct"].as_f64().unwrap() / 100.0;
    assert!(scatter > 0.001 && scatter < 0.05, "{scatter}");
    // every in-grid capture of the table whose cell has a value: the file, read at the
    // capture's direction by the nearest cell, agrees with it within 3 √(σ² + (scatter·v)²)
    let rows = jsonl(&s.join("export/captures-table.jsonl"));
    let (mut n, mut close, mut empty, mut rel) = (0, 0, 0, Vec::new());
    for r in rows.iter().filter(|r| r["in_grid"].as_bool().unwrap()) {
        let f = |k: &str| r[k].as_f64().unwrap();
        let wi = dir(f("theta_i_deg"), f("phi_i_deg"));
        let wo = dir(f("theta_o_deg"), f("phi_o_deg"));
        let Some(v) = merl.lookup(wi, wo) else {
            empty += 1;
            continue;
        };
        let sg = sig.lookup(wi, wo).unwrap();
        n += 1;
        let want = [f("brdf_r"), f("brdf_g"), f("brdf_b")];
        let z = (0..3)
            .map(|c| (v[c] - want[c]).abs() / (sg[c].powi(2) + (scatter * v[c]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        if z <= 3.0 {
            close += 1;
        }
        rel.push(
            (0..3)
                .map(|c| (v[c] / want[c] - 1.0).abs())
                .fold(0.0, f64::max),
        );
    }
    // 1,500 captures: the lights of θi 0°, 15° and part of 30°, so only those layers have cells
    assert!(n > 500, "{n} captures looked up, {empty} in empty cells");
    assert!(close as f64 >= 0.85 * n as f64, "{close} of {n} within 3σ");
    rel.sort_by(|a, b| a.total_cmp(b));
    assert!(rel[rel.len() / 2] < 0.03, "median {}", rel[rel.len() / 2]);
    // the sidecar
    assert_eq!(side["format"], "merl");
    assert_eq!(side["channel_scale"][0].as_f64().unwrap(), 1.0 / 1500.0);
    assert_eq!(side["no_value"].as_f64().unwrap(), -1.0);
    assert_eq!(side["correction"]["gain_source"], "isotropy-classes");
    assert!((side["correction"]["rate_pct_per_h"].as_f64().unwrap() + 1.03).abs() < 0.01);
    assert_eq!(side["white"]["kind"], "d65");
    assert_eq!(side["white"]["reflectance"].as_f64().unwrap(), 1.0);
    let cells = &side["cells"];
    let total: u64 = [
        "filled",
        "below_horizon",
        "beyond_theta_range",
        "outside_interpolant",
        "not_finite",
    ]
    .iter()
    .map(|k| cells[k].as_u64().unwrap())
    .sum();
    assert_eq!(total, 90 * 90 * 180);
    assert!(side["verdict"]["table2"]["pairs"].as_u64().unwrap() > 0);
    assert!(side["verdict"]["isotropy_warning"].is_null());
    assert_eq!(side["coverage"].as_array().unwrap().len(), 90);
    // the report's copy, and the report's BRDF section drawn from it
    assert!(s.join("merl-export.json").exists());
    let out = bin().arg("report").arg(&s).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let html = std::fs::read_to_string(s.join("report/report.html")).unwrap();
    let brdf = &html[html.find("<h2>BRDF</h2>").expect("a BRDF section")..];
    let brdf = &brdf[..brdf.find("<h2>Capture quality").unwrap()];
    assert!(
        brdf.contains("θi = 0°") && brdf.contains("θi = 15°"),
        "one curve per θi layer"
    );
    // corrected (solid) and as measured (dashed) for each layer
    assert_eq!(
        brdf.matches("<polyline").count(),
        2 * brdf.matches("θi = ").count()
    );
    assert!(brdf.matches("stroke-dasharray").count() >= 2);
    assert!(brdf.contains("The MERL export's coverage") && brdf.contains("brdf.binary"));
    // a second export is byte-identical (threads do not change it)
    let again = tmp.path().join("again.binary");
    let out = export(
        &s,
        &[
            "--format",
            "merl",
            "--out",
            again.to_str().unwrap(),
            "--threads",
            "1",
        ],
    );
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(
        std::fs::read(&file).unwrap(),
        std::fs::read(&again).unwrap()
    );
}

#[test]
fn the_table_divides_the_sessions_drift_out_and_names_its_columns() {
    let tmp = tempfile::tempdir().unwrap();
    let s = session("decay", tmp.path());
    let csv_path = tmp.path().join("t.csv");
    let out = export(
        &s,
        &["--format", "table", "--out", csv_path.to_str().unwrap()],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(
        header.starts_with("idx,file,entry,light,camera,probe,t_s,status,theta_i_deg"),
        "{header}"
    );
    let rows = jsonl(&tmp.path().join("t.jsonl"));
    assert_eq!(rows.len(), csv.lines().count() - 1);
    let keys: Vec<&str> = rows[0]
        .as_object()
        .unwrap()
        .keys()
        .map(|k| k.as_str())
        .collect();
    let mut cols: Vec<&str> = header.split(',').collect();
    cols.sort();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(sorted, cols, "the JSON lines carry the CSV's columns");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("summary.json")).unwrap()).unwrap();
    let rate = summary["isotropy_drift"]["rate_pct_per_h"]
        .as_f64()
        .unwrap();
    for r in &rows {
        let t = r["t_s"].as_f64().unwrap() / 3600.0;
        let g = r["gain"].as_f64().unwrap();
        assert!((g - (rate / 100.0 * t).exp()).abs() < 1e-9, "{r}");
        if let (Some(raw), Some(cor)) = (r["raw_y"].as_f64(), r["corrected_y"].as_f64()) {
            assert!((cor - raw / g).abs() < 1e-9 * raw.abs().max(1.0));
        }
    }
    // without correction every factor is 1
    let out = export(
        &s,
        &[
            "--format",
            "table",
            "--out",
            csv_path.to_str().unwrap(),
            "--no-drift-correction",
        ],
    );
    assert_eq!(out.status.code(), Some(0));
    for r in jsonl(&tmp.path().join("t.jsonl")) {
        assert_eq!(r["gain"].as_f64().unwrap(), 1.0);
    }
}

#[test]
fn an_anisotropic_sample_is_refused_a_merl_file_and_an_isotropy_alarm_warns() {
    let tmp = tempfile::tempdir().unwrap();
    let s = session("joint3-sentinel", tmp.path());
    let out = export(&s, &["--format", "merl"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("anisotropic"),
        "{}",
        text(&out.stderr)
    );
    assert!(!s.join("export/brdf.binary").exists());
    // its table is fine
    let out = export(&s, &["--format", "table"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));

    let s = session("off-centre", tmp.path());
    let out = export(&s, &["--format", "merl"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(
        err.contains("warning") && err.contains("sample-off-centre"),
        "{err}"
    );
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("export/brdf.binary.json")).unwrap())
            .unwrap();
    assert!(side["verdict"]["isotropy_warning"]
        .as_str()
        .unwrap()
        .contains("sample-off-centre"));
}

#[test]
fn bad_calls_and_empty_sessions_get_their_exit_status_and_nothing_is_written_under_the_captures() {
    let tmp = tempfile::tempdir().unwrap();
    let s = session("clean", tmp.path());
    // not a session
    let out = export(tmp.path(), &["--format", "table"]);
    assert_ne!(out.status.code(), Some(0));
    assert!(
        text(&out.stderr).contains("cannot export"),
        "{}",
        text(&out.stderr)
    );
    // options that belong to another format, and images without a folder
    for args in [
        vec!["--format", "table", "--sigma", "x"],
        vec!["--format", "table", "--fit-nodes", "20"],
        vec!["--format", "merl", "--capture-root", "x"],
        vec!["--format", "corrected-images"],
        vec!["--format", "mat"],
        vec!["--format", "merl", "--fit-nodes", "41"],
    ] {
        let out = export(&s, &args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
    // an output under the capture root
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("session.json")).unwrap()).unwrap();
    let root = PathBuf::from(info["capture_root"].as_str().unwrap());
    let inside = root.join("brdf.binary");
    let out = export(&s, &["--format", "merl", "--out", inside.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("capture folder"));
    assert!(!inside.exists());
    let out = export(
        &s,
        &[
            "--format",
            "corrected-images",
            "--out",
            root.join("c").to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    // every capture dark: nothing to export, exit 6
    let caps = std::fs::read_to_string(s.join("captures.jsonl")).unwrap();
    let dark: Vec<String> = caps
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            if v["xyz"].is_array() {
                v["xyz"] = serde_json::json!([0.01, 0.01, 0.01]);
                v["mean_rgb"] = serde_json::json!([0.0001, 0.0001, 0.0001]);
            }
            v.to_string()
        })
        .collect();
    std::fs::write(s.join("captures.jsonl"), dark.join("\n") + "\n").unwrap();
    let out = export(&s, &["--format", "merl"]);
    assert_ne!(out.status.code(), Some(0));
    assert!(
        text(&out.stderr).contains("no usable capture"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn corrected_images_list_a_truncated_capture_with_its_error_and_write_the_others() {
    let tmp = tempfile::tempdir().unwrap();
    let s = session("clean", tmp.path());
    // the captures, copied: one cut short, one deleted
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/sessions/clean/captures");
    let root = tmp.path().join("captures");
    std::fs::create_dir_all(root.join("clean")).unwrap();
    for e in std::fs::read_dir(src.join("clean")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), root.join("clean").join(e.file_name())).unwrap();
    }
    let cut = root.join("clean/cap_00010_e0010.hdr");
    let bytes = std::fs::read(&cut).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    std::fs::remove_file(root.join("clean/cap_00020_e0020.hdr")).unwrap();
    let out_dir = tmp.path().join("corrected");
    let out = export(
        &s,
        &[
            "--format",
            "corrected-images",
            "--out",
            out_dir.to_str().unwrap(),
            "--capture-root",
            root.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let listed = jsonl(&out_dir.join("corrected-images.jsonl"));
    assert_eq!(listed.len(), 240);
    let failed: Vec<&str> = listed
        .iter()
        .filter(|r| r.get("error").is_some())
        .map(|r| r["source"].as_str().unwrap())
        .collect();
    assert_eq!(
        failed,
        ["clean/cap_00010_e0010.hdr", "clean/cap_00020_e0020.hdr"]
    );
    assert!(out_dir.join("clean/cap_00011_e0011.exr").exists());
    assert!(!out_dir.join("clean/cap_00010_e0010.exr").exists());
    assert!(
        text(&out.stdout).contains("238 written, 2 failed"),
        "{}",
        text(&out.stdout)
    );
}
