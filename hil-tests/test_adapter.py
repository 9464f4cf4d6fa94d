"""The lab adapter (sim/adapter/rig_adapter.py) between a rig's own acquisition software and
`goniowatch run`: the 'lab' appends one log line per capture (files written beforehand by
`goniosim archive`), the adapter follows the log and speaks docs/protocol.md on its pty. A clean
run checks every capture; a daemon killed mid-run and restarted resumes through RESYNC."""

import json
import os
import signal
import subprocess
import sys
import threading
import time

import pytest
from hil import REPO, daemon_config, needs_simulator, read_jsonl, run_daemon, start_daemon, write_archive

ADAPTER = os.path.join(REPO, "sim", "adapter", "rig_adapter.py")
N = 486  # the first 6 light directions × 81 cameras of the light-outer plan
UNIX = 1_700_000_000.0  # the lab logs Unix times; the adapter makes them session-relative


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    """The capture files of N plan entries, and their truth (the lab's knowledge of each)."""
    needs_simulator()
    tmp = tmp_path_factory.mktemp("lab")
    folder, _ = write_archive(tmp, "lab", naming="bonn", captures=N, realism="clean")
    truth = read_jsonl(tmp / "lab-cap" / "lab.truth.jsonl")
    return folder.parent, sorted(truth, key=lambda r: r["idx"])


def expected_pairs(truth):
    """Reciprocal pairs of distinct directions among the captured entries, from the plan."""
    sys.path.insert(0, os.path.join(REPO, "sim"))
    from goniosim.geometry import Plan

    plan = Plan()  # config/sim.toml's plan is the UBO default
    taken = {plan.entry(r["entry"]) for r in truth}
    return sum(1 for (i, j) in taken if i < j and (j, i) in taken)


def lab_software(log, truth, delay, done=True):
    """The acquisition software: a log line per capture (after a logger's prefix), then RUN-DONE."""
    with open(log, "a", encoding="utf-8") as f:
        for r in truth:
            q = " ".join(f"{v:.4f}" for v in r["cmd"])
            sub = f" sub={r['substitute_theta_i']:.4f}" if r["substitute_theta_i"] is not None else ""
            f.write(f"2024-05-01 12:00:00 INFO acq: CAPTURE {r['idx']} {r['file']} {q} t={UNIX + r['t']:.3f} entry={r['entry']}{sub}\n")
            f.flush()
            time.sleep(delay)
        if done:
            f.write("2024-05-01 12:00:01 INFO acq: RUN-DONE\n")


class Adapter:
    def __init__(self, tmp, root):
        self.port, self.capture_root, self.log = str(tmp / "lab.port"), str(root), tmp / "acq.log"
        self.err = open(tmp / "adapter.err", "w")
        self.proc = subprocess.Popen(
            [sys.executable, ADAPTER, "--port", self.port, "--follow", str(self.log), "--session", "lab", "--captures", str(N)],
            stdout=self.err, stderr=subprocess.STDOUT,
        )
        deadline = time.monotonic() + 10
        while not os.path.lexists(self.port):
            assert self.proc.poll() is None and time.monotonic() < deadline, (tmp / "adapter.err").read_text()
            time.sleep(0.02)

    def lab(self, truth, delay):
        t = threading.Thread(target=lab_software, args=(self.log, truth, delay), daemon=True)
        t.start()
        return t

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        code = self.proc.wait(timeout=10)
        self.err.close()
        return code


@pytest.fixture
def adapter(tmp_path, captures):
    a = Adapter(tmp_path, captures[0])
    yield a
    a.stop()


def assert_complete(session, truth):
    caps = read_jsonl(session / "captures.jsonl")
    assert [c["idx"] for c in caps] == list(range(N)), len(caps)
    assert all(c["status"] == "ok" for c in caps), [c for c in caps if c["status"] != "ok"][:3]
    assert [c["entry"] for c in caps] == [r["entry"] for r in truth]
    s = json.load(open(session / "summary.json"))
    n = expected_pairs(truth)
    assert n == 15 and s["finished"] and s["table2"]["pairs"] == n, s["table2"]
    assert len([p for p in read_jsonl(session / "pairs.jsonl") if p["status"] == "exact"]) == n
    return s


def test_a_lab_log_drives_a_full_check(adapter, captures, tmp_path):
    _, truth = captures
    lab = adapter.lab(truth, delay=0.004)
    time.sleep(0.3)  # the daemon arrives late: what came before reaches it by RESYNC
    session = tmp_path / "session"
    code, out, err = run_daemon(adapter, session, daemon_config(tmp_path, "lab"), 60)
    assert code == 0, err[-3000:]
    lab.join()
    assert_complete(session, truth)
    alarms = read_jsonl(session / "alarms.jsonl")
    assert not [a for a in alarms if a["kind"] == "link"], alarms
    # the adapter ends cleanly on SIGTERM and takes its port name with it
    assert adapter.stop() == 0 and not os.path.lexists(adapter.port)


def test_a_daemon_killed_mid_run_resumes_by_resync(adapter, captures, tmp_path):
    _, truth = captures
    lab = adapter.lab(truth, delay=0.006)
    session, cfg = tmp_path / "session", daemon_config(tmp_path, "lab")
    p = start_daemon(adapter, session, cfg)
    deadline = time.monotonic() + 30
    while not (session / "captures.jsonl").exists() or sum(1 for _ in open(session / "captures.jsonl", "rb")) < 100:
        assert p.poll() is None and time.monotonic() < deadline, p.communicate()[1][-2000:]
        time.sleep(0.01)
    p.send_signal(signal.SIGKILL)
    p.wait()
    checked = sum(1 for _ in open(session / "captures.jsonl", "rb"))
    assert checked < N
    time.sleep(0.5)  # the lab goes on while nobody listens
    code, out, err = run_daemon(adapter, session, cfg, 60)
    assert code == 0, err[-3000:]
    lab.join()
    s = assert_complete(session, truth)
    assert s["link"]["restarts"] == 1, s["link"]
    # the restart is noted, nothing on the link went wrong
    link = [a["code"] for a in read_jsonl(session / "alarms.jsonl") if a["kind"] == "link"]
    assert set(link) <= {"daemon-restart", "port-back"}, link
    # the restarted daemon asked from where it stopped, and the adapter replayed the rest
    sent = [j["out"] for j in read_jsonl(session / "journal.jsonl") if " RESYNC " in j.get("out", "")]
    assert any(int(line.split("from=")[1].split("*")[0]) >= checked for line in sent), sent
