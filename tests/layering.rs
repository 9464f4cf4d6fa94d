//! The layering of ARCHITECTURE.md, checked: a module may use only the modules its row of the
//! rule table names. A use is any path into another top-level module: `crate::m`, each entry of
//! a `crate::{…}` group (over any number of lines, nested), and `super::…` chains that climb to
//! the crate's root. Comments and string literals are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The rule table between the `<!-- layering -->` markers of ARCHITECTURE.md: module → the
/// modules it may use.
fn rules(architecture: &str) -> BTreeMap<String, BTreeSet<String>> {
    let start = architecture
        .find("<!-- layering -->")
        .expect("ARCHITECTURE.md has no <!-- layering --> table");
    let end = architecture[start..]
        .find("<!-- /layering -->")
        .expect("the layering table is not closed")
        + start;
    let mut out = BTreeMap::new();
    for row in architecture[start..end].lines() {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        if cells.len() < 3 || !cells[1].starts_with('`') {
            continue;
        }
        let module = cells[1].trim_matches('`').to_string();
        let may: BTreeSet<String> = cells[2]
            .split(',')
            .map(|m| m.trim().to_string())
            .filter(|m| !m.is_empty() && m != "–" && m != "-")
            .collect();
        out.insert(module, may);
    }
    out
}

/// The text with comments and string literals blanked (their line breaks kept).
fn code_only(text: &str) -> String {
    let b: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        match (b[i], b.get(i + 1).copied()) {
            ('/', Some('/')) => {
                while i < b.len() && b[i] != '\n' {
                    i += 1;
                }
            }
            ('/', Some('*')) => {
                let mut depth = 0;
                while i < b.len() {
                    if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                        depth += 1;
                        i += 2;
                    } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                        depth -= 1;
                        i += 2;
                        if depth == 0 {
                            break;
                        }
                    } else {
                        if b[i] == '\n' {
                            out.push('\n');
                        }
                        i += 1;
                    }
                }
            }
            // a raw string r#"…"#: to the quote followed by as many #
            ('r', Some('#' | '"'))
                if i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == '_') =>
            {
                let hashes = b[i + 1..].iter().take_while(|&&c| c == '#').count();
                if b.get(i + 1 + hashes) != Some(&'"') {
                    out.push('r');
                    i += 1;
                    continue;
                }
                let mut k = i + 2 + hashes;
                while k < b.len() {
                    if b[k] == '"'
                        && b[k + 1..]
                            .iter()
                            .take(hashes)
                            .filter(|&&c| c == '#')
                            .count()
                            == hashes
                    {
                        break;
                    }
                    if b[k] == '\n' {
                        out.push('\n');
                    }
                    k += 1;
                }
                out.push_str("\"\"");
                i = k + 1 + hashes;
            }
            ('"', _) => {
                i += 1;
                while i < b.len() && b[i] != '"' {
                    if b[i] == '\\' {
                        i += 1;
                    } else if b[i] == '\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
                out.push_str("\"\"");
                i += 1;
            }
            // a char literal ('"', '{'): blanked; a lifetime ('a) is left alone
            ('\'', _) if b.get(i + 2) == Some(&'\'') || b.get(i + 1) == Some(&'\\') => {
                let close = (i + 1..b.len().min(i + 12)).find(|&k| b[k] == '\'' && k > i + 1);
                out.push_str("' '");
                i = close.map_or(i + 1, |k| k + 1);
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    out
}

fn ident_at(s: &str) -> String {
    s.trim_start()
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect()
}

/// The entries of the `{…}` group whose text starts at `s` (after its `{`): each entry's first
/// segment.
fn group_heads(s: &str) -> Vec<String> {
    let (mut depth, mut entry, mut heads) = (1usize, String::new(), Vec::new());
    for c in s.chars() {
        match c {
            '{' => {
                depth += 1;
                entry.push(c);
            }
            '}' => {
                depth -= 1;
                if depth == 0 {
                    heads.push(ident_at(&entry));
                    return heads;
                }
                entry.push(c);
            }
            ',' if depth == 1 => heads.push(ident_at(&std::mem::take(&mut entry))),
            _ => entry.push(c),
        }
    }
    heads
}

/// The top-level modules that the code of the file at module path `module` (`["engine",
/// "alarms"]` for src/engine/alarms.rs) names.
fn uses(text: &str, module: &[String]) -> BTreeSet<String> {
    let code = code_only(text);
    let mut out = BTreeSet::new();
    let bytes = code.as_bytes();
    let word_start =
        |at: usize| at == 0 || !(bytes[at - 1].is_ascii_alphanumeric() || bytes[at - 1] == b'_');
    // crate::m and crate::{a, b::c}
    let mut from = 0;
    while let Some(at) = code[from..].find("crate::").map(|k| k + from) {
        from = at + 7;
        if !word_start(at) {
            continue;
        }
        let rest = &code[from..];
        match rest.trim_start().strip_prefix('{') {
            Some(group) => out.extend(group_heads(group)),
            None => {
                out.insert(ident_at(rest));
            }
        }
    }
    // super::super::m, super::{m, …}: the chains that climb out of the top-level module
    let mut from = 0;
    while let Some(at) = code[from..].find("super::").map(|k| k + from) {
        if !word_start(at) {
            from = at + 7;
            continue;
        }
        let mut k = at;
        let mut ups = 0;
        while code[k..].starts_with("super::") {
            ups += 1;
            k += 7;
        }
        from = k;
        if ups < module.len() {
            continue; // still inside the file's own top-level module
        }
        let rest = &code[k..];
        match rest.trim_start().strip_prefix('{') {
            Some(group) => out.extend(group_heads(group)),
            None => {
                out.insert(ident_at(rest));
            }
        }
    }
    out.retain(|m| !m.is_empty() && m != "self" && m != "super" && Some(m) != module.first());
    out
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// `src/engine/alarms.rs` → ["engine", "alarms"]; `src/engine/mod.rs` → ["engine"].
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut v: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if v.last().is_some_and(|l| l == "mod") {
        v.pop();
    }
    v
}

/// Every use against the rules: "file uses m".
fn violations(
    rules: &BTreeMap<String, BTreeSet<String>>,
    files: &[(Vec<String>, String, String)],
) -> Vec<String> {
    let mut bad = Vec::new();
    for (module, name, text) in files {
        let Some(top) = module.first() else { continue };
        let Some(may) = rules.get(top) else {
            bad.push(format!(
                "{name}: module {top} has no row in the layering table"
            ));
            continue;
        };
        for used in uses(text, module) {
            // `fixtures` exists only in test builds: a use outside a test cannot compile
            if used != "fixtures" && !may.contains(&used) {
                bad.push(format!("{name} uses crate::{used}"));
            }
        }
    }
    bad
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn no_module_uses_one_its_rule_does_not_name() {
    let rules = rules(&std::fs::read_to_string(repo().join("ARCHITECTURE.md")).unwrap());
    let src = repo().join("src");
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    let files: Vec<(Vec<String>, String, String)> = paths
        .iter()
        .map(|p| {
            (
                module_path(&src, p),
                p.display().to_string(),
                std::fs::read_to_string(p).unwrap(),
            )
        })
        .filter(|(m, _, _)| !matches!(m.first().map(String::as_str), Some("lib" | "main")))
        .collect();
    assert!(files.len() > 50, "{} files", files.len());
    let bad = violations(&rules, &files);
    assert!(bad.is_empty(), "layering broken:\n{}", bad.join("\n"));
}

#[test]
fn every_top_level_module_has_a_row_and_every_row_a_module() {
    let rules = rules(&std::fs::read_to_string(repo().join("ARCHITECTURE.md")).unwrap());
    let lib = std::fs::read_to_string(repo().join("src/lib.rs")).unwrap();
    let modules: BTreeSet<String> = lib
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            l.strip_prefix("pub mod ")
                .or_else(|| l.strip_prefix("pub(crate) mod "))
        })
        .map(|m| m.trim_end_matches(';').to_string())
        .collect();
    let rows: BTreeSet<String> = rules.keys().cloned().collect();
    assert_eq!(rows, modules);
    for may in rules.values() {
        assert!(may.is_subset(&modules), "{may:?}");
    }
}

#[test]
fn the_rules_point_one_way() {
    // no circle: a module's row never reaches back to it
    let rules = rules(&std::fs::read_to_string(repo().join("ARCHITECTURE.md")).unwrap());
    for start in rules.keys() {
        let mut seen = BTreeSet::new();
        let mut todo: Vec<&String> = rules[start].iter().collect();
        while let Some(m) = todo.pop() {
            assert_ne!(m, start, "{start} can reach itself");
            if seen.insert(m.clone()) {
                todo.extend(rules.get(m).into_iter().flatten());
            }
        }
    }
}

#[test]
fn the_check_finds_each_form_of_a_use_that_breaks_the_rules() {
    let rules = rules(
        "<!-- layering -->\n| module | may use |\n|---|---|\n| `measure` | – |\n| `checks` | measure |\n| `daemon` | checks, measure |\n<!-- /layering -->",
    );
    let file = |path: &[&str], text: &str| {
        (
            path.iter().map(|s| s.to_string()).collect::<Vec<_>>(),
            path.join("/"),
            text.to_string(),
        )
    };
    let cases = [
        // a plain path, in code and in an expression
        (file(&["checks"], "use crate::daemon::run;"), true),
        (
            file(&["checks", "a"], "fn f() { crate::daemon::go() }"),
            true,
        ),
        // a group over several lines, nested
        (
            file(
                &["checks"],
                "use crate::{\n    measure::{x, y},\n    daemon::run,\n};",
            ),
            true,
        ),
        // super chains climbing out of the module
        (
            file(
                &["checks", "deep", "file"],
                "use super::super::super::daemon::x;",
            ),
            true,
        ),
        (
            file(&["checks", "file"], "use super::super::{measure, daemon};"),
            true,
        ),
        // allowed, or inside the module, or only in a comment or a string
        (
            file(
                &["checks", "file"],
                "use super::other; use crate::measure::x;",
            ),
            false,
        ),
        (
            file(&["checks"], "// crate::daemon\nlet s = \"crate::daemon\";"),
            false,
        ),
        (
            file(&["checks"], "/* crate::daemon */ use crate::checks::x;"),
            false,
        ),
        (
            file(
                &["checks"],
                "let h = r#\"a \"quoted\" crate::daemon\"#; use crate::measure::x;",
            ),
            false,
        ),
        (
            file(
                &["checks"],
                "let h = r#\"a \"quoted\"\"#; use crate::daemon::x;",
            ),
            true,
        ),
        (file(&["daemon"], "use crate::{checks, measure::y};"), false),
        (
            file(&["measure"], "#[cfg(test)] use crate::fixtures;"),
            false,
        ),
    ];
    for (f, broken) in cases {
        let bad = violations(&rules, std::slice::from_ref(&f));
        assert_eq!(!bad.is_empty(), broken, "{}: {bad:?}", f.2);
    }
    // a module with no row is itself a violation
    assert!(!violations(&rules, &[file(&["engine"], "")]).is_empty());
}
