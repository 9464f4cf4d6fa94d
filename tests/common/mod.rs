//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The repository's copy of the shared reference material (`tests/reference/`).
pub fn reference(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/reference")
        .join(name)
}

/// Read a reference CSV: skips `#` comments and the header row; returns the numeric rows.
pub fn csv_rows(name: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(reference(name)).expect("reference file");
    let mut rows = Vec::new();
    let mut header_seen = false;
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if !header_seen {
            header_seen = true;
            continue;
        }
        rows.push(
            line.split(',')
                .map(|s| s.trim().parse::<f64>().expect("number"))
                .collect(),
        );
    }
    rows
}
