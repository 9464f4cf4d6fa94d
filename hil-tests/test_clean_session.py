"""A clean full 6,561-capture session at small resolution, as fast as the simulator goes."""

import os

from hil import REAL_PORT, assert_replay_identical, daemon_config, read_jsonl, run_daemon


def test_clean_full_session(hil, tmp_path):
    rig = hil("clean", realism="clean")
    session = tmp_path / "clean-session"
    cfg = daemon_config(tmp_path, "clean")
    code, out, err = run_daemon(rig, session, cfg, timeout=600)
    assert code == 0, out + err[-3000:]
    caps = read_jsonl(session / "captures.jsonl")
    pairs = read_jsonl(session / "pairs.jsonl")
    alarms = read_jsonl(session / "alarms.jsonl")
    n = 6561 if not REAL_PORT else len(caps)
    assert len(caps) == n and [c["idx"] for c in caps] == list(range(n))
    assert all(c["status"] == "ok" for c in caps)
    if not REAL_PORT:
        # every reciprocal pair of distinct directions is exact; self pairs are not pairs
        exact = [p for p in pairs if p["status"] == "exact"]
        assert len(exact) == 3240
        assert alarms == [], alarms[:5]
        # the clean preset is reciprocal up to noise
        s = __import__("json").load(open(session / "summary.json"))
        assert s["finished"] and s["table2"]["pairs"] == 3240
        assert s["table2"]["de76"] < 0.5, s["table2"]
        assert s["checked"]["isotropy_comparisons"] > 1000
        subs = [c for c in caps if c["substitute"] is not None]
        assert len(subs) == 81
        # every light direction but the first few is tested as a sweep, none is flagged
        sweeps = read_jsonl(session / "sweeps.jsonl")
        assert len(sweeps) >= 70, len(sweeps)
        assert all(abs(j["offset_deg"]) < 0.25 for r in sweeps for j in r["joints"]), sweeps[-1]
    assert "Table 2" in out
    assert_replay_identical(session, tmp_path)
    # run again on the finished session: it resumes, sees it is done, and exits unchanged
    before = open(session / "captures.jsonl", "rb").read()
    code, out, err = run_daemon(rig, session, cfg, timeout=60)
    assert code == 0 and "Table 2" in out, err[-2000:]
    assert open(session / "captures.jsonl", "rb").read() == before


def test_a_second_daemon_on_the_same_session_is_refused(hil, tmp_path):
    import signal
    import time

    from hil import needs_simulator, start_daemon

    needs_simulator()
    rig = hil("busy", captures=400, speed=7.0 / 0.01)
    session = tmp_path / "busy-session"
    cfg = daemon_config(tmp_path, "busy")
    # --keep-running: the first daemon holds the session however long the second takes to start
    first = start_daemon(rig, session, cfg, "--keep-running")
    try:
        deadline = time.monotonic() + 60
        while not os.path.exists(session / "journal.jsonl"):
            assert first.poll() is None and time.monotonic() < deadline, "the first daemon did not start"
            time.sleep(0.05)
        code, out, err = run_daemon(rig, session, cfg, timeout=30)
        assert code == 3 and "in use" in err, (code, err)
        assert first.poll() is None
    finally:
        if first.poll() is None:
            first.send_signal(signal.SIGTERM)
        first.wait(timeout=120)
    assert first.returncode == 128 + 15
