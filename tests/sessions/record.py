"""Record the regression corpus of sessions (tests/sessions/<name>/), gpsd-style: each is a real
session of the daemon beside the simulated rig (config, session.json, journal, and for the short
ones their captures), with the live run's result files as the expected output in expected/.
`cargo test --test session_corpus` replays every one and diffs the outputs byte for byte.

    cargo build && python3 tests/sessions/record.py [NAME ...]    (default: all)

Recording replaces the session folder, expected outputs included: do it only to add a session or
when the simulator changes. After an intended change of the checks' output, re-bless instead:

    GONIOWATCH_BLESS=1 cargo test --test session_corpus
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
sys.path.insert(0, str(REPO / "hil-tests"))
import hil  # noqa: E402  (the HIL harness: simulated rig, daemon config, run)

FAST = 7.0 / 0.004  # the simulator's speed: a 7-s capture every 4 ms

# name: (what it exercises, faults, simulator session settings, daemon config overrides,
#        keep the captures (replay re-measures them) or take outcomes as journaled)
SCENARIOS = {
    "clean": (
        "a fault-free run of the first 240 captures (three light sweeps): pairs, isotropy, no alarm",
        [],
        {"captures": 240},
        {},
        True,
    ),
    "capture-faults": (
        "every capture fault of the simulator: NaN and Inf pixels, a saturated block, a dark "
        "frame, a truncated file, a missing file, a slowly written file, a duplicate index",
        [
            {"kind": "nan-pixels", "at_capture": 20, "count": 6},
            {"kind": "inf-pixels", "at_capture": 30, "count": 6},
            {"kind": "saturated-block", "at_capture": 40, "size_px": 6},
            {"kind": "dark-frame", "at_capture": 50},
            {"kind": "truncated-file", "at_capture": 60, "keep_fraction": 0.4},
            {"kind": "missing-file", "at_capture": 70},
            {"kind": "slow-write", "at_capture": 80, "duration_s": 1.0},
            {"kind": "duplicate-index", "at_capture": 90},
        ],
        {"captures": 160, "speed": 7.0 / 0.02},
        {"give_up_s": 3.0},
        True,
    ),
    "link-faults": (
        "every link fault: corrupt bytes, dropped lines, a controller reboot, an unplugged "
        "port, a slow link; resyncs recover every capture",
        [
            {"kind": "corrupt-bytes", "at_capture": 40, "until_capture": 70, "rate": 0.003},
            {"kind": "drop-lines", "at_capture": 90, "until_capture": 110, "rate": 0.3},
            {"kind": "reboot", "at_capture": 140},
            {"kind": "unplug", "at_capture": 190, "duration_s": 1.0},
            {"kind": "slow-link", "at_capture": 230, "until_capture": 250, "baud": 19200},
        ],
        {"captures": 300, "speed": 7.0 / 0.02},
        {},
        True,
    ),
    "malformed-announcement": (
        "an intact CAPTURE line with a bad % escape, live and in every resend: asked for once "
        "more, then skipped with announcement-refused",
        [{"kind": "malformed-announcement", "at_capture": 30}],
        {"captures": 120, "speed": 7.0 / 0.02},
        {},
        True,
    ),
    "kill-9-resume": (
        "the daemon killed with SIGKILL twice and resumed: the journal holds both restarts",
        [],
        {"captures": 300, "speed": 7.0 / 0.02},
        {},
        True,
    ),
    "probe-step": (
        "drift probes every 25 captures and a -3 % lamp step at capture 200: gain-step from "
        "the probes, the probe drift rate",
        [{"kind": "lamp-step", "at_capture": 200, "step_pct": -3.0}],
        {"captures": 400},
        {"every": 25},
        True,
    ),
    "decay": (
        "a 1 %/h lamp decay from the start, no probes: trend-unresolved from the isotropy "
        "classes while the 15° layer's 6 lights cannot tell a drift from a light-side pattern, "
        "gain-drift once the 30° layer's lights can",
        [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 1.0}],
        {"captures": 1500},
        {},
        False,
    ),
    "lamp-step": (
        "a -3 % lamp step at capture 1000 (inside light sweep 13), no probes: gain-step from "
        "the light sweeps, a step term in the drift model",
        [{"kind": "lamp-step", "at_capture": 1000, "step_pct": -3.0}],
        {"captures": 1500},
        {},
        False,
    ),
    "joint-slip": (
        "arm joint 2 slips by +2 deg at capture 2000 (inside light sweep 25), no probes: "
        "joint-offset-suspected naming joint 2 from the light sweeps",
        [{"kind": "joint-offset", "at_capture": 2000, "joint": 2, "offset_deg": 2.0}],
        {"captures": 2300},
        {},
        False,
    ),
    "encoder-offset": (
        "the wagon's encoder reads +0.5 deg off from capture 200 while the wagon goes where it is "
        "told, no probes: one encoder-mismatch episode, the captures placed by the commanded "
        "pose and their pairs in Table 2's by-command subset",
        [{"kind": "encoder-mismatch", "at_capture": 200, "joint": 4, "offset_deg": 0.5}],
        {"captures": 400},
        {},
        False,
    ),
    "joint3-sentinel": (
        "a brushed (anisotropic) sample with drift probes every 25 captures; arm joint 3 turns by "
        "+1 deg at capture 300: the sentinel probe after each lamp probe names joint 3",
        [{"kind": "joint-offset", "at_capture": 300, "joint": 3, "offset_deg": 1.0}],
        {"captures": 500, "preset": "brushed"},
        {"every": 25, "isotropic": False},
        False,
    ),
    "wagon-backlash": (
        "the wagon lags 1 deg behind its direction of motion from capture 1300, drift probes "
        "every 75: the re-captured pair departs, one of its poses re-captured from below and "
        "from above reads the lag, wagon-backlash-suspected from the re-captures",
        [{"kind": "wagon-backlash", "at_capture": 1300, "backlash_deg": 1.0}],
        {"captures": 1700},
        {"every": 75},
        False,
    ),
    "off-centre": (
        "the second nuisance model (realistic-b: a sample mounted off the rotation centre, "
        "vignetting, stray light) under a 1 %/h lamp decay, no probes: sample-off-centre from "
        "the isotropy classes, then gain-drift without false steps",
        [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 1.0}],
        {"captures": 1500, "realism": "realistic-b"},
        {},
        False,
    ),
}

RESULTS = hil.RESULT_FILES  # the result files, summary.json included


def record(name, tmp):
    doc, faults, session, overrides, keep = SCENARIOS[name]
    session = {"speed": FAST, **session}
    rig = hil.Rig(tmp, name, faults, **session)
    try:
        cfg = hil.daemon_config(tmp, name, **overrides)
        folder = tmp / f"{name}-session"
        if name == "kill-9-resume":
            kills = 0
            for stop_at in (80, 160):
                p = hil.start_daemon(rig, folder, cfg)
                while p.poll() is None:
                    caps = folder / "captures.jsonl"
                    if caps.exists() and sum(1 for _ in open(caps)) >= stop_at:
                        p.send_signal(signal.SIGKILL)
                        p.wait()
                        kills += 1
                        break
                    time.sleep(0.01)
            assert kills == 2, "the run ended before both kills"
        code, out, err = hil.run_daemon(rig, folder, cfg, timeout=600)
        if code not in (0, 4):
            raise RuntimeError(f"{name}: daemon exit {code}\n{out}\n{err[-3000:]}")
    finally:
        rig.stop()

    dest = HERE / name
    shutil.rmtree(dest, ignore_errors=True)
    (dest / "expected").mkdir(parents=True)
    for f in ("config.toml", "journal.jsonl"):
        shutil.copy(folder / f, dest / f)
    info = json.load(open(folder / "session.json"))
    # paths of the recording machine mean nothing here; the test names the captures itself
    info.update({"capture_root": "captures", "port": "/dev/null", "config_source": "config.toml"})
    (dest / "session.json").write_text(json.dumps(info, indent=2) + "\n")
    for f in RESULTS:
        shutil.copy(folder / f, dest / "expected" / f)
    if keep:
        src = Path(rig.capture_root) / rig.session_id
        shutil.copytree(src, dest / "captures" / rig.session_id, ignore=shutil.ignore_patterns(".*"))
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    summary = json.load(open(folder / "summary.json"))
    lines = [
        f"# {name}",
        "",
        doc[0].upper() + doc[1:] + ".",
        "",
        f"- simulator: {session.get('preset', 'walkway')}, realistic preset, seed 7, 16 x 16 images, {session['captures']} captures; faults: "
        + (json.dumps(faults) if faults else "none"),
        "- daemon config: config/sim.toml" + (f" with {json.dumps(overrides)}" if overrides else ""),
        "- captures: " + ("kept (replay measures them again)" if keep else "not kept (replay takes the journaled outcomes: `replay --recorded-outcomes`)"),
        f"- recorded with goniowatch at {commit} by `python3 tests/sessions/record.py {name}`",
        f"- summary: {summary['checked']['captures']} captures checked, alarms {json.dumps(summary['alarms'])}",
    ]
    (dest / "PROVENANCE.md").write_text("\n".join(lines) + "\n")
    return summary


def main():
    names = sys.argv[1:] or list(SCENARIOS)
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        sys.exit(f"unknown session(s) {unknown}; known: {list(SCENARIOS)}")
    os.environ.setdefault("GONIOWATCH_BIN", hil.binary())
    for n in names:
        with tempfile.TemporaryDirectory(prefix="gw-corpus-") as tmp:
            s = record(n, Path(tmp))
            print(f"{n}: {s['checked']['captures']} checked, alarms {s['alarms']}")


if __name__ == "__main__":
    main()
