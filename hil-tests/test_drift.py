"""Gain drift without probes (the isotropy path): on an isotropic sample every capture is
compared with the first capture of the same geometry; a lamp decay raises a rate alarm naming
that source, the summary carries the rate, and every later capture carries its colour with the
drift divided out. Replay gives the same bytes."""

import json

from hil import assert_replay_identical, daemon_config, needs_simulator, read_jsonl, run_daemon


def test_a_lamp_decay_is_caught_from_isotropy_classes(hil, tmp_path):
    needs_simulator()
    rig = hil("isodecay", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 2.0, "model": "exponential"}], captures=2500)
    session = tmp_path / "isodecay-session"
    code, out, err = run_daemon(rig, session, daemon_config(tmp_path, "isodecay"), timeout=300)
    assert code == 0, err[-2000:]
    alarms = [a for a in read_jsonl(session / "alarms.jsonl") if a["code"] == "gain-drift"]
    assert len(alarms) == 1 and alarms[0]["evidence"]["source"] == "isotropy classes", alarms
    assert alarms[0]["evidence"]["rate_pct_per_h"] < -1.5
    s = json.load(open(session / "summary.json"))
    assert abs(s["isotropy_drift"]["rate_pct_per_h"] + 2.0) < 0.15, s["isotropy_drift"]
    assert "gain drift from isotropy classes" in out
    caps = read_jsonl(session / "captures.jsonl")
    last = caps[-1]
    g = last["gain_corrected"]
    assert g["source"] == "isotropy classes" and g["gain"] < 1.0 and g["sigma_rel"] < 0.01
    assert abs(g["xyz"][1] * g["gain"] - last["xyz"][1]) < 1e-9 * last["xyz"][1]
    assert_replay_identical(session, tmp_path)


def test_an_anisotropic_sample_has_no_isotropy_drift(hil, tmp_path):
    needs_simulator()
    import re

    rig = hil("aniso", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 2.0}], captures=1500)
    cfg = daemon_config(tmp_path, "aniso")
    cfg.write_text(re.sub(r"(?m)^isotropic = true$", "isotropic = false", cfg.read_text()))
    session = tmp_path / "aniso-session"
    code, out, err = run_daemon(rig, session, cfg, timeout=300)
    assert code == 0, err[-2000:]
    s = json.load(open(session / "summary.json"))
    assert s["isotropy_drift"] is None and s["checked"]["isotropy_comparisons"] == 0
    assert not (session / "isotropy.jsonl").read_text().strip()
    assert all("gain_corrected" not in c for c in read_jsonl(session / "captures.jsonl"))
