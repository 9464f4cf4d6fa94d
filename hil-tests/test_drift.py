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


def test_a_lamp_colour_drift_is_caught_in_kelvin_per_hour_and_divided_out(hil, tmp_path):
    """A 3000 K lamp cooling by 40 K/h (Planck's law through the simulator's spectral path) on the
    realistic walkway: one colour-drift alarm with the rate in K/h, no gain alarm (the luminance
    is kept), the corrected output's chromaticity back near the start's."""
    needs_simulator()
    rig = hil("isocolour", [{"kind": "lamp-colour-drift", "at_capture": 0, "cct_k_per_h": -40.0}], captures=2500)
    session = tmp_path / "isocolour-session"
    code, out, err = run_daemon(rig, session, daemon_config(tmp_path, "isocolour"), timeout=300)
    assert code == 0, err[-2000:]
    alarms = read_jsonl(session / "alarms.jsonl")
    colour = [a for a in alarms if a["code"] == "colour-drift"]
    assert len(colour) == 1, alarms
    ev = colour[0]["evidence"]
    assert ev["source"] == "isotropy classes" and -50.0 < ev["k_per_h"] < -30.0, ev
    assert "K/h" in colour[0]["message"] and "redder" in colour[0]["message"]
    assert not [a for a in alarms if a["code"] in ("gain-drift", "gain-step")], alarms
    s = json.load(open(session / "summary.json"))
    c = s["colour_drift"]
    assert abs(c["k_per_h"] + 40.0) < 10.0 and c["de00_per_h"] > 0, c
    assert c["source"] == "isotropy classes" and "lamp colour drift from isotropy classes" in out
    # the chromaticity change divided out of the last capture is the lamp's, within 25 %: the
    # truth's colour temperature through the simulator's own lamp model, for a white
    import math

    import numpy as np
    from goniosim.spectral import M, lamp_colour_matrix  # hil puts sim/ on the path

    last = read_jsonl(session / "captures.jsonl")[-1]
    cct = rig.truth()[last["idx"]]["lamp_cct_k"]
    x, y, z = M @ lamp_colour_matrix(cct) @ np.ones(3)
    x0, y0, z0 = M @ np.ones(3)
    want = (math.log(x / y) - math.log(x0 / y0), math.log(z / y) - math.log(z0 / y0))
    got = last["gain_corrected"]["colour"]
    for g, w in zip(got, want):
        assert abs(g - w) < 0.25 * abs(w) + 0.002, (got, want, cct)
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
    assert "colour_drift" not in s
    # said at the start, in the summary and in its printout: nothing watches the lamp, and how to
    # make it watched
    blind = {b["what"]: b for b in s["observability"]["blind"]}
    assert "[probes] every" in blind["the lamp's gain drift (rate and steps)"]["remedy"], blind
    assert "the lamp's colour drift" in blind
    assert "not observable in this session: the lamp's gain drift" in err
    assert "not observable: the lamp's gain drift" in out
