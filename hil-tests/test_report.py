"""`goniowatch report`: the end-of-run HTML report and its CSV tables, on a simulated session with
probes, a lamp step, a dark frame and a cross-validation; the report of the replayed session is
byte-identical to the live one's."""

import csv
import io
import subprocess
import sys

from hil import REPO, binary, daemon_config, needs_simulator, read_jsonl, run_daemon


def run(*args, timeout=120):
    r = subprocess.run([binary(), *map(str, args)], capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_report_of_a_session_and_of_its_replay_are_identical(hil, tmp_path):
    needs_simulator()
    faults = [
        {"kind": "lamp-step", "at_capture": 700, "step_pct": -3.0},
        {"kind": "dark-frame", "at_capture": 300},
    ]
    # paced (10 ms per capture): with probes on, the step is seen only at a probe after it, and
    # a rig running flat out could end before a lagging daemon's rounds are taken
    rig = hil("rep", faults, captures=1400, speed=7.0 / 0.01)
    session = tmp_path / "rep-session"
    code, out, err = run_daemon(rig, session, daemon_config(tmp_path, "rep", every=50), timeout=300)
    assert code == 0, err[-2000:]
    ref = tmp_path / "rep.ref"
    r = subprocess.run([sys.executable, "-m", "goniosim", "reference", str(rig.scenario), "--out", str(ref)], cwd=f"{REPO}/sim", capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    run("compare", session, ref)
    listed = run("report", session).split()
    assert listed[0].endswith("report.html") and len(listed) == 9, listed  # + sweeps.csv, table3.csv

    html = (session / "report" / "report.html").read_text()
    for needle in ["Table 2", "Table 3", "Residual per light direction", "Gain drift", "Capture quality", "Link", "Configuration",
                   "dark-capture", "gain-step", "<svg", "[probes]", "Light sweeps", "Retake list"]:
        assert needle in html, needle
    # the sweeps' levels against their layer's prediction, one point per sweep, on the time axis
    # with the alarms
    assert html.count("against the layer's prediction") == len(read_jsonl(session / "sweeps.jsonl"))
    assert "level − layer's prediction [%]" in html
    # self-contained: nothing loaded from anywhere
    assert "http://" not in html.replace('xmlns="http://www.w3.org/2000/svg"', "") and "<script" not in html
    assert str(tmp_path) not in html, "the report must not depend on where the session lives"

    caps = list(csv.DictReader(io.StringIO((session / "report" / "captures.csv").read_text())))
    assert len(caps) == len(read_jsonl(session / "captures.jsonl"))
    assert {"idx", "X", "Y", "Z", "theta_i", "pose_error_deg", "by_command"} <= set(caps[0])
    alarms = list(csv.DictReader(io.StringIO((session / "report" / "alarms.csv").read_text())))
    assert any(a["code"] == "dark-capture" and a["idx"] == "300" for a in alarms)
    t3 = list(csv.DictReader(io.StringIO((session / "report" / "table3.csv").read_text())))
    assert {r["table"] for r in t3} == {"as measured", "gain-corrected"}
    # the dark frame is the one capture to take again (the lamp step is corrected, not retaken)
    retakes = list(csv.DictReader(io.StringIO((session / "report" / "retakes.csv").read_text())))
    assert [(r["idx"], r["why"]) for r in retakes] == [("300", "dark capture")], retakes
    sweeps = list(csv.DictReader(io.StringIO((session / "report" / "sweeps.csv").read_text())))
    assert len(sweeps) == len(read_jsonl(session / "sweeps.jsonl")) > 10
    assert {"light", "level_pct", "joint1_offset_deg", "joint2_se_deg"} <= set(sweeps[0])

    # the replayed session's report equals the live one's
    replayed = tmp_path / "rep-replay"
    run("replay", session, "--out", replayed, "--quiet", timeout=300)
    run("compare", replayed, ref)
    run("report", replayed)
    for name in ["report.html", "captures.csv", "pairs.csv", "alarms.csv", "table2.csv", "light_residuals.csv", "retakes.csv", "sweeps.csv", "table3.csv"]:
        assert (session / "report" / name).read_bytes() == (replayed / "report" / name).read_bytes(), name


def test_report_refuses_a_folder_that_is_not_a_session(tmp_path):
    r = subprocess.run([binary(), "report", str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 3 and "config.toml" in r.stderr, r.stderr
