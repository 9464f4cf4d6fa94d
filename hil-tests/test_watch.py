"""Watch mode (`goniowatch run` with a files source) and `check` against a careless operator:
files rewritten after a failed check, file times that step back, a folder replaced under the
daemon, copies and rejected files beside the originals, and a resumed check."""

import json
import os
import shutil
import signal
import subprocess
import time

from hil import REPO, assert_replay_identical, binary, needs_simulator, read_jsonl, run_check, write_archive


def watch_config(tmp_path, extra="", give_up_s=None):
    """config/sim.toml with a files source (`extra` lines in its `[source]` table)."""
    cfg = tmp_path / "watch.toml"
    text = open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read()
    if give_up_s is not None:
        assert "give_up_s = 30.0" in text
        text = text.replace("give_up_s = 30.0", f"give_up_s = {give_up_s}")
    cfg.write_text(text + '\n[source]\nkind = "files"\n' + extra)
    return cfg


class Watch:
    """A watch-mode daemon on `folder`, stopped with SIGINT."""

    def __init__(self, cfg, session, folder):
        self.session = session
        self.p = subprocess.Popen(
            [binary(), "run", "--config", str(cfg), "--session", str(session), "--capture-root", str(folder), "--quiet"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )

    def captures(self):
        try:
            return read_jsonl(self.session / "captures.jsonl")
        except (OSError, ValueError):
            return []

    def wait(self, pred, what, timeout=60):
        """Until `pred(captures)` holds (judged on what the daemon recorded, not on time)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.p.poll() is not None:
                raise AssertionError(f"the daemon ended early: {self.p.communicate()[1][-3000:]}")
            caps = self.captures()
            if pred(caps):
                return caps
            time.sleep(0.1)
        self.stop()
        raise AssertionError(f"timed out waiting for {what}: {len(self.captures())} captures\n{self.err[-3000:]}")

    def stop(self):
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGINT)
        try:
            self.out, self.err = self.p.communicate(timeout=60)
        finally:
            if self.p.poll() is None:
                self.p.kill()
        return self.err


def archive_files(tmp_path, name, n, naming="bonn", **kw):
    """A finished capture set of `n` captures, and its files in acquisition order."""
    folder, _ = write_archive(tmp_path, name, captures=n, naming=naming, id=name, **kw)
    files = sorted((p for p in folder.iterdir() if p.is_file() and p.suffix == ".hdr"), key=lambda p: p.stat().st_mtime_ns)
    return folder, files


def test_a_capture_that_failed_is_checked_again_when_its_file_is_complete(tmp_path):
    """A file written in two halves far apart fails its check; once it is whole it is checked
    again as a new capture of its entry, and the retake list does not name it."""
    needs_simulator()
    src, files = archive_files(tmp_path, "halves", 40)
    folder = tmp_path / "watch-halves"
    folder.mkdir()
    w = Watch(watch_config(tmp_path, "poll_ms = 100\n"), tmp_path / "halves-session", folder)
    try:
        for f in files[:10]:
            shutil.copy2(f, folder / f.name)
        w.wait(lambda c: len(c) >= 10, "ten captures")
        half = files[10]
        data = half.read_bytes()
        (folder / half.name).write_bytes(data[: len(data) // 2])
        caps = w.wait(lambda c: any(x["status"] == "failed" for x in c), "the half file to fail", timeout=120)
        failed = next(x for x in caps if x["status"] == "failed")
        # the rest of the file arrives
        with open(folder / half.name, "ab") as fh:
            fh.write(data[len(data) // 2 :])
        caps = w.wait(
            lambda c: any(x["entry"] == failed["entry"] and x["status"] == "ok" for x in c),
            "the completed file to be checked again",
        )
    finally:
        err = w.stop()
    again = [x for x in caps if x["entry"] == failed["entry"]]
    assert [x["status"] for x in again] == ["failed", "ok"], again
    assert again[1]["idx"] > again[0]["idx"]
    assert "checking them again" in err, err[-2000:]
    # the report's retake list does not name an entry taken again successfully
    r = subprocess.run([binary(), "report", str(w.session)], capture_output=True, text=True, timeout=120)
    assert r.returncode in (0, 4), r.stderr[-2000:]
    retakes = (w.session / "report" / "retakes.csv").read_text() if (w.session / "report" / "retakes.csv").exists() else ""
    assert half.name not in retakes, retakes
    assert_replay_identical(w.session, tmp_path)


def test_a_sidecar_row_written_before_its_file_is_checked_when_the_file_arrives(tmp_path):
    """Sidecar rows written before their files (which come after `give_up_s`): the captures are
    missing at first and checked once their files arrive."""
    needs_simulator()
    src, _ = write_archive(tmp_path, "early-rows", captures=30, naming="sidecar", id="early-rows")
    folder = tmp_path / "watch-rows"
    folder.mkdir()
    cfg = watch_config(
        tmp_path,
        'sidecar = "captures.csv"\npoll_ms = 100\n',
        give_up_s=1.0,
    )
    w = Watch(cfg, tmp_path / "rows-session", folder)
    late = sorted(p.name for p in src.iterdir() if p.name.startswith("cap_"))[20:]
    try:
        for p in sorted(src.iterdir()):
            if p.name.startswith("cap_") and p.name not in late:
                shutil.copy2(p, folder / p.name)
        shutil.copy2(src / "captures.csv", folder / "captures.csv")
        w.wait(lambda c: sum(x["status"] == "missing" for x in c) >= len(late), "the late rows to be missing", timeout=120)
        for name in late:
            shutil.copy2(src / name, folder / name)
        caps = w.wait(lambda c: sum(x["status"] == "ok" for x in c) >= 30, "every capture checked", timeout=120)
    finally:
        w.stop()
    ok_entries = {x["entry"] for x in caps if x["status"] == "ok"}
    assert len(ok_entries) == 30
    assert_replay_identical(w.session, tmp_path)


def test_file_times_that_step_back_are_alarmed_and_removed_from_the_time_line(tmp_path):
    """Captures ordered by modification time, the clock set back by an hour half-way: watch mode
    raises one `time-stepped-back` alarm at the first capture after the step, and capture times
    go on increasing."""
    needs_simulator()
    src, files = archive_files(tmp_path, "clock", 60)
    folder = tmp_path / "watch-clock"
    folder.mkdir()
    w = Watch(watch_config(tmp_path, 'order = "mtime"\npoll_ms = 100\n'), tmp_path / "clock-session", folder)
    t0 = time.time()
    try:
        staging = tmp_path / "clock-staging"
        staging.mkdir()
        for k, f in enumerate(files):
            # the file appears with its time already set (a rename), as a camera's finished
            # file would: copied in and touched after, a busy machine can let the watcher see
            # the copy's own time first
            shutil.copy(f, staging / f.name)
            t = t0 + 7.0 * k - (3600.0 if k >= 30 else 0.0)
            os.utime(staging / f.name, (t, t))
            os.replace(staging / f.name, folder / f.name)
            if k in (29, 59):
                w.wait(lambda c, n=k + 1: len(c) >= n, f"{k + 1} captures")
    finally:
        w.stop()
    caps = sorted(w.captures(), key=lambda c: c["idx"])
    times = [c["t"] for c in caps]
    assert all(b >= a for a, b in zip(times, times[1:])), times
    steps = [a for a in read_jsonl(w.session / "alarms.jsonl") if a["code"] == "time-stepped-back"]
    assert len(steps) == 1, steps
    assert steps[0]["idx"] == 30 and abs(steps[0]["evidence"]["step_s"] - (3600.0 - 7.0)) < 1.0, steps
    assert "files' modification times" in steps[0]["message"]
    # 7 s between captures on both sides of the step
    assert abs(times[31] - times[30] - 7.0) < 0.01 and abs(times[29] - times[28] - 7.0) < 0.01
    assert_replay_identical(w.session, tmp_path)


def test_a_folder_moved_away_and_made_again_is_watched_anew(tmp_path):
    """File-system events only (a listing every 10 minutes): after the capture folder is moved
    away and a new one made at its path, the files written into the new one are checked."""
    needs_simulator()
    src, files = archive_files(tmp_path, "moved", 30)
    folder = tmp_path / "watch-moved"
    folder.mkdir()
    w = Watch(watch_config(tmp_path, "poll_ms = 600000\n"), tmp_path / "moved-session", folder)
    try:
        time.sleep(0.3)
        for f in files[:15]:
            shutil.copy2(f, folder / f.name)
        w.wait(lambda c: len(c) >= 15, "the first fifteen captures")
        folder.rename(tmp_path / "watch-moved.old")
        folder.mkdir()
        for f in files[:30]:
            shutil.copy2(f, folder / f.name)
        caps = w.wait(lambda c: len(c) >= 30, "the captures written into the new folder", timeout=60)
    finally:
        err = w.stop()
    assert "was replaced" in err, err[-2000:]
    assert len({c["entry"] for c in caps}) == 30


def test_copies_and_rejected_files_do_not_win_over_the_original(tmp_path):
    """An archive with a copy, an upper-case twin and a rejected file beside three originals:
    `check` keeps the originals whatever their names sort as, raises one `duplicate-files`
    alarm per entry naming the others, and watch mode keeps the same files."""
    needs_simulator()
    folder, files = archive_files(tmp_path, "dups", 200)
    a, b, c = files[5], files[6], files[7]
    shutil.copy2(a, folder / (a.stem + " copy.hdr"))
    shutil.copy2(files[40], folder / (b.stem.upper() + ".HDR"))  # another capture's image
    (folder / "rejected").mkdir()
    shutil.copy2(files[41], folder / "rejected" / c.name)
    session = tmp_path / "dups-session"
    code, out, err = run_check(folder, session)
    assert code == 0, err[-2000:]
    dups = [x for x in read_jsonl(session / "alarms.jsonl") if x["code"] == "duplicate-files"]
    assert len(dups) == 1, dups
    groups = dups[0]["evidence"]["groups"]
    assert sorted(g["kept"] for g in groups) == sorted([a.name, b.name, c.name]), groups
    assert all(len(g["others"]) == 1 for g in groups)
    summary = json.loads((session / "summary.json").read_text())
    assert summary["entries_with_duplicates"] == 3, summary
    assert summary["files_skipped"] == {"duplicate": 3}, summary
    assert "duplicates: 3 plan entries" in out, out
    # the report names each file left out and the one checked instead
    r = subprocess.run([binary(), "report", str(session)], capture_output=True, text=True, timeout=120)
    assert r.returncode in (0, 4), r.stderr[-2000:]
    html = (session / "report" / "report.html").read_text()
    assert "Plan entries and files" in html
    for name in (a.stem + " copy.hdr", b.stem.upper() + ".HDR", "rejected/" + c.name):
        assert name in html, name
    kept = {x["file"] for x in read_jsonl(session / "captures.jsonl")}
    assert {a.name, b.name, c.name} <= kept
    assert not any("copy" in k or k.endswith(".HDR") or k.startswith("rejected/") for k in kept)
    assert_replay_identical(session, tmp_path)


def test_a_resumed_check_says_nothing_of_a_serial_link(tmp_path):
    """A check run again on its finished session resumes it: no "serial link is down", and no
    message blames a controller."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "again", captures=120, id="again")
    session = tmp_path / "again-session"
    code, _, err = run_check(folder, session)
    assert code == 0, err[-2000:]
    code, out, err = run_check(folder, session)
    assert code == 0, err[-2000:]
    assert "resuming" in err, err[-2000:]
    assert "serial link" not in err and "port-lost" not in err, err[-2000:]
    alarms = read_jsonl(session / "alarms.jsonl")
    assert not any(a["code"] == "port-lost" for a in alarms), alarms
    assert not any("the controller" in a["message"] for a in alarms), [a["message"] for a in alarms]


def test_the_report_of_a_killed_check_counts_the_captures_it_recorded(tmp_path):
    """A check killed between two writes of summary.json leaves more capture records than the
    summary counts: the report counts the records and says why, rather than a stale count."""
    needs_simulator()
    folder, _ = write_archive(tmp_path, "killed", captures=200, id="killed")
    session = tmp_path / "killed-session"
    code, _, err = run_check(folder, session)
    assert code == 0, err[-2000:]
    # what a kill leaves: the summary as written some captures before the end, not finished
    path = session / "summary.json"
    s = json.loads(path.read_text())
    s["finished"] = False
    s["checked"]["captures"] = 120
    s["checked"]["ok"] = 120
    path.write_text(json.dumps(s))
    out = tmp_path / "killed-report"
    r = subprocess.run([binary(), "report", str(session), "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode in (0, 4), r.stderr[-2000:]
    html = (out / "report.html").read_text()
    assert "200 of 6561 planned captures checked" in html, html[:3000]
    assert "stopped after its summary was last written (120 captures)" in html
    assert "<td>captures checked</td><td>200</td>" in html
