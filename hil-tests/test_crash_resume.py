"""kill -9 of the daemon at random points and restart: the final results equal those of an
uninterrupted run; and the replay of the resumed session is byte-identical to it."""

import json
import random
import signal
import time

import pytest
from hil import assert_replay_identical, daemon_config, needs_simulator, read_jsonl, run_daemon, start_daemon

N = 700
SPEED = 7.0 / 0.008  # 8 ms per capture: about 5.6 s for the run


def results(session):
    out = {name: read_jsonl(session / name) for name in ("captures.jsonl", "pairs.jsonl", "isotropy.jsonl", "manifest.jsonl")}
    out["alarms (not link)"] = [a for a in read_jsonl(session / "alarms.jsonl") if a["kind"] != "link"]
    return out


def wait_for_checked(p, session, at_least, timeout=60):
    """Until the daemon `p` has written at least `at_least` capture results (or exited): the
    kill points are chosen in captures checked, which the daemon controls, not in wall time."""
    path = session / "captures.jsonl"
    deadline = time.monotonic() + timeout
    while p.poll() is None and time.monotonic() < deadline:
        if path.exists() and sum(1 for _ in open(path, "rb")) >= at_least:
            return
        time.sleep(0.01)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The same scenario (same seed, same files), uninterrupted."""
    from hil import Rig

    needs_simulator()
    tmp = tmp_path_factory.mktemp("ref")
    rig = Rig(tmp, "crash", (), captures=N, speed=0, realism="realistic", preset="ceiling")
    try:
        session = tmp / "ref-session"
        code, out, err = run_daemon(rig, session, daemon_config(tmp, "ref"), timeout=180)
        assert code == 0, err[-2000:]
        return results(session)
    finally:
        rig.stop()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_kill_9_and_resume(hil, tmp_path, reference, seed):
    rng = random.Random(seed)
    rig = hil("crash", (), captures=N, speed=SPEED, realism="realistic", preset="ceiling")
    session = tmp_path / "crash-session"
    cfg = daemon_config(tmp_path, "crash")
    kills, at = 0, 0
    for _ in range(rng.randint(1, 3)):
        p = start_daemon(rig, session, cfg)
        at += rng.randint(20, 200)
        wait_for_checked(p, session, at)
        if p.poll() is None:
            p.send_signal(signal.SIGKILL)
            p.wait()
            kills += 1
    code, out, err = run_daemon(rig, session, cfg, timeout=180)
    assert code == 0, err[-3000:]
    assert kills >= 1
    got = results(session)
    for name, rows in reference.items():
        assert got[name] == rows, f"{name} differs after {kills} kill(s)"
    s = json.load(open(session / "summary.json"))
    assert s["finished"] and s["link"]["restarts"] == kills
    assert_replay_identical(session, tmp_path)


def test_sigterm_stops_cleanly_and_resumes(hil, tmp_path, reference):
    rig = hil("crash", (), captures=N, speed=SPEED, realism="realistic", preset="ceiling")
    session = tmp_path / "term-session"
    cfg = daemon_config(tmp_path, "term")
    p = start_daemon(rig, session, cfg)
    wait_for_checked(p, session, 150)
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=30)
    assert p.returncode == 128 + 15, (p.returncode, err[-2000:])
    summary = json.load(open(session / "summary.json"))
    assert not summary["finished"]
    code, out, err = run_daemon(rig, session, cfg, timeout=180)
    assert code == 0, err[-2000:]
    assert results(session) == reference
