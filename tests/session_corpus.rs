//! The regression corpus (gpsd's regress driver, in Rust): every recorded session under
//! `tests/sessions/<name>/` is replayed through the same engine and measuring code as the live
//! daemon, and each result file must equal the live run's, kept in `expected/`, byte for byte.
//! Sessions that kept their captures are measured again; the others replay the journaled
//! outcomes. Each folder's PROVENANCE.md says what it exercises and how it was recorded.
//!
//! After an intended change of the output: `GONIOWATCH_BLESS=1 cargo test --test session_corpus`
//! rewrites `expected/` from the replay (review the diff before committing it).

use goniowatch::daemon::replay::{replay, ReplayOptions};
use std::path::{Path, PathBuf};

const RESULT_FILES: [&str; 7] = [
    "captures.jsonl",
    "pairs.jsonl",
    "isotropy.jsonl",
    "sweeps.jsonl",
    "alarms.jsonl",
    "manifest.jsonl",
    "summary.json",
];

fn corpus() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/sessions");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.join("journal.jsonl").exists())
        .collect();
    dirs.sort();
    dirs
}

/// The first line where two files differ, for the failure message.
fn first_difference(want: &[u8], got: &[u8]) -> String {
    let (w, g) = (String::from_utf8_lossy(want), String::from_utf8_lossy(got));
    for (n, (a, b)) in w.lines().zip(g.lines()).enumerate() {
        if a != b {
            return format!("line {}:\n  expected {a}\n  replayed {b}", n + 1);
        }
    }
    format!(
        "{} lines expected, {} replayed",
        w.lines().count(),
        g.lines().count()
    )
}

#[test]
fn every_recorded_session_replays_to_its_expected_output() {
    let bless = std::env::var_os("GONIOWATCH_BLESS").is_some();
    let dirs = corpus();
    assert!(dirs.len() >= 10, "the corpus is missing sessions: {dirs:?}");
    let mut failures = Vec::new();
    for dir in &dirs {
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let out = std::env::temp_dir().join(format!("gw-corpus-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&out);
        let captures = dir.join("captures");
        let kept = captures.exists();
        let report = replay(
            dir,
            &ReplayOptions {
                out: Some(out.clone()),
                workers: 1,
                capture_root: kept.then_some(captures),
                recorded_outcomes: !kept,
                ..ReplayOptions::default()
            },
        )
        .unwrap_or_else(|e| panic!("{name}: {e:#}"));
        if !report.mismatches.is_empty() {
            failures.push(format!("{name}: captures differ: {:?}", report.mismatches));
        }
        for f in RESULT_FILES {
            let got = std::fs::read(out.join(f)).unwrap();
            let expected = dir.join("expected").join(f);
            if bless {
                std::fs::write(&expected, &got).unwrap();
                continue;
            }
            let want =
                std::fs::read(&expected).unwrap_or_else(|e| panic!("{}: {e}", expected.display()));
            if want != got {
                failures.push(format!("{name}/{f}: {}", first_difference(&want, &got)));
            }
        }
        std::fs::remove_dir_all(&out).ok();
    }
    assert!(
        failures.is_empty(),
        "{} difference(s); after an intended change re-bless with GONIOWATCH_BLESS=1:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn every_session_says_where_it_comes_from() {
    for dir in corpus() {
        let p = std::fs::read_to_string(dir.join("PROVENANCE.md"))
            .unwrap_or_else(|_| panic!("{} has no PROVENANCE.md", dir.display()));
        assert!(
            p.contains("record.py") && p.contains("faults"),
            "{}",
            dir.display()
        );
    }
}
