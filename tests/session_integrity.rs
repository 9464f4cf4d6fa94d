//! A session folder that is damaged or incomplete is never overwritten or trusted: a missing or
//! emptied journal with results present, a changed byte in the journal, a folder without its
//! config. Each case is a real session (a journal of protocol lines and measured captures,
//! rebuilt into results), damaged afterwards, then handed to the binary.

mod common;
use common::reference;
use goniowatch::daemon::ingest::measure_file;
use goniowatch::decode::DecodeLimits;
use goniowatch::engine::Input;
use goniowatch::fixtures::Controller;
use goniowatch::session::journal::{JournalEntry, JournalItem, JsonlFile};
use goniowatch::session::recovery::{recover, Session};
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_goniowatch"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("gw-integrity-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const CAPTURES: u64 = 4;

/// A session of `CAPTURES` checked captures under `base/session`, its captures under
/// `base/captures`; the capture root is given relative to `base` (as `--capture-root` would be
/// from a shell whose working directory is `base`).
fn make_session(base: &Path) -> PathBuf {
    let root = base.join("captures");
    std::fs::create_dir_all(root.join("s")).unwrap();
    for i in 0..CAPTURES {
        let src = reference(if i % 2 == 0 {
            "images/valid/scale.hdr"
        } else {
            "images/valid/f16_zip.exr"
        });
        std::fs::copy(src, root.join(format!("s/cap_{i}.img"))).unwrap();
    }
    let dir = base.join("session");
    let config = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml");
    // the working directory is the process's: one test at a time may move it
    static CWD: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let guard = CWD.lock().unwrap_or_else(|e| e.into_inner());
    let cwd = std::env::current_dir().unwrap();
    std::env::set_current_dir(base).unwrap();
    let session = Session::open_or_create(
        &dir,
        Some(&config),
        Some(Path::new("/nonexistent/port")),
        Some(Path::new("captures")),
    );
    std::env::set_current_dir(cwd).unwrap();
    drop(guard);
    let session = session.unwrap();
    assert!(
        session.info.capture_root.is_absolute(),
        "the capture root is stored absolute"
    );
    let mut journal = JsonlFile::append(&dir.join("journal.jsonl")).unwrap();
    let mut controller = Controller::default();
    let mut line = |verb: &str, fields: &[(&str, String)]| controller.line(verb, fields);
    let mut inputs = vec![
        Input::Connected,
        line(
            "IDENT",
            &[
                ("rig", "r".into()),
                ("proto", "1".into()),
                ("session", "s".into()),
                ("captures", "6561".into()),
                ("boot", "1".into()),
            ],
        ),
    ];
    for i in 0..CAPTURES {
        inputs.push(line(
            "CAPTURE",
            &[
                ("idx", i.to_string()),
                ("entry", i.to_string()),
                ("file", format!("s/cap_{i}.img")),
                ("t", format!("{}.125", i * 7)),
                ("cmd", "0,90,-90,12".into()),
                ("enc", "0,90,-90,12".into()),
                ("exp", "x".into()),
            ],
        ));
    }
    // a link blip: two alarms without a capture index
    inputs.push(Input::Disconnected {
        reason: "EIO".into(),
    });
    inputs.push(Input::Connected);
    for i in 0..CAPTURES {
        let p = root.join(format!("s/cap_{i}.img"));
        let outcome =
            measure_file(&root, &p, &session.config.capture, &DecodeLimits::default()).unwrap();
        inputs.push(Input::Outcome { idx: i, outcome });
    }
    for (n, input) in inputs.into_iter().enumerate() {
        journal
            .write_entry(&JournalEntry {
                wall_ms: 1_000 + n as u64,
                item: JournalItem::In(input),
            })
            .unwrap();
    }
    journal.sync().unwrap();
    drop(journal);
    recover(&session).unwrap();
    let captures = std::fs::read_to_string(dir.join("captures.jsonl")).unwrap();
    assert_eq!(captures.lines().count() as u64, CAPTURES);
    dir
}

/// Every file of a folder, for "nothing was changed".
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().map(|t| t.is_file()).unwrap_or(false))
        .filter(|e| e.file_name() != "lock")
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

fn run_on(dir: &Path) -> std::process::Output {
    bin()
        .args(["run", "--quiet", "--session"])
        .arg(dir)
        .output()
        .unwrap()
}

fn replay_of(dir: &Path, out: &Path) -> std::process::Output {
    bin()
        .args(["replay", "--quiet", "--out"])
        .arg(out)
        .arg(dir)
        .output()
        .unwrap()
}

#[test]
fn an_intact_session_replays_identically_from_any_working_directory() {
    let base = scratch("intact");
    let dir = make_session(&base);
    let out = base.join("replayed");
    let r = bin()
        .current_dir("/")
        .args(["replay", "--quiet", "--out"])
        .arg(&out)
        .arg(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert_eq!(
        r.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(!stdout.contains("MISMATCH"), "{stdout}");
    for f in ["captures.jsonl", "manifest.jsonl", "alarms.jsonl"] {
        assert_eq!(
            std::fs::read(dir.join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
            "{f}"
        );
    }
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn a_missing_or_emptied_journal_never_costs_the_results() {
    for how in ["deleted", "emptied"] {
        let base = scratch(how);
        let dir = make_session(&base);
        let journal = dir.join("journal.jsonl");
        if how == "deleted" {
            std::fs::remove_file(&journal).unwrap();
        } else {
            std::fs::write(&journal, b"").unwrap();
        }
        let before = snapshot(&dir);
        let r = run_on(&dir);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(3), "{how}: {err}");
        assert!(
            err.contains("journal.jsonl") && err.contains("will not overwrite"),
            "{how}: {err}"
        );
        assert_eq!(snapshot(&dir), before, "{how}: the folder is unchanged");
        let r = replay_of(&dir, &base.join("replayed"));
        assert_eq!(r.status.code(), Some(3), "{how}: replay refuses too");
        assert!(String::from_utf8_lossy(&r.stderr).contains("nothing to replay"));
        std::fs::remove_dir_all(&base).ok();
    }
}

#[test]
fn a_session_stopped_before_its_first_input_resumes() {
    // the run writes summary.json on its first tick, before any input reaches the journal;
    // that alone is not a result that resuming could lose
    let base = scratch("firsttick");
    let dir = make_session(&base);
    for f in goniowatch::session::folder::RESULT_FILES {
        if dir.join(f).exists() {
            std::fs::write(dir.join(f), b"").unwrap();
        }
    }
    std::fs::write(dir.join("journal.jsonl"), b"").unwrap();
    assert!(dir.join("summary.json").exists());
    Session::open_or_create(&dir, None, None, None).unwrap();
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn a_folder_with_data_but_no_config_is_not_taken_for_a_new_session() {
    let base = scratch("noconfig");
    let dir = make_session(&base);
    std::fs::remove_file(dir.join("config.toml")).unwrap();
    let before = snapshot(&dir);
    let r = bin()
        .args(["run", "--quiet", "--config"])
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml"))
        .arg("--session")
        .arg(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(err.contains("not a complete goniowatch session"), "{err}");
    assert_eq!(snapshot(&dir), before);
    std::fs::remove_dir_all(&base).ok();
}

/// Change one byte of the journal (the first match of `from` on a line containing `on`) and
/// check that resume and replay refuse it, name the line, and change nothing.
fn damaged_journal_is_refused(name: &str, on: &str, from: &str, to: &str) {
    let base = scratch(name);
    let dir = make_session(&base);
    let journal = dir.join("journal.jsonl");
    let text = std::fs::read_to_string(&journal).unwrap();
    let (n, line) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains(on) && l.contains(from))
        .unwrap();
    let damaged = text.replacen(line, &line.replacen(from, to, 1), 1);
    assert_ne!(damaged, text);
    std::fs::write(&journal, damaged).unwrap();
    let before = snapshot(&dir);
    let r = run_on(&dir);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{name}: {err}");
    assert!(
        err.contains(&format!("line {} is damaged", n + 1)),
        "{name}: {err}"
    );
    assert_eq!(snapshot(&dir), before, "{name}: nothing was changed");
    let r = replay_of(&dir, &base.join("replayed"));
    assert_eq!(r.status.code(), Some(3), "{name}: replay refuses too");
    assert!(String::from_utf8_lossy(&r.stderr).contains("is damaged"));
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn a_bit_flip_in_a_journaled_serial_line_is_refused() {
    // capture index 2 becomes 3 ('2' ^ 0x01): still a well-formed line, wrong content
    damaged_journal_is_refused("flip", "CAPTURE idx=2", "idx=2", "idx=3");
}

#[test]
fn a_changed_digit_in_a_journaled_measurement_is_refused() {
    damaged_journal_is_refused(
        "digit",
        "\"outcome\"",
        "\"mean_rgb\":[157.",
        "\"mean_rgb\":[158.",
    );
}

#[test]
fn compare_refuses_a_malformed_reference_as_bad_input() {
    let base = scratch("badref");
    let dir = make_session(&base);
    let reference = base.join("bad.ref");
    std::fs::write(&reference, "this is not a reference file\n1 2 3\n").unwrap();
    let r = bin()
        .arg("compare")
        .arg(&dir)
        .arg(&reference)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("invalid reference") && err.contains("line"),
        "{err}"
    );
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn the_report_counts_every_alarm_the_summary_counts() {
    let base = scratch("report");
    let dir = make_session(&base);
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap();
    let total: u64 = summary["alarms"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    let lines = std::fs::read_to_string(dir.join("alarms.jsonl"))
        .unwrap()
        .lines()
        .count() as u64;
    assert!(total >= 2 && total == lines, "{total} vs {lines}");
    let out = base.join("report");
    let r = bin()
        .arg("report")
        .arg(&dir)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        r.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        html.contains(&format!("<td>alarms</td><td>{total}</td>")),
        "summary table"
    );
    assert!(html.contains(&format!("<h2>Alarms ({total})</h2>")));
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn a_journal_that_is_only_a_torn_line_never_costs_the_results() {
    let base = scratch("tornonly");
    let dir = make_session(&base);
    let journal = dir.join("journal.jsonl");
    // a journal that lost every line end: one unterminated "line"
    std::fs::write(&journal, b"{\"wall_ms\":1,\"in\":\"connected\"").unwrap();
    let before = snapshot(&dir);
    let r = run_on(&dir);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(err.contains("records no input"), "{err}");
    assert_eq!(snapshot(&dir), before, "nothing was changed");
    // a tail far longer than any journal line is damage, not a torn write
    let base2 = scratch("torntail");
    let dir2 = make_session(&base2);
    let mut j = std::fs::read(dir2.join("journal.jsonl")).unwrap();
    j.extend(std::iter::repeat_n(b'x', 2 << 20));
    std::fs::write(dir2.join("journal.jsonl"), &j).unwrap();
    let before = snapshot(&dir2);
    let r = run_on(&dir2);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(err.contains("without a line end"), "{err}");
    assert_eq!(snapshot(&dir2), before, "nothing was changed");
    std::fs::remove_dir_all(&base).ok();
    std::fs::remove_dir_all(&base2).ok();
}

#[test]
fn a_session_from_before_checksums_stays_resumable() {
    let base = scratch("legacy");
    let dir = make_session(&base);
    let journal = dir.join("journal.jsonl");
    // the journal as an older goniowatch wrote it: no checksums, and session.json says so
    let plain: String = std::fs::read_to_string(&journal)
        .unwrap()
        .lines()
        .map(|l| {
            let cut = l.rfind(",\"sum\":\"").unwrap();
            format!("{}}}\n", &l[..cut])
        })
        .collect();
    std::fs::write(&journal, plain).unwrap();
    let info_path = dir.join("session.json");
    let mut info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&info_path).unwrap()).unwrap();
    info["journal_checksums"] = false.into();
    std::fs::write(&info_path, serde_json::to_vec_pretty(&info).unwrap()).unwrap();
    let captures = std::fs::read(dir.join("captures.jsonl")).unwrap();
    // resumed once: the run loop appends checksummed lines after the plain ones
    let session = Session::open_or_create(&dir, None, None, None).unwrap();
    recover(&session).unwrap();
    let mut j = JsonlFile::append(&journal).unwrap();
    j.write_entry(&JournalEntry {
        wall_ms: 9_999,
        item: JournalItem::In(Input::Idle),
    })
    .unwrap();
    j.sync().unwrap();
    drop(j);
    // and resumed again: still readable, and the results are the same
    let session = Session::open_or_create(&dir, None, None, None).unwrap();
    let (_, inputs) = recover(&session).unwrap();
    assert!(inputs > CAPTURES as usize);
    assert_eq!(std::fs::read(dir.join("captures.jsonl")).unwrap(), captures);
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn replay_never_writes_over_another_session_or_into_the_captures() {
    let base = scratch("replayout");
    let dir = make_session(&base);
    let other = base.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("journal.jsonl"), b"precious\n").unwrap();
    let before = snapshot(&other);
    let r = replay_of(&dir, &other);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_ne!(r.status.code(), Some(0), "{err}");
    assert!(err.contains("holds a session"), "{err}");
    assert_eq!(snapshot(&other), before);
    let inside = base.join("captures/s/replayed");
    let r = replay_of(&dir, &inside);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_ne!(r.status.code(), Some(0), "{err}");
    assert!(err.contains("inside the capture folder"), "{err}");
    assert!(!inside.exists());
    // `..` after a folder that does not exist yet still resolves into the captures
    let sneaky = base.join("nowhere/../captures/s/replayed");
    let r = replay_of(&dir, &sneaky);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_ne!(r.status.code(), Some(0), "{err}");
    assert!(err.contains("inside the capture folder"), "{err}");
    assert!(!base.join("nowhere").exists());
    assert!(!inside.exists());
    std::fs::remove_dir_all(&base).ok();
}
