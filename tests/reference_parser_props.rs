//! The reference-BRDF parser (docs/reference-format.md) reads files from outside: it must take
//! any text without panicking, name a line and column inside the input for every error, point
//! at the offending field, and read a very long line in time linear in its length.

use goniowatch::reference::{parse, ReferenceError, ValueKind};
use proptest::prelude::*;

const HEADER: &str = "# goniowatch reference BRDF, version 1\n";

/// Valid files of each kind, the mutation tests' starting points.
fn seeds() -> Vec<String> {
    vec![
        format!(
            "{HEADER}# an Integra-like measurement\nname = walkway (Integra, 2001)\n\
             format = spectral   # spectral | rgb | xyz\nbands = 400 500 600 700\n\
             # theta_i phi_i theta_o phi_o values\n30 0 45 180   0.5 0.5 0.5 0.5   # a comment\n\
             30 0 40 170.5 1 1 1 1\n0 0 0 0 0.25 0.5 0.75 1e-3\n"
        ),
        format!("{HEADER}format = xyz\n0 0 10 0 1 2 3\n45 90 30 270 -0.5 2.5e1 3\n"),
        format!("{HEADER}name = Zürich façade\nformat = rgb\n\n  10\t20 30 40 0.1 0.2 0.3\n90 -30 0 360 1 1 1\n")
            .replace('\n', "\r\n"),
    ]
}

/// Every error's line exists in the input and its column lies on that line (one past its last
/// character at most, for an error at the end of a line); an empty input has only line 1,
/// column 1.
fn location_is_inside(text: &str, e: &ReferenceError) -> Result<(), String> {
    let lines: Vec<&str> = text.lines().collect();
    let ok = if lines.is_empty() {
        (e.line, e.column) == (1, 1)
    } else {
        e.line >= 1
            && e.line <= lines.len()
            && e.column >= 1
            && e.column <= lines[e.line - 1].chars().count() + 1
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "error at line {}, column {} outside the input ({} lines): {e}",
            e.line,
            e.column,
            lines.len()
        ))
    }
}

/// Parse and check the invariants that hold whatever the input: an error is located inside it,
/// a success has data lines that exist, angles in range and finite XYZ.
fn check(text: &str) -> Result<(), String> {
    match parse(text) {
        Err(e) => location_is_inside(text, &e),
        Ok(r) => {
            let lines = text.lines().count();
            for s in &r.samples {
                if !(s.line >= 2 && s.line <= lines) {
                    return Err(format!("sample line {} of {lines}", s.line));
                }
                let [ti, _, to, _] = s.angles_deg;
                if !((0.0..=90.0).contains(&ti) && (0.0..=90.0).contains(&to)) {
                    return Err(format!("angles {:?}", s.angles_deg));
                }
                if !s.xyz.iter().all(|v| v.is_finite()) {
                    return Err(format!("xyz {:?}", s.xyz));
                }
            }
            if r.samples.is_empty() {
                return Err("a success without samples".into());
            }
            Ok(())
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Long lines
// ---------------------------------------------------------------------------------------------

#[test]
fn a_line_of_200000_values_parses() {
    // 200,000 bands 0.0015 nm apart and a reflectance of 1 in each: the white, Y = 100
    let n = 200_000;
    let bands: Vec<String> = (0..n)
        .map(|i| format!("{:.4}", 400.0 + 0.0015 * i as f64))
        .collect();
    let mut text = format!("{HEADER}format = spectral\nbands = {}\n", bands.join(" "));
    text.push_str("30 0 30 180");
    text.push_str(&" 1".repeat(n));
    text.push('\n');
    let r = parse(&text).unwrap();
    assert_eq!(r.kind, ValueKind::Spectral);
    assert_eq!(r.bands.len(), n);
    assert_eq!(r.samples.len(), 1);
    assert!(
        (r.samples[0].xyz[1] - 100.0).abs() < 1e-6,
        "{:?}",
        r.samples[0].xyz
    );
    // a bad value at the very end is found and located by its column
    let mut bad = text.trim_end().to_string();
    bad.replace_range(bad.len() - 1.., "x");
    let e = parse(&bad).unwrap_err();
    let last = bad.lines().last().unwrap();
    assert_eq!((e.line, e.column), (4, last.chars().count()), "{e}");
    assert!(e.message.contains("'x'"), "{e}");
}

#[test]
fn a_line_of_200000_fields_is_refused_at_the_first_extra_field() {
    let n = 200_000;
    let mut text = format!("{HEADER}format = xyz\n0 0 10 0");
    text.push_str(&" 1".repeat(n));
    text.push('\n');
    let e = parse(&text).unwrap_err();
    // "0 0 10 0" is 8 characters, then " 1" per value: the 4th value is at column 8 + 4·2
    assert_eq!((e.line, e.column), (3, 8 + 4 * 2), "{e}");
    assert!(
        e.message.contains(&format!(
            "expected 4 angles and 3 values, found {} fields",
            n + 4
        )),
        "{e}"
    );
    // a field far along a line of blanks
    let text = format!("{HEADER}format = xyz\n0 0 10 0 1 2{}x\n", " ".repeat(n));
    let e = parse(&text).unwrap_err();
    assert_eq!((e.line, e.column), (3, 12 + n + 1), "{e}");
}

#[test]
fn columns_count_characters_not_bytes() {
    // U+3000 (ideographic space) is whitespace of three bytes; 'ü' is two bytes
    for (text, line, column) in [
        (format!("{HEADER}format\u{3000}= png\n"), 2, 10),
        (format!("{HEADER}format =\u{3000}png\n"), 2, 10),
        (
            format!("{HEADER}format = spectral\nbands =\u{3000}400 bäd\n"),
            3,
            13,
        ),
        (format!("{HEADER}format = xyz\n0 0 10 0 ü 2 3\n"), 3, 10),
        (
            format!("{HEADER}format = xyz\n0\u{3000}0 10 0 1 2 x\n"),
            3,
            14,
        ),
        (format!("{HEADER}format = xyz\nü=1\n"), 3, 1),
    ] {
        let e = parse(&text).unwrap_err();
        assert_eq!((e.line, e.column), (line, column), "{text:?}: {e}");
        location_is_inside(&text, &e).unwrap();
    }
}

#[test]
fn the_seeds_are_valid() {
    for s in seeds() {
        let r = parse(&s).unwrap_or_else(|e| panic!("{s:?}: {e}"));
        assert!(r.samples.len() >= 2);
        check(&s).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------------------

/// One edit of a file: by character position (taken modulo the length) or by line.
#[derive(Debug, Clone)]
enum Edit {
    Insert(usize, char),
    Delete(usize),
    Replace(usize, char),
    InsertText(usize, String),
    DuplicateLine(usize),
    DeleteLine(usize),
    SwapLines(usize, usize),
    Truncate(usize),
}

/// Characters that mean something to the parser, and any character at all.
fn interesting_char() -> impl Strategy<Value = char> {
    prop_oneof![
        prop::sample::select(vec![
            ' ', '\t', '\n', '\r', '#', '=', '-', '+', '.', 'e', 'E', '0', '1', '9', 'n', 'a', 'i',
            'f', 'ü', '\u{3000}', '\u{a0}', '\u{feff}',
        ]),
        any::<char>(),
    ]
}

fn interesting_text() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "nan",
            "inf",
            "-inf",
            "1e999",
            "1e-999",
            "-0",
            "0x10",
            "",
            "=",
            "# ",
            "\n",
            "\r\n",
            " 1",
            "format = xyz\n",
            "format = rgb\n",
            "format = spectral\n",
            "bands = 400 700\n",
            "bands = 700 400\n",
            "bands = 300\n",
            "name = x\n",
            "90.0000001",
            "-1e-300",
            "91",
        ])
        .prop_map(str::to_string),
        ".{0,12}",
    ]
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), interesting_char()).prop_map(|(i, c)| Edit::Insert(i, c)),
        any::<usize>().prop_map(Edit::Delete),
        (any::<usize>(), interesting_char()).prop_map(|(i, c)| Edit::Replace(i, c)),
        (any::<usize>(), interesting_text()).prop_map(|(i, t)| Edit::InsertText(i, t)),
        any::<usize>().prop_map(Edit::DuplicateLine),
        any::<usize>().prop_map(Edit::DeleteLine),
        (any::<usize>(), any::<usize>()).prop_map(|(i, j)| Edit::SwapLines(i, j)),
        any::<usize>().prop_map(Edit::Truncate),
    ]
}

fn apply(text: &str, e: &Edit) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    let at = |i: usize, n: usize| if n == 0 { 0 } else { i % n };
    let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
    match e {
        Edit::Insert(i, c) => {
            let p = at(*i, chars.len() + 1);
            chars.insert(p, *c);
        }
        Edit::Delete(i) => {
            if !chars.is_empty() {
                let p = at(*i, chars.len());
                chars.remove(p);
            }
        }
        Edit::Replace(i, c) => {
            if !chars.is_empty() {
                let p = at(*i, chars.len());
                chars[p] = *c;
            }
        }
        Edit::InsertText(i, t) => {
            let p = at(*i, chars.len() + 1);
            chars.splice(p..p, t.chars());
        }
        Edit::DuplicateLine(i) => {
            let p = at(*i, lines.len());
            let l = lines[p].clone();
            lines.insert(p, l);
            return lines.join("\n");
        }
        Edit::DeleteLine(i) => {
            if lines.len() > 1 {
                let p = at(*i, lines.len());
                lines.remove(p);
            }
            return lines.join("\n");
        }
        Edit::SwapLines(i, j) => {
            let (p, q) = (at(*i, lines.len()), at(*j, lines.len()));
            lines.swap(p, q);
            return lines.join("\n");
        }
        Edit::Truncate(i) => {
            let p = at(*i, chars.len() + 1);
            chars.truncate(p);
        }
    }
    chars.into_iter().collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn any_text_is_parsed_or_refused_with_a_location_inside_it(text in "(?s).{0,300}") {
        check(&text).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn any_text_after_a_valid_first_line_is_parsed_or_refused_inside_it(
        body in proptest::collection::vec(
            prop_oneof![
                "[ -~]{0,60}",
                "[0-9 .eE+-]{0,60}",
                "(format|bands|name) ?= ?[ -~]{0,30}",
                ".{0,40}",
            ],
            0..12,
        )
    ) {
        let text = format!("{HEADER}{}", body.join("\n"));
        check(&text).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn edited_valid_files_are_parsed_or_refused_inside_them(
        seed in 0usize..3,
        edits in proptest::collection::vec(edit(), 1..6),
    ) {
        let mut text = seeds()[seed].clone();
        for e in &edits {
            text = apply(&text, e);
        }
        check(&text).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn a_bad_field_is_named_at_its_own_line_and_column(
        rows in proptest::collection::vec(
            (
                (0u32..=90, 0u32..360, 0u32..=90, 0u32..360),
                proptest::collection::vec(-100i32..100, 3),
                proptest::collection::vec("[ \t]{1,3}", 7),
            ),
            1..6,
        ),
        pick in any::<(usize, usize)>(),
        word in "[a-df-z_][a-z_]{0,6}",
    ) {
        // an xyz file whose fields are separated by random blanks; one field becomes a word
        let (row, field) = (pick.0 % rows.len(), pick.1 % 7);
        let mut text = format!("{HEADER}format = xyz\n");
        let mut want = (0, 0);
        for (r, ((ti, pi, to, po), vals, gaps)) in rows.iter().enumerate() {
            let mut fields: Vec<String> = [ti, pi, to, po].iter().map(|v| v.to_string()).collect();
            fields.extend(vals.iter().map(|v| format!("{}", *v as f64 / 10.0)));
            let mut line = String::new();
            for (f, value) in fields.iter().enumerate() {
                line.push_str(&gaps[f]);
                if r == row && f == field {
                    want = (r + 3, line.chars().count() + 1);
                    line.push_str(&word);
                } else {
                    line.push_str(value);
                }
            }
            text.push_str(&line);
            text.push('\n');
        }
        let e = parse(&text).unwrap_err();
        prop_assert_eq!((e.line, e.column), want, "{}", e);
        prop_assert!(e.message.contains(&format!("'{word}'")), "{}", e);
    }
}
