//! The alarm catalogue against the docs and against what recorded sessions raised: docs/alarms.md
//! holds exactly the generated table, and every alarm of the session corpus and of the lab's
//! regression sessions has the kind and a severity its entry names.

use goniowatch::checks::alarm::Alarm;
use goniowatch::checks::catalogue::{entry, markdown};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn docs_alarms_md_holds_the_generated_catalogue() {
    let doc = std::fs::read_to_string(repo().join("docs/alarms.md")).unwrap();
    let (start, end) = ("<!-- catalogue -->\n", "<!-- /catalogue -->");
    let a = doc
        .find(start)
        .expect("docs/alarms.md has no catalogue markers")
        + start.len();
    let b = doc.find(end).unwrap();
    assert!(
        doc[a..b] == markdown(),
        "docs/alarms.md is not the generated catalogue: run `goniowatch alarms` and paste it between the markers"
    );
}

fn alarms_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            alarms_files(&p, out);
        } else if p.file_name().is_some_and(|n| n == "alarms.jsonl") {
            out.push(p);
        }
    }
}

#[test]
fn recorded_alarms_agree_with_their_entries() {
    let mut files = Vec::new();
    alarms_files(&repo().join("tests/sessions"), &mut files);
    assert!(files.len() >= 8, "{files:?}");
    let mut seen = 0;
    for f in files {
        for line in std::fs::read_to_string(&f).unwrap().lines() {
            let a: Alarm = serde_json::from_str(line)
                .unwrap_or_else(|e| panic!("{}: {e}: {line}", f.display()));
            let e = entry(a.code);
            assert_eq!(a.kind, e.kind, "{}: {}", f.display(), a.code);
            assert!(
                e.severities.contains(&a.severity),
                "{}: {} raised as {:?}",
                f.display(),
                a.code,
                a.severity
            );
            seen += 1;
        }
    }
    assert!(seen > 10, "{seen}");
}
