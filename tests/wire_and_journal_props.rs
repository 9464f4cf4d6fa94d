//! Property tests of the two readers of untrusted bytes in the shell's path: the protocol
//! parser (every line from the controller) and the journal reader (every resume and replay).
//! Neither may panic on any input; the parser must round-trip what the formatter writes and
//! tell an intact line from a corrupt one; the journal must round-trip what it writes and
//! refuse any changed byte, naming its line.

use goniowatch::engine::Input;
use goniowatch::protocol::{format, parse, parse_line, LineError};
use goniowatch::session::journal::{
    read_journal, JournalEntry, JournalError, JournalItem, JsonlFile,
};
use proptest::prelude::*;
use std::path::PathBuf;

/// A journal path in a fresh directory, removed with the guard (also when a case fails).
fn scratch(name: &str) -> (tempfile::TempDir, PathBuf) {
    let d = tempfile::Builder::new()
        .prefix(&format!("gw-props-{name}-"))
        .tempdir()
        .unwrap();
    let p = d.path().join("journal.jsonl");
    (d, p)
}

/// Field keys as the protocol has them: printable, no space, `=`, `*` or `%`.
fn key() -> impl Strategy<Value = String> {
    "[a-z][a-z0-9_]{0,7}"
}

fn input() -> impl Strategy<Value = Input> {
    prop_oneof![
        Just(Input::Connected),
        Just(Input::Idle),
        Just(Input::Restart),
        ".{0,40}".prop_map(|reason| Input::Disconnected { reason }),
        ".{0,200}".prop_map(|line| Input::Rx { line }),
        ".{0,40}".prop_map(|reason| Input::RxBad { reason }),
        proptest::collection::vec(".{0,20}", 0..4).prop_map(|files| Input::Unannounced { files }),
    ]
}

fn entry() -> impl Strategy<Value = JournalEntry> {
    (
        any::<u64>(),
        prop_oneof![
            input().prop_map(JournalItem::In),
            ".{0,80}".prop_map(JournalItem::Out)
        ],
    )
        .prop_map(|(wall_ms, item)| JournalEntry { wall_ms, item })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn the_parser_never_panics(line in ".{0,600}") {
        let _ = parse_line(&line);
    }

    #[test]
    fn the_parser_never_panics_on_near_protocol_lines(
        seq in 0u32..2_000_000,
        verb in "[A-Z?]{0,8}",
        body in "[ -~]{0,80}",
    ) {
        let p = format!("{seq} {verb} {body}");
        let line = format!("{p}*{:04X}", goniowatch::protocol::crc16(p.as_bytes()));
        let _ = parse_line(&line);
    }

    #[test]
    fn what_is_formatted_parses_back(
        seq in 0u32..1_000_000,
        verb in "[A-Z]{1,8}",
        fields in proptest::collection::btree_map(key(), ".{0,30}", 0..6),
    ) {
        let fields: Vec<(&str, String)> = fields.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
        let line = format(seq, &verb, &fields);
        // a value that is not valid in a line is encoded; an over-long line is refused whole
        match parse(&line) {
            Ok(m) => {
                prop_assert_eq!(m.seq, seq);
                prop_assert_eq!(&m.verb, &verb);
                for (k, v) in &fields {
                    // values survive byte for byte when they are UTF-8 (they are)
                    prop_assert_eq!(m.get(k), Some(v.as_str()));
                }
            }
            Err(e) => prop_assert!(line.len() + 1 > goniowatch::protocol::MAX_LINE, "{e}: {line}"),
        }
    }

    #[test]
    fn a_changed_character_is_a_frame_error_unless_the_crc_still_matches(
        fields in proptest::collection::btree_map(key(), "[ -~]{0,20}", 1..5),
        pos in any::<prop::sample::Index>(),
        ch in 0x20u8..0x7f,
    ) {
        let fields: Vec<(&str, String)> = fields.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
        let line = format(7, "CAPTURE", &fields);
        let mut bytes = line.clone().into_bytes();
        let i = pos.index(bytes.len());
        prop_assume!(bytes[i] != ch);
        bytes[i] = ch;
        let mutated = String::from_utf8(bytes).unwrap();
        match parse_line(&mutated) {
            // CRC-16 lets one change in 65,536 through; then the line is taken as sent
            Ok(_) | Err(LineError::Content { .. }) => {
                let star = mutated.rfind('*').unwrap();
                let crc = &mutated[star + 1..];
                prop_assert_eq!(
                    crc,
                    format!("{:04X}", goniowatch::protocol::crc16(&mutated.as_bytes()[..star]))
                );
            }
            Err(LineError::Frame(_)) => {}
        }
    }

    #[test]
    fn the_engine_takes_any_line_without_panicking(lines in proptest::collection::vec(".{0,120}", 1..40)) {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sim.toml")).unwrap();
        let mut e = goniowatch::engine::Engine::from_config(&goniowatch::config::Config::from_toml_str(&text).unwrap()).unwrap();
        e.handle(&Input::Connected);
        for line in lines {
            e.handle(&Input::Rx { line });
        }
        e.handle(&Input::Idle);
    }

    #[test]
    fn the_journal_reader_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
        let (_dir, p) = scratch("any");
        std::fs::write(&p, &bytes).unwrap();
        let _ = read_journal(&p, true);
        let _ = read_journal(&p, false);
    }

    #[test]
    fn the_journal_round_trips_and_refuses_any_changed_byte(
        entries in proptest::collection::vec(entry(), 1..8),
        pos in any::<prop::sample::Index>(),
        flip in 1u8..=255,
    ) {
        let (_dir, p) = scratch("rt");
        let mut f = JsonlFile::create(&p).unwrap();
        for e in &entries {
            f.write_entry(e).unwrap();
        }
        f.sync().unwrap();
        drop(f);
        let read = read_journal(&p, true).unwrap();
        prop_assert_eq!(&read.entries, &entries);
        let good = std::fs::read(&p).unwrap();
        let i = pos.index(good.len());
        let mut bad = good.clone();
        bad[i] ^= flip;
        std::fs::write(&p, &bad).unwrap();
        match read_journal(&p, true) {
            Err(JournalError::Damaged { line, .. }) => {
                // the damaged line is the one holding the byte, or (when the change made or
                // removed a line break) one next to it
                let at = good[..i].iter().filter(|b| **b == b'\n').count() + 1;
                prop_assert!(line + 1 >= at && line <= at + 1, "line {} for byte on line {}", line, at);
            }
            // the last line break changed: the last entry became a torn tail, left out
            Ok(r) => {
                prop_assert!(r.torn_tail && i == good.len() - 1);
                prop_assert_eq!(r.entries.len(), entries.len() - 1);
            }
            Err(e) => prop_assert!(false, "{e}"),
        }
    }
}
