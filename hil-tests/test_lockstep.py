"""The detection lab's fast path (`goniosim lockstep` with `goniowatch lockstep`) against a live
run over the pty, and the regression sessions (hil-tests/regression/*.chk): full-length runs of
the detection matrix through the fast path, each with the outcome it must keep, judged in
captures.

A .chk file names a run of benches/matrix.py and what it must show:
- `expect = "quiet"`: no drift or positioning alarm of warning severity or above in the run;
  with `advisories = [CODE, ...]`, each of those codes raised at least once (what the run could
  not decide, said rather than alarmed);
- `expect = "caught"`: a drift alarm of the fault's sign within `within` captures of the onset,
  none before it; with `rate_within_pct_per_h`, the final rate that close to the truth;
- `expect = "named"`: the first `joint-offset-suspected` (or `wagon-backlash-suspected` or
  `wagon-offset-suspected`, axis 4: the lag as a lag, the offset as an offset) after the onset
  names the fault's axis and sign within `within` captures, none before it;
  with `size_within`, the estimate within that fraction of the truth; with `lamp_quiet = true`,
  no drift alarm and no `lamp-unstable` after the onset either (the lamp is steady);
- `expect = "encoder"`: an `encoder-mismatch` after the onset, and neither a drift nor a joint
  alarm anywhere.
"""

import functools
import glob
import json
import math
import os
import subprocess
import sys
import tomllib

import pytest

from hil import REPO, Rig, binary, needs_simulator, read_jsonl, run_daemon

sys.path.insert(0, os.path.join(REPO, "benches"))
import detection as D  # noqa: E402
import matrix as M  # noqa: E402

COMPARED = ["alarms.jsonl", "captures.jsonl", "sweeps.jsonl", "pairs.jsonl", "isotropy.jsonl", "manifest.jsonl"]


def lockstep(tmp, name, scenario_text, config_path):
    """A session recorded through the fast path; returns its folder."""
    sc = tmp / f"{name}.fast.toml"
    sc.write_text(scenario_text)
    session = tmp / f"{name}-fast"
    r = subprocess.run([sys.executable, "-m", "goniosim", "lockstep", str(sc), "--session", str(session),
                        "--config", str(config_path), "--goniowatch", binary()],
                       cwd=os.path.join(REPO, "sim"), capture_output=True, text=True, timeout=600)
    assert r.returncode in (0, 4), r.stderr[-3000:]
    return session


def test_the_fast_path_gives_a_live_runs_results(hil, tmp_path):
    """A short run with a −5 % lamp step and a +2° slip of joint 2: live over the pty and in
    lockstep, with the same scenario and seed, the result files are byte-identical and the
    summaries equal but for the link counters, and both saw the step and the slip."""
    needs_simulator()
    faults = [{"kind": "lamp-step", "at_capture": 900, "step_pct": -5.0},
              {"kind": "joint-offset", "at_capture": 1700, "joint": 2, "offset_deg": 2.0}]
    rig = hil("equiv", faults, captures=2600)
    config = os.path.join(REPO, "config", "sim.toml")
    live = tmp_path / "equiv-live"
    code, _, err = run_daemon(rig, live, config, timeout=300)
    assert code == 0, err[-2000:]
    text = rig.scenario.read_text().replace(f'capture_root = "{rig.capture_root}"', f'capture_root = "{tmp_path}/fast-cap"')
    assert "fast-cap" in text
    fast = lockstep(tmp_path, "equiv", text, config)
    for name in COMPARED:
        assert (live / name).read_bytes() == (fast / name).read_bytes(), f"{name} differs"
    a, b = (json.loads((d / "summary.json").read_text()) for d in (live, fast))
    a.pop("link"), b.pop("link")
    assert a == b
    codes = [(x["code"], x["idx"]) for x in read_jsonl(fast / "alarms.jsonl")]
    assert any(c in ("gain-step", "gain-drift") and 900 <= i <= 1300 for c, i in codes), codes
    joint = [x for x in read_jsonl(fast / "alarms.jsonl") if x["code"] == "joint-offset-suspected"]
    assert joint and joint[0]["evidence"]["joint"] == 2 and joint[0]["evidence"]["offset_deg"] > 0, joint


def test_a_paused_lockstep_run_ends_instead_of_waiting_forever(tmp_path):
    """The daemon pauses the rig on a critical alarm (pause_on_critical; here five missing
    captures in a row): nothing will resume a lockstep rig, so the run ends there, and the
    session folder is complete and replays."""
    needs_simulator()
    text = open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read()
    config = tmp_path / "pause.toml"
    config.write_text(text.replace("pause_on_critical = false", "pause_on_critical = true")
                      .replace("give_up_s = 30.0", "give_up_s = 0.2"))
    run = M.Run(M.ROWS["no fault"], "walkway", "realistic", 1)
    sc = run.scenario_toml(str(tmp_path / "cap")).replace("seed = 1\n", "seed = 1\ncaptures = 600\n")
    sc += "".join(f'[[faults]]\nkind = "missing-file"\nat_capture = {i}\n' for i in range(200, 205))
    session = lockstep(tmp_path, "pause", sc, config)
    alarms = read_jsonl(session / "alarms.jsonl")
    assert any(a["severity"] == "critical" for a in alarms), alarms
    summary = json.loads((session / "summary.json").read_text())
    assert 205 <= summary["checked"]["captures"] < 600, summary["checked"]
    out = tmp_path / "pause-replay"
    r = subprocess.run([binary(), "replay", str(session), "--out", str(out), "--quiet"], capture_output=True, text=True, timeout=120)
    assert r.returncode in (0, 4), r.stderr
    assert (out / "alarms.jsonl").read_bytes() == (session / "alarms.jsonl").read_bytes()


CHECKS = sorted(glob.glob(os.path.join(REPO, "hil-tests", "regression", "*.chk")))


@functools.cache
def catalogue():
    """`goniowatch alarms --json`, by code."""
    out = subprocess.run([binary(), "alarms", "--json"], capture_output=True, text=True, check=True).stdout
    return {e["code"]: e for e in map(json.loads, out.splitlines())}


@pytest.mark.parametrize("chk", CHECKS, ids=[os.path.basename(p)[:-4] for p in CHECKS])
def test_regression_session(chk, tmp_path):
    needs_simulator()
    with open(chk, "rb") as f:
        want = tomllib.load(f)
    runs = [r for r in M.RUNS if r.id == want["run"]]
    assert runs, f"{chk}: run {want['run']} is not in benches/matrix.py"
    run = runs[0]
    config = tmp_path / "config.toml"
    config.write_text(run.config_toml())
    session = lockstep(tmp_path, "reg", run.scenario_toml(str(tmp_path / "cap")), config)
    rec = D.score(run, str(session))
    # the plan's captures, and the probes and re-captures a probe-taking run asks for besides
    assert rec["captures"] - (rec["probes"] or 0) == M.CAPTURES, rec
    # every alarm raised is in the catalogue, with its kind and one of its severities
    for a in read_jsonl(session / "alarms.jsonl"):
        e = catalogue()[a["code"]]
        assert a["kind"] == e["kind"] and a["severity"] in e["severities"], (a["code"], a["kind"], a["severity"], e)
    t = run.row.truth
    expect = want["expect"]
    if expect == "quiet":
        # no drift or positioning alarm, and the lamp not taken for unstable
        assert rec["drift_after"] is None and rec["positioning_after"] is None and rec["unstable_after"] is None, rec
        raised = {a["code"] for a in read_jsonl(session / "alarms.jsonl")}
        for code in want.get("advisories", []):
            assert code in catalogue(), f"{chk}: {code} is not an alarm code"
            assert code in raised, f"no {code} in the run: {sorted(raised)}"
        return
    assert rec["drift_before"] is None and rec["positioning_before"] is None, f"alarm before the onset: {rec}"
    if expect == "caught":
        a = rec["drift_after"]
        assert a is not None, f"not caught: {rec}"
        assert a["idx"] - t.onset <= want["within"], f"caught {a['idx'] - t.onset} captures after the onset: {a}"
        v = a["level_pct"] if a["level_pct"] is not None else a["rate_pct_per_h"]
        sign = -1 if t.kind in ("rate", "rate-exp") else math.copysign(1, t.size)
        assert v is not None and math.copysign(1, v) == sign, a
        if "rate_within_pct_per_h" in want:
            err = rec["final_rate_pct_per_h"] - D.truth_rate(t.kind, t.size)
            assert abs(err) <= want["rate_within_pct_per_h"], f"final rate off by {err:+.3f} %/h"
    elif expect == "named":
        a = rec["joint_after"]
        assert a is not None, f"not named: {rec}"
        assert a["joint"] == t.axis and a["offset_deg"] * t.size > 0, f"named wrong: {a}"
        if t.axis == 4:
            # the wagon's lag named as a lag, its offset as an offset
            lag = "backlash" in run.row.name
            assert (a["code"] == "wagon-backlash-suspected") == lag, f"the wagon's other fault: {a}"
        assert a["idx"] - t.onset <= want["within"], f"named {a['idx'] - t.onset} captures after the onset"
        if "size_within" in want:
            assert abs(a["offset_deg"] / t.size - 1) <= want["size_within"], a
        if want.get("lamp_quiet"):
            assert rec["drift_after"] is None and rec["unstable_after"] is None, f"the lamp taken for the pose: {rec}"
    elif expect == "encoder":
        assert "encoder-mismatch" in rec["codes_after"], rec
        assert rec["drift_after"] is None and rec["joint_after"] is None, rec
    else:
        raise AssertionError(f"{chk}: unknown expect {expect!r}")
