//! The layering of ARCHITECTURE.md, checked: a module may use only the modules below it. Each
//! `crate::<module>` path in code (comments left out) is a use.

use std::collections::BTreeSet;
use std::path::Path;

/// Each top-level module and the modules it may use.
const ALLOWED: &[(&str, &[&str])] = &[
    ("measure", &[]),
    ("reference", &["measure"]),
    ("protocol", &[]),
    ("archive", &["measure", "protocol"]),
    ("checks", &["measure"]),
    ("config", &["measure", "checks", "archive"]),
    (
        "engine",
        &["measure", "checks", "config", "protocol", "archive"],
    ),
    ("decode", &["measure"]),
    (
        "fixtures",
        &[
            "measure", "checks", "config", "protocol", "engine", "archive",
        ],
    ),
    (
        "session",
        &[
            "measure", "checks", "config", "protocol", "engine", "archive",
        ],
    ),
    (
        "daemon",
        &[
            "measure", "checks", "config", "protocol", "engine", "decode", "session", "archive",
        ],
    ),
    (
        "cli",
        &[
            "measure",
            "checks",
            "config",
            "protocol",
            "engine",
            "decode",
            "session",
            "daemon",
            "reference",
            "archive",
        ],
    ),
];

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level modules a file's code names as `crate::<module>`.
fn uses(text: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            rest = &rest[at + 7..];
            if let Some(group) = rest.strip_prefix('{') {
                // `crate::{a, b::c}`: the first segment of each entry (on this line)
                let inner = group.split('}').next().unwrap_or("");
                for entry in inner.split(',') {
                    let name = entry.trim().split("::").next().unwrap_or("");
                    if !name.is_empty() {
                        out.insert(name.to_string());
                    }
                }
                continue;
            }
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            out.insert(name);
        }
    }
    out
}

#[test]
fn no_module_uses_one_above_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut bad = Vec::new();
    for (module, allowed) in ALLOWED {
        let mut files = Vec::new();
        let dir = src.join(module);
        if dir.is_dir() {
            rust_files(&dir, &mut files);
        } else {
            files.push(src.join(format!("{module}.rs")));
        }
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for used in uses(&text) {
                // `fixtures` exists only in test builds, so a use outside a test cannot compile
                let dev_only = used == "fixtures";
                if used != *module && !dev_only && !allowed.contains(&used.as_str()) {
                    bad.push(format!("{} uses crate::{used}", f.display()));
                }
            }
        }
    }
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
}

#[test]
fn every_top_level_module_has_a_place_in_the_layering() {
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    for line in lib.lines() {
        if let Some(m) = line.strip_prefix("pub mod ") {
            let m = m.trim_end_matches(';');
            assert!(
                ALLOWED.iter().any(|(n, _)| *n == m),
                "{m} is not in the layering"
            );
        }
    }
}
