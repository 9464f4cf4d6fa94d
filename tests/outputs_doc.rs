//! docs/outputs.md against the files goniowatch writes.
//!
//! What is read: the recorded regression sessions (`tests/sessions/<name>/`: `config.toml`,
//! `session.json`, `journal.jsonl`, and the result files of the live run in `expected/`), and
//! files made here from them: a `check` session of a capture folder built from the `clean`
//! session's captures with a few files that cannot be placed (a files source's journal inputs,
//! `files_skipped`, a storm's aggregated alarm, `lock`), `compare` on copies of the `decay` and
//! `probe-step` sessions' results against a reference written here (`crossval.json`, with a gain
//! rate and with the probes' gain curve), `report` of the first (every CSV, `sweeps.csv` and
//! `table3.csv` included, and `report.html`), `replay --out` of the `clean` session, and `export`
//! of the check session in every format (the MERL file and its sidecar, the table, the corrected
//! images' list).
//!
//! The conventions of docs/outputs.md this test reads:
//!
//! - A file is documented by a heading that names it in backticks (`` ### `captures.jsonl` ``);
//!   its section runs to the next heading. Every file found must have one, and every file with a
//!   heading must be among the files found.
//! - A field is a table row of that section whose first cell is its path in backticks: dots for
//!   nested objects, `[]` for array elements, `<name>` for one key that is data (a map), and a
//!   trailing `.*` for every path below it (`evidence.*`: the alarm catalogue, docs/alarms.md,
//!   names those fields per code).
//! - The last column of a JSON file's table is *present*. A field whose cell starts with `when`
//!   is conditional: it need not occur in the files read here. Any other field is `always`: it
//!   must occur in every object of its parent path, and at all unless that parent never occurs
//!   and may be absent (its own row is conditional, says `null` or is an array). A field that is
//!   ever `null` must say `null` in that cell.
//! - JSON and JSON Lines files (every line) are walked for every key path; a CSV file's header
//!   must list exactly the documented columns, in the documented order; other files (`config.toml`,
//!   `report.html`, `lock`) are checked by name only.
//!
//! So: (a) every file found is documented, (b) every key path found is documented in its file's
//! section, (c) every documented field of a file found occurs, unless conditional, and
//! (d) "always" and "null" in the doc hold for every record read.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_goniowatch"))
}

// ------------------------------------------------------------------------------------------
// the doc
// ------------------------------------------------------------------------------------------

/// One documented field (a row of a file's table).
#[derive(Debug, Clone)]
struct Field {
    path: String,
    /// The *present* cell starts with "when".
    conditional: bool,
    /// The *present* cell says "null".
    nullable: bool,
    /// The second cell (the type).
    kind: String,
    line: usize,
}

#[derive(Debug, Default)]
struct Section {
    fields: Vec<Field>,
    /// The table has a *present* column (JSON files).
    has_present: bool,
}

/// Whether a backticked token of a heading names a file.
fn is_file_name(token: &str) -> bool {
    token == "lock"
        || (!token.contains([' ', '/', '*'])
            && [".jsonl", ".json", ".toml", ".csv", ".html", ".binary"]
                .iter()
                .any(|e| token.ends_with(e)))
}

fn backticked(s: &str) -> Vec<&str> {
    s.split('`').skip(1).step_by(2).collect()
}

/// The cells of a table row; `\|` is a pipe inside a cell.
fn cells(row: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = row.trim().trim_start_matches('|').chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                cur.push('|');
                chars.next();
            }
            '|' => out.push(std::mem::take(&mut cur).trim().to_string()),
            _ => cur.push(c),
        }
    }
    if !cur.trim().is_empty() {
        out.push(cur.trim().to_string());
    }
    out
}

fn parse_doc(text: &str) -> Result<BTreeMap<String, Section>, String> {
    let mut doc: BTreeMap<String, Section> = BTreeMap::new();
    let mut current: Vec<String> = Vec::new();
    let mut present_column = false;
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        if line.starts_with('#') {
            current = backticked(line)
                .into_iter()
                .filter(|t| is_file_name(t))
                .map(str::to_string)
                .collect();
            for f in &current {
                if doc.insert(f.clone(), Section::default()).is_some() {
                    return Err(format!("line {line_no}: {f} has a second heading"));
                }
            }
            continue;
        }
        if current.is_empty() || !line.starts_with('|') {
            continue;
        }
        let c = cells(line);
        let Some(first) = c.first() else { continue };
        if !first.starts_with('`') {
            // a header row (or the separator): does this table say when a field is present?
            if !first.starts_with('-') {
                present_column = c.last().is_some_and(|l| l == "present");
            }
            continue;
        }
        let path = first.trim_matches('`').to_string();
        let last = c.last().cloned().unwrap_or_default();
        let field = Field {
            conditional: present_column && last.starts_with("when"),
            nullable: present_column && last.contains("null"),
            kind: c.get(1).cloned().unwrap_or_default(),
            path,
            line: line_no,
        };
        for f in &current {
            let s = doc.get_mut(f).unwrap();
            s.has_present |= present_column;
            s.fields.push(field.clone());
        }
    }
    Ok(doc)
}

/// Whether the documented path `pattern` stands for the key path `path`.
fn matches(pattern: &str, path: &str) -> bool {
    if let Some(prefix) = pattern.strip_suffix(".*") {
        return path
            .strip_prefix(prefix)
            .is_some_and(|rest| rest.starts_with('.'));
    }
    let (p, k): (Vec<&str>, Vec<&str>) = (pattern.split('.').collect(), path.split('.').collect());
    p.len() == k.len()
        && p.iter().zip(&k).all(|(p, k)| {
            p == k
                || (p.starts_with('<') && {
                    // `<name>` or `<name>[]…`: any key, with the same array suffix
                    let suffix = &p[p.find('>').map_or(p.len(), |i| i + 1)..];
                    k.ends_with(suffix) && k.len() > suffix.len()
                })
        })
}

fn is_exact(pattern: &str) -> bool {
    !pattern.ends_with(".*") && !pattern.contains('<')
}

// ------------------------------------------------------------------------------------------
// the files
// ------------------------------------------------------------------------------------------

/// What the records of one file hold.
#[derive(Debug, Default)]
struct Seen {
    /// Key path → occurrences.
    keys: BTreeMap<String, u64>,
    /// Path → objects found at it ("" for the records themselves).
    objects: BTreeMap<String, u64>,
    /// Key paths that were `null` somewhere.
    nulls: BTreeSet<String>,
    /// CSV: the header of each file read, with where.
    headers: Vec<(Vec<String>, PathBuf)>,
    /// Where each file name was found (for messages).
    found_in: Vec<PathBuf>,
    /// An example file for each key path.
    example: BTreeMap<String, PathBuf>,
}

fn join(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

fn walk(v: &serde_json::Value, at: &str, seen: &mut Seen, file: &Path) {
    use serde_json::Value;
    match v {
        Value::Object(m) => {
            *seen.objects.entry(at.to_string()).or_default() += 1;
            for (k, x) in m {
                let p = join(at, k);
                *seen.keys.entry(p.clone()).or_default() += 1;
                if x.is_null() {
                    seen.nulls.insert(p.clone());
                }
                seen.example
                    .entry(p.clone())
                    .or_insert_with(|| file.to_path_buf());
                walk(x, &p, seen, file);
            }
        }
        Value::Array(a) => {
            let p = format!("{at}[]");
            for x in a {
                walk(x, &p, seen, file);
            }
        }
        _ => {}
    }
}

fn read_file(path: &Path, all: &mut BTreeMap<String, Seen>) {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let seen = all.entry(name.clone()).or_default();
    seen.found_in.push(path.to_path_buf());
    let text =
        || std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    if name.ends_with(".jsonl") {
        for (n, line) in text().lines().enumerate() {
            let v: serde_json::Value = serde_json::from_str(line)
                .unwrap_or_else(|e| panic!("{} line {}: {e}", path.display(), n + 1));
            walk(&v, "", seen, path);
        }
    } else if name.ends_with(".json") {
        let v: serde_json::Value =
            serde_json::from_str(&text()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        walk(&v, "", seen, path);
    } else if name.ends_with(".csv") {
        let header = text().lines().next().unwrap_or_default().to_string();
        seen.headers.push((
            header.split(',').map(str::to_string).collect(),
            path.to_path_buf(),
        ));
    }
}

/// Every file of a folder (not below it).
fn read_folder(dir: &Path, all: &mut BTreeMap<String, Seen>) {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{} is empty", dir.display());
    for f in files {
        read_file(&f, all);
    }
}

fn corpus() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(repo().join("tests/sessions"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("journal.jsonl").exists())
        .collect();
    dirs.sort();
    assert!(dirs.len() >= 10, "the corpus is missing sessions: {dirs:?}");
    dirs
}

/// A scratch folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let p = std::env::temp_dir().join(format!("gw-outputs-doc-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        Scratch(p)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn run(cmd: &mut Command, what: &str, ok: &[i32]) {
    let out = cmd.output().unwrap_or_else(|e| panic!("{what}: {e}"));
    let code = out.status.code().unwrap_or(-1);
    assert!(
        ok.contains(&code),
        "{what} exited {code}:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A corpus session's recorded results as a session folder of their own.
fn session_copy(name: &str, into: &Path) {
    let src = repo().join("tests/sessions").join(name);
    for f in ["config.toml", "session.json"] {
        std::fs::copy(src.join(f), into.join(f)).unwrap();
    }
    for e in std::fs::read_dir(src.join("expected")).unwrap().flatten() {
        std::fs::copy(e.path(), into.join(e.file_name())).unwrap();
    }
}

/// A reference measurement (docs/reference-format.md, RGB) on an Integra-like grid, with a
/// colour that changes with the directions so that the transform is determined.
fn write_reference(path: &Path) {
    let mut s = String::from(
        "# goniowatch reference BRDF, version 1\nname = outputs_doc test reference\nformat = rgb\n",
    );
    for ti in [0.0f64, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0, 85.0] {
        for pi in [0.0f64, 90.0, 180.0, 270.0] {
            for to in (0..=17).map(|k| k as f64 * 5.0) {
                let phis: Vec<f64> = if to == 0.0 {
                    vec![0.0]
                } else {
                    (0..24).map(|k| k as f64 * 15.0).collect()
                };
                for po in phis {
                    let (a, b) = (to.to_radians(), (po - pi).to_radians());
                    let r = 0.30 + 0.10 * a.cos() + 0.04 * b.cos();
                    let g = 0.28 + 0.06 * (2.0 * a).sin() + 0.02 * ti.to_radians().cos();
                    let bl = 0.22 + 0.08 * a.sin() * a.sin() - 0.03 * b.cos();
                    s.push_str(&format!("{ti} {pi} {to} {po} {r:.5} {g:.5} {bl:.5}\n"));
                }
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

/// `check` of a folder built from the clean session's captures, placed by a sidecar whose times
/// step back an hour at capture 100, with eight dark frames, a second file of one plan entry, a
/// file whose entry is off the plan and a file of another type.
fn make_check_session(scratch: &Path) -> PathBuf {
    let caps = scratch.join("captures");
    std::fs::create_dir_all(caps.join("rejected")).unwrap();
    let src = repo().join("tests/sessions/clean/captures/clean");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&src)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    names.sort();
    let mut sidecar = String::from("file,entry,idx,t\n");
    for (k, p) in names.iter().enumerate() {
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        std::fs::copy(p, caps.join(&name)).unwrap();
        let t = 7 * k as i64 - if k >= 100 { 3600 } else { 0 };
        sidecar.push_str(&format!("{name},{k},{k},{t}\n"));
    }
    // eight dark frames: more than 5 of one alarm code, so a storm's aggregated alarm
    let mut dark = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16 +X 16\n".to_vec();
    dark.resize(dark.len() + 16 * 16 * 4, 0);
    for p in &names[150..158] {
        std::fs::write(caps.join(p.file_name().unwrap()), &dark).unwrap();
    }
    std::fs::copy(&names[3], caps.join("rejected/cap_00003_e0003.hdr")).unwrap();
    sidecar.push_str("rejected/cap_00003_e0003.hdr,3,3,21\n");
    std::fs::copy(&names[4], caps.join("cap_00900_e9999.hdr")).unwrap();
    sidecar.push_str("cap_00900_e9999.hdr,9999,900,6300\n");
    std::fs::write(caps.join("sidecar.csv"), sidecar).unwrap();
    std::fs::write(caps.join("readme.txt"), "notes\n").unwrap();
    let mut config =
        std::fs::read_to_string(repo().join("tests/sessions/clean/config.toml")).unwrap();
    config.push_str("\n[source]\nkind = \"files\"\nsidecar = \"sidecar.csv\"\n");
    let cfg = scratch.join("check.toml");
    std::fs::write(&cfg, config).unwrap();
    let session = scratch.join("session");
    run(
        bin()
            .arg("check")
            .arg(&caps)
            .arg("--config")
            .arg(&cfg)
            .arg("--session")
            .arg(&session)
            .args(["--workers", "2"])
            .env("GONIOWATCH_LOG", "error"),
        "check",
        &[0],
    );
    for format in ["merl", "table"] {
        run(
            bin().arg("export").arg(&session).args(["--format", format]),
            "export",
            &[0],
        );
    }
    run(
        bin()
            .arg("export")
            .arg(&session)
            .args(["--format", "corrected-images", "--out"])
            .arg(scratch.join("corrected")),
        "export",
        &[0],
    );
    session
}

/// `compare` of copies of the decay session's results (a gain rate from isotropy classes) and
/// of the probe-step session's (the probes' gain curve), and `report` of the first: the folders
/// to read.
fn make_compare_and_report(scratch: &Path) -> Vec<PathBuf> {
    let reference = scratch.join("test.ref");
    write_reference(&reference);
    let mut dirs = Vec::new();
    for name in ["decay", "probe-step"] {
        let session = scratch.join(name);
        std::fs::create_dir_all(&session).unwrap();
        session_copy(name, &session);
        run(
            bin().arg("compare").arg(&session).arg(&reference),
            "compare",
            &[0],
        );
        dirs.push(session);
    }
    let report = scratch.join("report");
    run(
        bin().arg("report").arg(&dirs[0]).arg("--out").arg(&report),
        "report",
        &[0],
    );
    dirs.push(report);
    dirs
}

fn make_replay(scratch: &Path) -> PathBuf {
    use goniowatch::daemon::replay::{replay, ReplayOptions};
    let out = scratch.join("replay");
    replay(
        &repo().join("tests/sessions/clean"),
        &ReplayOptions {
            out: Some(out.clone()),
            workers: 1,
            recorded_outcomes: true,
            ..ReplayOptions::default()
        },
    )
    .unwrap_or_else(|e| panic!("replay: {e:#}"));
    out
}

/// Every output this test reads, by file name.
fn outputs() -> BTreeMap<String, Seen> {
    let mut all = BTreeMap::new();
    for dir in corpus() {
        for f in ["config.toml", "session.json", "journal.jsonl"] {
            read_file(&dir.join(f), &mut all);
        }
        read_folder(&dir.join("expected"), &mut all);
    }
    let (check, compare, replay) = (
        Scratch::new("check"),
        Scratch::new("compare"),
        Scratch::new("replay"),
    );
    let (check_session, compared, replayed) = std::thread::scope(|s| {
        let a = s.spawn(|| make_check_session(&check.0));
        let b = s.spawn(|| make_compare_and_report(&compare.0));
        let c = s.spawn(|| make_replay(&replay.0));
        (a.join().unwrap(), b.join().unwrap(), c.join().unwrap())
    });
    read_folder(&check_session, &mut all);
    read_folder(&check_session.join("export"), &mut all);
    read_file(&check.0.join("corrected/corrected-images.jsonl"), &mut all);
    for dir in &compared {
        read_folder(dir, &mut all);
    }
    read_folder(&replayed, &mut all);
    all
}

// ------------------------------------------------------------------------------------------
// the checks
// ------------------------------------------------------------------------------------------

/// Whether the object at `parent` (a field's parent path) may be absent from a file, so that its
/// fields need not occur: its own row is conditional, may be null or is an array (which may be
/// empty), or its parent may be absent.
fn may_be_absent(section: &Section, parent: &str) -> bool {
    let own = parent.trim_end_matches("[]");
    if own.is_empty() {
        return false;
    }
    let Some(row) = section.fields.iter().find(|f| f.path == own) else {
        return false;
    };
    row.conditional
        || row.nullable
        || row.kind.starts_with("array")
        || may_be_absent(section, own.rsplit_once('.').map_or("", |(p, _)| p))
}

fn check_doc(doc: &BTreeMap<String, Section>, all: &BTreeMap<String, Seen>) -> Vec<String> {
    let mut problems = Vec::new();
    // (a) every file found is documented, and every documented file was found
    for (name, seen) in all {
        if !doc.contains_key(name) {
            problems.push(format!(
                "{name} (e.g. {}) has no heading in docs/outputs.md",
                seen.found_in[0].display()
            ));
        }
    }
    for name in doc.keys() {
        if !all.contains_key(name) {
            problems.push(format!(
                "docs/outputs.md documents {name}, which no output read here holds: make one in tests/outputs_doc.rs"
            ));
        }
    }
    for (name, seen) in all {
        let Some(section) = doc.get(name) else {
            continue;
        };
        if name.ends_with(".csv") {
            let documented: Vec<&str> = section.fields.iter().map(|f| f.path.as_str()).collect();
            for (header, file) in &seen.headers {
                if header
                    .iter()
                    .map(String::as_str)
                    .ne(documented.iter().copied())
                {
                    problems.push(format!(
                        "{}: the header is\n    {}\n  docs/outputs.md documents the columns\n    {}",
                        file.display(),
                        header.join(","),
                        documented.join(",")
                    ));
                }
            }
            continue;
        }
        if !(name.ends_with(".json") || name.ends_with(".jsonl")) {
            continue;
        }
        if !section.has_present {
            problems.push(format!(
                "docs/outputs.md: the table of {name} has no `present` column"
            ));
        }
        // (b) every key path found is documented
        for path in seen.keys.keys() {
            if !section.fields.iter().any(|f| matches(&f.path, path)) {
                problems.push(format!(
                    "{name}: `{path}` (e.g. in {}) is not documented in its section of docs/outputs.md",
                    seen.example[path].display()
                ));
            }
        }
        for f in &section.fields {
            let found: Vec<&String> = seen.keys.keys().filter(|p| matches(&f.path, p)).collect();
            if !f.conditional {
                let parent = f.path.rsplit_once('.').map_or("", |(p, _)| p);
                let objects = seen.objects.get(parent).copied().unwrap_or(0);
                let n = seen.keys.get(&f.path).copied().unwrap_or(0);
                if is_exact(&f.path) && objects > 0 && n != objects {
                    // (d) in every object of its parent
                    problems.push(format!(
                        "docs/outputs.md:{}: {name} `{}` is documented as always there, but occurs {n} times in {objects} objects of `{}`",
                        f.line,
                        f.path,
                        if parent.is_empty() { "(the records)" } else { parent }
                    ));
                } else if found.is_empty() && !(objects == 0 && may_be_absent(section, parent)) {
                    // (c) at all, unless its parent never occurs and may be absent
                    problems.push(format!(
                        "docs/outputs.md:{}: {name} `{}` never occurs in the files read; mark it conditional (`when …`) or remove it",
                        f.line, f.path
                    ));
                }
            }
            if !f.path.ends_with(".*") && !f.nullable {
                for p in found.iter().filter(|p| seen.nulls.contains(p.as_str())) {
                    problems.push(format!(
                        "docs/outputs.md:{}: {name} `{p}` is null somewhere (e.g. in {}), and the doc does not say when",
                        f.line,
                        seen.example[p.as_str()].display()
                    ));
                }
            }
        }
    }
    problems
}

#[test]
fn docs_outputs_md_documents_every_file_and_field_goniowatch_writes() {
    let text = std::fs::read_to_string(repo().join("docs/outputs.md")).unwrap();
    let doc = parse_doc(&text).unwrap_or_else(|e| panic!("docs/outputs.md: {e}"));
    let all = outputs();
    // what must be among the outputs read, whatever the doc says
    for name in [
        "config.toml",
        "session.json",
        "journal.jsonl",
        "lock",
        "manifest.jsonl",
        "captures.jsonl",
        "pairs.jsonl",
        "isotropy.jsonl",
        "sweeps.jsonl",
        "alarms.jsonl",
        "summary.json",
        "crossval.json",
        "report.html",
        "captures.csv",
        "pairs.csv",
        "alarms.csv",
        "table2.csv",
        "light_residuals.csv",
        "retakes.csv",
        "sweeps.csv",
        "table3.csv",
        "brdf.binary",
        "brdf.binary.json",
        "merl-export.json",
        "captures-table.csv",
        "captures-table.jsonl",
        "corrected-images.jsonl",
    ] {
        assert!(all.contains_key(name), "{name} was not made");
    }
    let problems = check_doc(&doc, &all);
    assert!(
        problems.is_empty(),
        "docs/outputs.md does not match the outputs ({} problem(s)):\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn the_doc_conventions_are_read_as_stated() {
    let doc = parse_doc(
        "# x\n### `a.jsonl`\n| field | type | unit | meaning | present |\n|---|---|---|---|---|\n\
         | `a` | integer | – | x \\| y | always |\n| `b.<k>` | integer | – | x | when any |\n\
         | `c` | object | – | x | always; null when not |\n| `e.*` | – | – | x | when e |\n\
         ## other\n| `z` | x |\n### `t.csv`\n| column | type |\n|---|---|\n| `idx` | integer |\n",
    )
    .unwrap();
    let a = &doc["a.jsonl"].fields;
    assert_eq!(
        a.iter()
            .map(|f| (f.path.as_str(), f.conditional, f.nullable))
            .collect::<Vec<_>>(),
        [
            ("a", false, false),
            ("b.<k>", true, false),
            ("c", false, true),
            ("e.*", true, false)
        ]
    );
    assert!(doc["a.jsonl"].has_present && !doc["t.csv"].has_present);
    assert_eq!(doc["t.csv"].fields[0].path, "idx");
    assert!(!doc.contains_key("other"));
    assert!(matches("b.<k>", "b.drift") && !matches("b.<k>", "b") && !matches("b.<k>", "b.x.y"));
    assert!(matches("in.counts.<reason>", "in.counts.not-a-capture"));
    assert!(matches("e.*", "e.x.y") && !matches("e.*", "e") && !matches("e.*", "ex.y"));
    assert!(matches("joints[].z", "joints[].z") && !matches("joints[].z", "joints.z"));
    assert!(is_file_name("lock") && is_file_name("summary.json") && !is_file_name("replay --out"));
}
