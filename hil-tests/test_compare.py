"""Cross-validation end to end: a simulated session against the simulator's
Integra-like spectral reference of the same material. A clean session agrees within a small ΔE;
a lamp step shows up in Table 3 and in the worst directions; a known drift divided out brings
the table back."""

import json
import subprocess
import sys

from hil import REPO, binary, daemon_config, needs_simulator, run_daemon


def reference(tmp, name, scenario):
    path = tmp / f"{name}.ref.txt"
    r = subprocess.run(
        [sys.executable, "-m", "goniosim", "reference", str(scenario), "--out", str(path), "--seed", "3"],
        cwd=f"{REPO}/sim",
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    return path


def compare(session, ref, *extra):
    r = subprocess.run([binary(), "compare", str(session), str(ref), "--json", *extra], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(r.stdout)


def test_compare_clean_and_faulty_sessions_against_the_reference(hil, tmp_path):
    needs_simulator()
    cfg = daemon_config(tmp_path, "cmp")
    clean = hil("cmpclean", realism="clean")
    ref = reference(tmp_path, "cmp", clean.scenario)
    session = tmp_path / "cmpclean-session"
    code, out, err = run_daemon(clean, session, cfg, timeout=600)
    assert code == 0, err[-2000:]
    c = compare(session, ref)
    assert c["captures_compared"] > 6000, c["captures_compared"]
    assert c["table3"]["de2000"]["median"] < 0.5, c["table3"]
    assert c["table3"]["de2000"]["avg"] < 1.0, c["table3"]
    assert (session / "crossval.json").exists()
    # the text form names the table and the transform's conditioning
    r = subprocess.run([binary(), "compare", str(session), str(ref)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "Table 3" in r.stdout and "condition number" in r.stdout

    # a −15 % lamp step at capture 3,000: the light directions after it disagree with the
    # reference through the one transform fitted to the whole session
    faulty = hil("cmpstep", [{"kind": "lamp-step", "at_capture": 3000, "step_pct": -15.0}], realism="clean")
    session = tmp_path / "cmpstep-session"
    code, out, err = run_daemon(faulty, session, cfg, timeout=600)
    assert code == 0, err[-2000:]
    f = compare(session, ref)
    assert f["table3"]["de2000"]["median"] > 3 * c["table3"]["de2000"]["median"], (f["table3"], c["table3"])
    assert f["table3"]["de76"]["avg"] > 2 * c["table3"]["de76"]["avg"]

    # an exponential lamp decay of 5 %/h (g = e^(−0.05 t)), divided out with the known rate: the table comes back
    decay = hil("cmpdecay", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 5.0, "model": "exponential"}], realism="clean")
    session = tmp_path / "cmpdecay-session"
    code, out, err = run_daemon(decay, session, cfg, timeout=600)
    assert code == 0, err[-2000:]
    raw = compare(session, ref, "--no-gain-correction")
    assert raw["gain_corrected"] is None
    fixed = compare(session, ref, "--drift-rate", "-5")
    g, t = fixed["gain_corrected"]
    assert g["rate_pct_per_h"] == -5.0 and g["source"] == "command line"
    assert t["de2000"]["median"] < 0.5 < raw["table3"]["de2000"]["median"], (t["de2000"], raw["table3"]["de2000"])


def test_compare_refuses_bad_inputs(tmp_path):
    (tmp_path / "notasession").mkdir()
    bad_ref = tmp_path / "bad.txt"
    bad_ref.write_text("# goniowatch reference BRDF, version 1\nformat = rgb\n10 0 10 180 0.5 0.5\n")
    r = subprocess.run([binary(), "compare", str(tmp_path / "notasession"), str(bad_ref)], capture_output=True, text=True)
    assert r.returncode == 3 and ("not a goniowatch session" in r.stderr or "config.toml" in r.stderr), r.stderr
    r = subprocess.run([binary(), "compare", str(tmp_path), str(bad_ref), "--max-reference-spread-pct", "-1"], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
