"""Drift and positioning without probes, from the light sweeps: on an isotropic sample
in light-outer order, every completed light direction is compared with the earlier ones. A lamp
step is a `gain-step` from "light sweeps"; an arm joint that slips is a `joint-offset-suspected`
naming that joint; a fault-free run on the realistic preset raises neither. One fixed seed, the
onset part-way through light sweep 25 (θi = 45°), 700 captures after it. Replay gives the same
bytes."""

import json
import math

import pytest

from hil import assert_replay_identical, daemon_config, needs_simulator, read_jsonl, run_daemon

ONSET = 25 * 81 + 40
CAPTURES = ONSET + 700


def run(hil, tmp_path, name, faults):
    needs_simulator()
    rig = hil(name, faults, captures=CAPTURES)
    session = tmp_path / f"{name}-session"
    code, out, err = run_daemon(rig, session, daemon_config(tmp_path, name), timeout=600)
    assert code == 0, err[-2000:]
    alarms = read_jsonl(session / "alarms.jsonl")
    return session, alarms, out


def first(alarms, code):
    return next((a for a in alarms if a["code"] == code), None)


@pytest.mark.parametrize("joint", [1, 2])
def test_a_slipped_joint_is_named(hil, tmp_path, joint):
    session, alarms, out = run(hil, tmp_path, f"slip{joint}", [{"kind": "joint-offset", "at_capture": ONSET, "joint": joint, "offset_deg": 2.0}])
    a = first(alarms, "joint-offset-suspected")
    assert a is not None, [x["code"] for x in alarms]
    assert a["kind"] == "positioning"
    assert a["evidence"]["joint"] == joint, a
    assert 0 < a["evidence"]["offset_deg"] < 3.0, a
    assert ONSET <= a["idx"] <= ONSET + 600, a
    assert f"joint {joint} looks offset" in a["message"]
    # what to do, and every capture since the slip on the retake list
    assert f"arm joint {joint}" in a["action"], a
    assert a["affects"]["scope"] == "since" and a["affects"]["handling"] == "retake", a
    assert a["affects"]["from_idx"] <= ONSET, a
    # the encoders agree with the commands (the slip is after them): no encoder alarm
    assert not [x for x in alarms if x["code"] == "encoder-mismatch"]
    sweeps = read_jsonl(session / "sweeps.jsonl")
    assert sweeps and all(len(r["joints"]) == 2 for r in sweeps if r["idx"] > 1500)
    if joint == 2:
        assert_replay_identical(session, tmp_path)


def test_a_lamp_step_is_a_gain_step_from_the_sweeps(hil, tmp_path):
    session, alarms, out = run(hil, tmp_path, "sweepstep", [{"kind": "lamp-step", "at_capture": ONSET, "step_pct": -3.0}])
    a = first(alarms, "gain-step")
    assert a is not None, [x["code"] for x in alarms]
    assert a["kind"] == "drift" and a["evidence"]["source"] == "light sweeps", a
    assert -4.0 < a["evidence"]["level_pct"] < -1.0, a
    assert ONSET <= a["idx"] <= ONSET + 300, a
    assert a["affects"]["handling"] == "corrected" and a["affects"]["from_idx"] <= ONSET, a
    assert first(alarms, "joint-offset-suspected") is None, alarms
    # the step enters the isotropy drift model, and the corrected output divides it out
    s = json.load(open(session / "summary.json"))
    (step,) = s["isotropy_steps"]
    assert abs(step["ln_size"] - math.log(0.97)) < 0.01 and abs(step["t_h"] * 3600 / 7 - ONSET) < 81, step
    g = read_jsonl(session / "captures.jsonl")[-1]["gain_corrected"]
    assert g["source"] == "isotropy classes" and abs(g["gain"] - 0.97) < 0.01, g
    assert "with a gain step at" in out


def test_a_fault_free_realistic_run_raises_no_drift_or_positioning_alarm(hil, tmp_path):
    session, alarms, out = run(hil, tmp_path, "sweepquiet", [])
    bad = [a for a in alarms if a["kind"] in ("drift", "positioning")]
    assert bad == [], bad
    sweeps = read_jsonl(session / "sweeps.jsonl")
    assert len(sweeps) > 25
    s = json.load(open(session / "summary.json"))
    assert s["sweeps"]["tested"] == len(sweeps) and s["sweeps"]["last"] == sweeps[-1]
    assert "light sweeps: " in out and " tested; the last (light " in out, out


def test_on_a_probe_taking_rig_a_slip_is_named_once_re_captures_confirm_it(hil, tmp_path):
    """With probes, the slip the sweeps name waits for re-captures of earlier poses (four rising
    and four falling with the joint, from a sweep well before it); they show the slip, and the
    alarm says so. The rig is paced (25 ms a capture) so the live daemon keeps up with it."""
    needs_simulator()
    name = "slipconfirm"
    rig = hil(name, [{"kind": "joint-offset", "at_capture": ONSET, "joint": 2, "offset_deg": 2.0}],
              captures=CAPTURES, speed=7.0 / 0.025)
    session = tmp_path / f"{name}-session"
    code, out, err = run_daemon(rig, session, daemon_config(tmp_path, name, every=75), timeout=600)
    assert code == 0, err[-2000:]
    alarms = read_jsonl(session / "alarms.jsonl")
    a = first(alarms, "joint-offset-suspected")
    assert a is not None, [x["code"] for x in alarms]
    assert a["evidence"]["joint"] == 2, a
    r = a["evidence"]["recapture"]
    assert r["status"] == "confirmed", a
    assert len(r["entries"]) == 8 and all(e < ONSET for e in r["entries"]), r
    assert 1.0 < r["offset_deg"] < 3.0 and r["se_deg"] < 0.5, r
    assert "confirmed by a re-capture" in a["message"], a
    assert ONSET <= a["idx"] <= ONSET + 600, a
    assert first(alarms, "slip-refuted") is None, alarms
    # the re-captures were asked for as probes of those entries, after the sweep that named it
    probes = [j["out"] for j in read_jsonl(session / "journal.jsonl") if " PROBE " in j.get("out", "")]
    asked = [int(p.split("entry=")[1].split()[0].split("*")[0]) for p in probes]
    assert set(r["entries"]) <= set(asked), (r["entries"], asked[-12:])
    assert_replay_identical(session, tmp_path)
