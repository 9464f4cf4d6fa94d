"""Captures without a controller: `goniowatch check` on a finished capture set and `goniowatch run`
in watch mode, both with a files source ([source] kind = "files"). The same scenario through the
protocol and through the files gives the same captures and the same alarms; bad names, unreadable
and half-written files, an empty folder and a bad config each get a clear message."""

import json
import os
import signal
import subprocess
import time

import pytest

from hil import (
    REPO,
    assert_replay_identical,
    binary,
    daemon_config,
    needs_simulator,
    read_jsonl,
    run_check,
    run_daemon,
    write_archive,
)

FAULTS = [
    {"kind": "lamp-step", "at_capture": 700, "step_pct": -3.0},
    {"kind": "dark-frame", "at_capture": 300},
    {"kind": "nan-pixels", "at_capture": 500, "count": 5},
]
CHECKS = ["capture-quality", "drift", "positioning", "reciprocity-outlier", "isotropy"]


def verdicts(session):
    """The alarms that judge the captures (not the link's), as (code, idx)."""
    return sorted((a["code"], a.get("idx")) for a in read_jsonl(session / "alarms.jsonl") if a["kind"] in CHECKS)


def values(session):
    return [(c["idx"], c["entry"], c["t"], c.get("xyz")) for c in read_jsonl(session / "captures.jsonl")]


def test_the_same_scenario_through_the_protocol_and_through_the_files_gives_the_same_verdicts(hil, tmp_path):
    needs_simulator()
    rig = hil("proto", FAULTS, captures=1400)
    live = tmp_path / "proto-session"
    code, _, err = run_daemon(rig, live, daemon_config(tmp_path, "proto"), timeout=300)
    assert code == 0, err[-2000:]
    expected = verdicts(live)
    assert {"gain-step", "gain-drift"} & {c for c, _ in expected} and ("dark-capture", 300) in expected, expected

    for naming in ["bonn", "sidecar"]:
        folder, _ = write_archive(tmp_path, f"files-{naming}", FAULTS, naming=naming, captures=1400, id="proto")
        session = tmp_path / f"{naming}-session"
        cfg = sidecar_config(tmp_path) if naming == "sidecar" else None
        code, out, err = run_check(folder, session, cfg)
        assert code == 0, err[-3000:]
        assert "1400 checked" in out, out
        assert "files source" in err and ("sidecar" in err) == (naming == "sidecar"), err
        assert verdicts(session) == expected, naming
        # the same images, the same times, the same numbers
        assert values(session) == values(live), naming
        assert_replay_identical(session, tmp_path)
        # a checked set is a session like any other
        r = subprocess.run([binary(), "report", str(session)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and "report.html" in r.stdout, r.stderr
    # the capture folder was only read
    assert sorted(os.listdir(folder)) == sorted(n for n in os.listdir(folder) if not n.endswith(".check"))


def sidecar_config(tmp_path):
    cfg = tmp_path / "sidecar.toml"
    text = open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read()
    cfg.write_text(text + '\n[source]\nkind = "files"\nsidecar = "captures.csv"\n')
    return cfg


def test_an_ldr_archive_with_per_capture_exposures_reads_like_the_hdr_one(tmp_path):
    """16-bit sRGB PNGs, each auto-exposed by a power of two recorded in the sidecar: after the
    transfer function is undone and the exposure divided out, every capture's Y is within 1 % of
    the same capture written as Radiance HDR (whose own RGBE rounding is about 0.4 %), and the
    checks reach the same verdicts (NaN pixels aside: a PNG cannot hold them)."""
    needs_simulator()
    faults = [f for f in FAULTS if f["kind"] != "nan-pixels"]
    hdr, _ = write_archive(tmp_path, "hdrset", faults, naming="bonn", captures=1400, id="set")
    ldr, _ = write_archive(tmp_path, "ldrset", faults, naming="sidecar", captures=1400, ldr="png16", id="set")
    assert sorted(os.listdir(ldr))[0].endswith(".png")
    exposures = {float(line.split(",")[-1]) for line in (ldr / "captures.csv").read_text().splitlines()[1:]}
    assert len(exposures) > 1, exposures
    a, b = tmp_path / "hdr-session", tmp_path / "ldr-session"
    for folder, session, cfg in [(hdr, a, None), (ldr, b, sidecar_config(tmp_path))]:
        code, out, err = run_check(folder, session, cfg)
        assert code == 0, err[-3000:]
    ya = [c["xyz"][1] for c in read_jsonl(a / "captures.jsonl")]
    yb = [c["xyz"][1] for c in read_jsonl(b / "captures.jsonl")]
    assert len(ya) == len(yb) == 1400
    worst = max(abs(y2 / y1 - 1) for y1, y2 in zip(ya, yb))
    assert worst < 0.01, worst
    assert [c for c, _ in verdicts(a)] == [c for c, _ in verdicts(b)], (verdicts(a), verdicts(b))


def test_check_reports_what_it_cannot_place_or_read(tmp_path):
    needs_simulator()
    folder, _ = write_archive(tmp_path, "bad", [], naming="bonn-indexed", captures=120)
    names = sorted(os.listdir(folder))
    # a file type that is no capture, a capture whose name says nothing, angles off the plan,
    # an unreadable file and a half-written one (both under good names)
    (folder / "notes.txt").write_text("operator notes\n")
    (folder / "IMG_0001.hdr").write_bytes((folder / names[5]).read_bytes())
    (folder / "00999_tl017_pl000_tv000_pv000.hdr").write_bytes((folder / names[5]).read_bytes())
    (folder / names[10]).write_bytes(b"#?RADIANCE\nthis is not an image\n")
    whole = (folder / names[20]).read_bytes()
    (folder / names[20]).write_bytes(whole[: len(whole) // 2])
    before = {n: (folder / n).read_bytes() for n in os.listdir(folder)}
    session = tmp_path / "bad-session"
    code, out, err = run_check(folder, session)
    assert code == 0, err[-3000:]
    assert "120 announced" in out and "2 failed" in out, out
    assert "skipped notes.txt: not a capture file type" in err, err
    assert "skipped IMG_0001.hdr: the name does not match source.pattern" in err, err
    assert "skipped 00999_tl017_pl000_tv000_pv000.hdr: not in the plan" in err, err
    failed = {c["idx"]: c for c in read_jsonl(session / "captures.jsonl") if c["status"] == "failed"}
    assert set(failed) == {10, 20}, failed
    alarms = read_jsonl(session / "alarms.jsonl")
    skipped = [a for a in alarms if a["code"] == "skipped-files"]
    assert len(skipped) == 1 and skipped[0]["severity"] == "warning", skipped
    why = {f["file"]: f["kind"] for f in skipped[0]["evidence"]["files"]}
    assert why == {"notes.txt": "not-a-capture", "IMG_0001.hdr": "no-match", "00999_tl017_pl000_tv000_pv000.hdr": "not-in-plan"}, why
    summary = json.loads((session / "summary.json").read_text())
    assert summary["files_skipped"] == {"not-a-capture": 1, "no-match": 1, "not-in-plan": 1}, summary
    assert "files not placed: 3" in out, out
    assert {n: (folder / n).read_bytes() for n in os.listdir(folder)} == before, "the capture folder was changed"


def test_check_refuses_an_empty_folder_a_session_inside_it_and_a_protocol_config(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = run_check(empty, tmp_path / "s1")
    assert code == 2 and "no capture in" in err, err
    assert not (tmp_path / "s1").exists()
    (empty / "x.hdr").write_bytes(b"")
    code, _, err = run_check(empty, empty / "session")
    assert code == 2 and "inside the capture folder" in err, err
    assert not (empty / "session").exists()
    cfg = tmp_path / "proto.toml"
    cfg.write_text('[source]\nkind = "protocol"\n')
    code, _, err = run_check(empty, tmp_path / "s2", cfg)
    assert code == 2 and 'kind = "files"' in err, err
    cfg.write_text('[source]\nkind = "files"\npattern = "(?P<tl>\\\\d+"\n')
    code, _, err = run_check(empty, tmp_path / "s3", cfg)
    assert code == 2 and "source.pattern" in err, err
    code, _, err = run_check(tmp_path / "nowhere", tmp_path / "s4")
    assert code == 2 and "not a folder" in err, err


@pytest.mark.parametrize("wake", ["notify", "poll"])
def test_watch_mode_follows_a_folder_as_it_is_written(tmp_path, wake):
    """notify: file-system events alone (the listing interval is 10 minutes); poll: the
    listing every 100 ms alone (as on a network share)."""
    needs_simulator()
    n = 600
    faults = [{"kind": "dark-frame", "at_capture": 250}]
    cfg = tmp_path / "watch-daemon.toml"
    text = open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read()
    source = "poll_ms = 600000\n" if wake == "notify" else "poll_ms = 100\nnotify = false\n"
    cfg.write_text(text + '\n[source]\nkind = "files"\n' + source)
    session = tmp_path / "watch-session"
    # the folder the camera will write into does not exist yet when the daemon starts
    folder = tmp_path / "watch-cap" / "watch"
    p = subprocess.Popen(
        [binary(), "run", "--config", str(cfg), "--session", str(session), "--capture-root", str(folder), "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(0.5)
        written, writer = write_archive(tmp_path, "watch", faults, naming="bonn", captures=n, speed=7.0 / 0.01)
        assert written == folder
        writer.communicate(timeout=300)
        assert writer.returncode == 0
        # stop once every written capture is checked (counted by the daemon, not timed)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            try:
                if json.load(open(session / "summary.json"))["checked"]["captures"] >= n:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.2)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert "watching" in err, err
    caps = read_jsonl(session / "captures.jsonl")
    assert len(caps) == n, (len(caps), err[-2000:])
    assert [c["idx"] for c in caps] == list(range(n))
    # the same verdicts as a check of the finished folder
    checked = tmp_path / "watch-checked"
    code, _, err2 = run_check(folder, checked)
    assert code == 0, err2[-2000:]
    assert verdicts(session) == verdicts(checked)
    assert values(session) == values(checked)
    assert ("dark-capture", 250) in verdicts(session)
    assert_replay_identical(session, tmp_path)


def test_a_session_folder_belongs_to_one_capture_folder_and_one_config(tmp_path):
    """`check B --session S` where S holds the check of folder A (or of A with another config)
    is refused with exit 3 and a message that says why; S is left as it was."""
    needs_simulator()
    a, _ = write_archive(tmp_path, "src-a", captures=200, id="src-a")
    b, _ = write_archive(tmp_path, "src-b", captures=200, id="src-b")
    session = tmp_path / "one-source"
    code, out, err = run_check(a, session)
    assert code == 0, err[-2000:]
    before = {p.name: p.read_bytes() for p in session.iterdir() if p.is_file()}
    code, out, err = run_check(b, session)
    assert code == 3, (code, out, err[-2000:])
    assert "another capture folder" in err and str(a) in err, err
    other = tmp_path / "other.toml"
    other.write_text(open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read().replace("dark_y = 0.5", "dark_y = 0.4"))
    code, out, err = run_check(a, session, other)
    assert code == 3, (code, out, err[-2000:])
    assert "another config" in err, err
    assert {p.name: p.read_bytes() for p in session.iterdir() if p.is_file()} == before


def test_an_all_dark_set_is_not_a_perfect_table_2(tmp_path):
    """Every capture at or below the dark level (here a config whose dark level is above the
    white): no pair is scored, and `check` says so and exits 6, never 0 with a Table 2 of zeros."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "dark", captures=400, id="dark")
    cfg = tmp_path / "dark.toml"
    cfg.write_text(open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read().replace("dark_y = 0.5", "dark_y = 100000.0"))
    code, out, err = run_check(folder, tmp_path / "dark-session", cfg)
    assert code == 6, (code, out, err[-2000:])
    assert "captures are dark" in err and "rgb_scale" in err, err
    # the same set with the right dark level scores its pairs and exits 0
    code, out, err = run_check(folder, tmp_path / "lit-session")
    assert code == 0, err[-2000:]


def rescaled(folder, dest, shift):
    """A copy of a flat-RGBE Bonn archive with every pixel times 2**shift (the exponent byte
    moved: the copy holds the same picture exactly, on another scale); written here, not by the
    simulator's archive writer."""
    dest.mkdir(parents=True)
    for name in sorted(os.listdir(folder)):
        data = (folder / name).read_bytes()
        head = data.index(b"\n", data.index(b"\n\n") + 2) + 1
        px = bytearray(data[head:])
        for i in range(3, len(px), 4):
            if px[i]:
                px[i] += shift
        (dest / name).write_bytes(data[:head] + bytes(px))
    return dest


def check_without_config(folder, session):
    """`goniowatch check FOLDER` with the built-in config (no --config): (code, out, err)."""
    r = subprocess.run([binary(), "check", str(folder), "--quiet", "--session", str(session)], capture_output=True, text=True, timeout=600)
    return r.returncode, r.stdout, r.stderr


SCALE_FAULTS = [
    {"kind": "lamp-step", "at_capture": 900, "step_pct": -5.0},
    {"kind": "joint-offset", "at_capture": 1700, "joint": 2, "offset_deg": 2.0},
]


def test_a_bonn_archive_on_any_scale_checks_as_with_its_scale_configured(tmp_path):
    """A Bonn-named archive at 2^-10 (about 1e-3), 1 and 2^10 (about 1e3) times the simulator's
    radiance, checked with no config (the built-in one sets no rgb_scale): the white is taken
    from the data and printed with the factor, every scale gives the same captures, and the same
    drift and positioning alarms are raised and the same pairs scored as with the simulator's
    scale (rgb_scale = 100) configured."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "scales", SCALE_FAULTS, naming="bonn", captures=2600, id="scales")
    configured = tmp_path / "configured.toml"
    configured.write_text(open(os.path.join(REPO, "config", "archive.toml"), encoding="utf-8").read() + "\n[colour]\nrgb_scale = 100.0\n")
    code, out, err = run_check(folder, tmp_path / "configured", configured)
    assert code == 0, err[-2000:]
    want = [(x["code"], x.get("idx")) for x in read_jsonl(tmp_path / "configured" / "alarms.jsonl") if x["kind"] in ("drift", "positioning")]
    codes = {c for c, _ in want}
    assert {"gain-step", "gain-drift"} & codes and "joint-offset-suspected" in codes, want
    want_pairs = json.load(open(tmp_path / "configured" / "summary.json"))["table2"]["pairs"]
    assert want_pairs > 100, want_pairs
    xyz = {}
    for shift in (-10, 0, 10):
        data = folder if shift == 0 else rescaled(folder, tmp_path / f"scale{shift}" / "scales", shift)
        session = tmp_path / f"auto{shift}"
        code, out, err = check_without_config(data, session)
        assert code == 0, (shift, err[-2000:])
        assert "the white is taken from the data" in err and "rgb_scale =" in err, err
        got = [(x["code"], x.get("idx")) for x in read_jsonl(session / "alarms.jsonl") if x["kind"] in ("drift", "positioning")]
        assert got == want, (shift, got, want)
        assert json.load(open(session / "summary.json"))["table2"]["pairs"] == want_pairs
        assert "rgb_scale" in (session / "config.toml").read_text()
        xyz[shift] = [c.get("xyz") for c in read_jsonl(session / "captures.jsonl")]
        assert_replay_identical(session, tmp_path)
    assert xyz[-10] == xyz[0] == xyz[10]


def test_a_finished_check_does_not_wait_for_sidecar_rows_without_their_files(tmp_path):
    """Six sidecar rows whose files were deleted: a finished set gets no more files, so each is
    missing at once (not after `give_up_s`, 30 s each here), counted in the summary and the
    manifest, and the rest is checked."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "absent", naming="sidecar", captures=300, id="absent")
    # not in a row: five failures in a row are critical (exit 4), which is another test's matter
    gone = sorted(p for p in folder.iterdir() if p.name.startswith("cap_"))[100:160:10]
    for p in gone:
        p.unlink()
    session = tmp_path / "absent-session"
    code, out, err = run_check(folder, session, sidecar_config(tmp_path), timeout=120)
    assert code == 0, err[-2000:]
    summary = json.load(open(session / "summary.json"))
    assert summary["checked"]["missing"] == 6 and summary["checked"]["captures"] == 300, summary["checked"]
    missing = [m for m in read_jsonl(session / "manifest.jsonl") if m["status"] == "missing"]
    assert sorted(m["file"].split("/")[-1] for m in missing) == [p.name for p in gone]
    assert all("after 0.0 s" in (m["error"] or "") for m in missing), missing


def test_every_plan_entry_without_a_capture_is_reported_and_listed_for_retaking(tmp_path):
    """Three files of a set deleted, one replaced by a symbolic link to another capture: the four
    entries are not captured, which the listing, the summary and the retake list say (the
    link among the skipped files with why), and nothing else changes."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "holes", captures=300, id="holes")
    names = sorted(p.name for p in folder.iterdir() if p.suffix == ".hdr")
    gone = [names[40], names[41], names[200]]
    for n in gone:
        (folder / n).unlink()
    (folder / names[120]).unlink()
    os.symlink(folder / names[121], folder / names[120])
    session = tmp_path / "holes-session"
    code, out, err = run_check(folder, session)
    assert code == 0, err[-3000:]
    assert f"skipped {names[120]}: a symbolic link" in err, err
    planned = 6561
    assert f"{planned - 296} plan entries have no capture" in err, err
    summary = json.load(open(session / "summary.json"))
    assert summary["entries_not_captured"] == planned - 296 and summary["checked"]["captures"] == 296
    assert f"not captured: {planned - 296} plan entries" in out, out
    r = subprocess.run([binary(), "report", str(session)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    import csv
    import io
    retakes = list(csv.DictReader(io.StringIO((session / "report" / "retakes.csv").read_text())))
    holes = [int(x["entry"]) for x in retakes if x["idx"] == "" and int(x["entry"]) < 300]
    assert holes == [40, 41, 120, 200], holes
    assert all(x["why"].startswith("not captured") for x in retakes if x["idx"] == "")
    # a capture folder given by a link to it is followed, and the link is not a skipped file
    alias = tmp_path / "holes-alias"
    os.symlink(folder, alias)
    code, out, err = run_check(alias, tmp_path / "alias-session")
    assert code == 0, err[-3000:]
    assert "296 captures placed, 1 files skipped" in err, err


def test_a_finished_check_of_a_folder_that_has_grown_is_refused_not_reported_stale(tmp_path):
    """Check half a folder, add the rest, run the same command: the finished session is not
    reported as the folder's result (it was: "200 captures placed", "100 checked", exit 0);
    it is refused with exit 3 and what to do, and left as it was; a new session checks all."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "grow", captures=200, id="grow")
    later = tmp_path / "later"
    later.mkdir()
    names = sorted(p.name for p in folder.iterdir() if p.suffix == ".hdr")
    for n in names[100:]:
        os.rename(folder / n, later / n)
    session = tmp_path / "grow-session"
    code, out, err = run_check(folder, session)
    assert code == 0, err[-2000:]
    before = {p.name: p.read_bytes() for p in session.iterdir() if p.is_file()}
    for n in names[100:]:
        os.rename(later / n, folder / n)
    code, out, err = run_check(folder, session)
    assert code == 3, (code, out, err[-2000:])
    assert "finished check of 100 captures" in err and "100 captures it has not checked" in err and "--session NEW" in err, err
    assert {p.name: p.read_bytes() for p in session.iterdir() if p.is_file()} == before
    # a new session checks all 200
    code, out, err = run_check(folder, tmp_path / "grow-all")
    assert code == 0, err[-2000:]
    assert json.load(open(tmp_path / "grow-all" / "summary.json"))["checked"]["captures"] == 200


def test_a_sidecar_that_does_not_parse_is_a_configuration_error(tmp_path):
    """A sidecar row with a value that is not a number: exit 2, as the exit-code table
    (docs/commands.md) says for the configuration's input, with the sidecar's line named; nothing is written."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "badcar", naming="sidecar", captures=50, id="badcar")
    table = folder / "captures.csv"
    lines = table.read_text().splitlines()
    cols = lines[1].split(",")
    cols[1] = "north"
    lines[1] = ",".join(cols)
    table.write_text("\n".join(lines) + "\n")
    session = tmp_path / "badcar-session"
    code, out, err = run_check(folder, session, sidecar_config(tmp_path))
    assert code == 2, (code, out, err[-2000:])
    assert "sidecar" in err and "line" in err, err
    assert not session.exists()
