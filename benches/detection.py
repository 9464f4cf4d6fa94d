"""Detection benchmark: full 6,561-capture simulated runs, several seeds per scenario.
With `--every N` the daemon asks for a drift probe every N captures (the probe path); with
`--every 0` there are no probes and the drift comes from isotropy classes only. Reports the alarm
rate on fault-free runs, the detection delay after onset (captures and hours), the final
drift-rate estimate of that path against the truth, and the daemon's CPU time per capture (all
of it: link, decoding, checks).

Run (after `cargo build --release`):
  python3 benches/detection.py [--seeds 3] [--first-seed 1] [--every 100] [--presets realistic,clean]
                               [--materials walkway,ceiling] [--only "no fault"] [--keep DIR]
  python3 benches/detection.py --replay DIR[,DIR...] [--replay-out OUT] [--seeds ...] [--presets ...] [--materials ...] [--only ...]
Prints a Markdown table. GONIOWATCH_BIN overrides the binary. `--keep DIR` keeps every recorded
session (DIR/<scenario>[-<material>]-<preset>-<seed>/s, with its captures); `--replay DIR` re-evaluates kept
sessions with the current binary through `goniowatch replay` (byte-identical to a live run of
that binary on the same rig data), in seconds per session instead of a minute: the way to
re-measure detection after a change to the checks. With `--replay` the CPU column is the
replay's (decoding included) per capture. `--jobs N` runs or replays N sessions at once (each run's CPU is its own; keep N at or
below the cores: a live run's link has wall-clock timeouts); `--json FILE` writes one record per
run for `benches/detection_curves.py`."""

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("GONIOWATCH_BIN") or os.path.join(REPO, "target", "release", "goniowatch")
T_CAPTURE_H = 7.0 / 3600.0

SCENARIOS = [
    ("no fault", [], None),
    ("decay 0.5 %/h", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 0.5}], ("rate", 0, 0.5)),
    ("decay 1 %/h", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 1.0}], ("rate", 0, 1.0)),
    # an exponential decay g = exp(−r·t): its ln-gain slope is −r at every time
    ("exponential decay 0.5 %/h", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 0.5, "model": "exponential"}], ("rate-exp", 0, 0.5)),
    ("exponential decay 1 %/h", [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 1.0, "model": "exponential"}], ("rate-exp", 0, 1.0)),
    ("step −2 % at mid-run", [{"kind": "lamp-step", "at_capture": 3280, "step_pct": -2.0}], ("step", 3280, None)),
    ("step −3 % at mid-run", [{"kind": "lamp-step", "at_capture": 3280, "step_pct": -3.0}], ("step", 3280, None)),
    ("step −1.5 % at mid-run", [{"kind": "lamp-step", "at_capture": 3280, "step_pct": -1.5}], ("step", 3280, None)),
    # light sweep 40 starts at capture 3,240; the θi = 75° layer holds lights 57–80 (captures 4,617 on)
    ("step −1.5 % at a sweep boundary", [{"kind": "lamp-step", "at_capture": 3240, "step_pct": -1.5}], ("step", 3240, None)),
    ("step −1.5 % early in the 75° layer", [{"kind": "lamp-step", "at_capture": 5200, "step_pct": -1.5}], ("step", 5200, None)),
    ("step −3 % early in the 75° layer", [{"kind": "lamp-step", "at_capture": 5200, "step_pct": -3.0}], ("step", 5200, None)),
    ("step −1.5 % late in the 75° layer", [{"kind": "lamp-step", "at_capture": 5900, "step_pct": -1.5}], ("step", 5900, None)),
] + [
    # the other sign (a lamp that brightens: a supply or a warm-up), and an early onset
    # (light sweep 20, θi = 45°)
    (f"step {'+' if size > 0 else '−'}{abs(size):g} % {where}", [{"kind": "lamp-step", "at_capture": at, "step_pct": size}], ("step", at, None))
    for size, where, at in ((1.5, "at mid-run", 3280), (3.0, "at mid-run", 3280), (-1.5, "early", 1700), (1.5, "early", 1700),
                            (-3.0, "early", 1700), (1.5, "early in the 75° layer", 5200))
] + [
    # a lamp decay with a joint slip part-way: the rate must survive the slip
    (f"decay 0.5 %/h with joint {j} +1° at mid-run",
     [{"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 0.5}, {"kind": "joint-offset", "at_capture": 3280, "joint": j, "offset_deg": 1.0}],
     ("rate", 0, 0.5))
    for j in (1, 2)
] + [
    # an encoder reading off while the arm goes where it is told: one episode, no drift or
    # joint alarm, and the pairs kept exact by the commanded pose (joint 4 is the wagon)
    (f"encoder {n} +{o}° at mid-run", [{"kind": "encoder-mismatch", "at_capture": 3280, "joint": j, "offset_deg": o}], ("encoder", 3280, j))
    for n, j, o in (("joint 1", 1, 0.3), ("joint 2", 2, 0.3), ("wagon", 4, 0.5))
] + [
    (f"joint {j} +{o}° at mid-run", [{"kind": "joint-offset", "at_capture": 3280, "joint": j, "offset_deg": float(o)}], ("joint", 3280, j))
    for j in (1, 2, 3) for o in (1, 2)
] + [
    # both signs at three onsets: early (light sweep 20, θi = 45°), mid-run, and in the θi = 75° layer
    (f"joint {j} {'+' if o > 0 else '−'}1° {where}", [{"kind": "joint-offset", "at_capture": at, "joint": j, "offset_deg": float(o)}], ("joint", at, j))
    for j in (1, 2) for o in (1, -1) for where, at in (("early", 1700), ("at mid-run", 3280), ("late in the 75° layer", 5200))
    if (o, at) != (1, 3280)
] + [
    # the wagon (axis 4): an offset of either sign, and backlash, at the same three onsets
    (f"wagon {name} {where}", [dict(fault, at_capture=at)], ("joint", at, 4))
    for name, fault in (("+1°", {"kind": "wagon-offset", "offset_deg": 1.0}),
                        ("−1°", {"kind": "wagon-offset", "offset_deg": -1.0}),
                        ("backlash 1°", {"kind": "wagon-backlash", "backlash_deg": 1.0}))
    for where, at in (("early", 1700), ("at mid-run", 3280), ("late in the 75° layer", 5200))
]


def fault_size(faults):
    """The positioning fault's size in degrees: a joint's or the wagon's offset, or the wagon's
    backlash (its lag against the direction of motion)."""
    f = next(f for f in faults if f["kind"] in ("joint-offset", "wagon-offset", "wagon-backlash"))
    return f.get("offset_deg", f.get("backlash_deg"))


CURVE_H = [1, 2, 3, 4, 6, 8, 10, 12]
RUN_H = 12.76


def truth_rate(form, rate_pct_per_h, hours=RUN_H):
    """The ln-gain slope (%/h) a decay of `rate_pct_per_h` has over [0, hours]: −r for an
    exponential decay (`rate-exp`), the mean slope of ln(1 − r·t) for a linear one."""
    if form == "rate-exp":
        return -rate_pct_per_h
    return 100 * math.log(1 - rate_pct_per_h / 100 * hours) / hours


def curve(captures_path):
    """The isotropy drift estimate at hours into the run: each capture's gain correction
    (g = exp(r·t) from the rate known at its time) gives r = ln g / t and its SE = σ_rel / t."""
    pts = {}
    for line in open(captures_path):
        c = json.loads(line)
        g = c.get("gain_corrected")
        t_h = c["t"] / 3600.0
        if not g or g.get("source") != "isotropy classes" or t_h <= 0 or c.get("probe"):
            continue
        for h in CURVE_H:
            if t_h <= h:
                pts[h] = (100 * math.log(g["gain"]) / t_h, 100 * g["sigma_rel"] / t_h)
    return pts


def slug(name):
    # a negative angle is spelt out so that both signs of a joint offset keep their own folder
    name = re.sub(r"−(?=[0-9.]+°)", "minus ", name)
    # and a lamp that brightens keeps its own from one that dims
    name = re.sub(r"\+(?=[0-9.]+ %)", "plus ", name)
    return re.sub(r"[^a-z0-9.]+", "-", name.lower()).strip("-")


def run_name(name, material, preset, seed):
    """The kept session's folder name (walkway runs keep the name they had before materials)."""
    m = "" if material == "walkway" else f"{material}-"
    return f"{slug(name)}-{m}{preset}-{seed}"


def replay(keeps, name, material, preset, seed, replay_out=None):
    """Replays the kept session of this run (the first of the folders `keeps` that has it) and
    scores it. With `replay_out` the replay's output is kept in replay_out/<run>, and a run
    whose output is already there is scored from it without replaying (its CPU is then
    unknown: None)."""
    run = run_name(name, material, preset, seed)
    d = next((os.path.join(k, run) for k in keeps if os.path.isdir(os.path.join(k, run, "s"))), None)
    if d is None:
        return None
    out = os.path.join(replay_out, run) if replay_out else os.path.join(tempfile.mkdtemp(prefix="gw-replay-"), "r")
    cpu = None
    if not (replay_out and os.path.exists(f"{out}/summary.json")):
        shutil.rmtree(out, ignore_errors=True)
        _, cpu = timed([BIN, "replay", f"{d}/s", "--out", out, "--quiet"])
    alarms = [json.loads(l) for l in open(f"{out}/alarms.jsonl") if l.strip()]
    summary = json.load(open(f"{out}/summary.json"))
    pts = curve(f"{out}/captures.jsonl")
    if not replay_out:
        shutil.rmtree(os.path.dirname(out), ignore_errors=True)
    return alarms, summary, cpu, pts


def run(tmp, name, material, preset, faults, seed, every, keep=None, config="sim.toml"):
    d = os.path.join(keep or tmp, run_name(name, material, preset, seed))
    if keep:
        shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    sc = os.path.join(d, "sc.toml")
    lines = [f'rig_config = "{REPO}/config/sim.toml"', "[session]", f'id = "r"', f'capture_root = "{d}/cap"',
             f'port = "{d}/port"', "image_size = [16, 16]", "speed = 0", f"seed = {seed}",
             "[material]", f'preset = "{material}"', f'realism = "{preset}"']
    for f in faults:
        lines.append("[[faults]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in f.items()]
    open(sc, "w").write("\n".join(lines) + "\n")
    cfg = os.path.join(d, "cfg.toml")
    text = open(os.path.join(REPO, "config", config)).read()
    open(cfg, "w").write(re.sub(r"(?m)^every = 0$", f"every = {every}", text))
    sim = subprocess.Popen([sys.executable, "-m", "goniosim", "run", sc, "--linger", "60"], cwd=os.path.join(REPO, "sim"),
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while not os.path.exists(f"{d}/port"):
            if sim.poll() is not None:
                raise RuntimeError(f"the simulator exited ({sim.returncode}) before opening its port: is `pip install -r sim/requirements.txt` done?")
            time.sleep(0.05)
        _, daemon_cpu = timed([BIN, "run", "--config", cfg, "--session", f"{d}/s", "--port", f"{d}/port",
                               "--capture-root", f"{d}/cap", "--quiet"])
    finally:
        sim.terminate()
        sim.wait()
    alarms = [json.loads(l) for l in open(f"{d}/s/alarms.jsonl") if l.strip()]
    summary = json.load(open(f"{d}/s/summary.json"))
    pts = curve(f"{d}/s/captures.jsonl")
    if not keep:
        shutil.rmtree(d, ignore_errors=True)
    return alarms, summary, daemon_cpu, pts


def timed(cmd, timeout=900):
    """Runs `cmd` (its output discarded) and returns its exit code and the CPU seconds it and its
    own children used (from wait4 on it alone, so that runs in parallel keep their own times)."""
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    while True:
        pid, status, ru = os.wait4(p.pid, os.WNOHANG)
        if pid == p.pid:
            break
        if time.monotonic() > deadline:
            p.kill()
            os.wait4(p.pid, 0)
            p.returncode = -9
            raise TimeoutError(f"{' '.join(cmd[:3])} … took more than {timeout} s")
        time.sleep(0.1)
    p.returncode = os.waitstatus_to_exitcode(status)
    return p.returncode, ru.ru_utime + ru.ru_stime


def joint_summary(runs):
    """Per sample and joint: named with the right joint and sign within 600 captures of the
    onset (the first `joint-offset-suspected` after it), and the estimate against the truth."""
    print("\nJoint offsets: the first `joint-offset-suspected` after the onset, per sample and joint "
          "(both signs, every onset of the rows above).\n")
    print("| sample | joint | runs | named right within 600 | named wrong (joint or sign) | not named | estimate / truth: median (range) | estimate within ±30 % |")
    print("|---|---|---|---|---|---|---|---|")
    for key in dict.fromkeys((r[0], r[1]) for r in runs):
        rows = [r for r in runs if (r[0], r[1]) == key]
        right, wrong, missed, ratios = 0, 0, 0, []
        for _, joint, offset, _, a, onset in rows:
            if a is None:
                missed += 1
                continue
            e = a["evidence"]
            if e["joint"] == joint and e["offset_deg"] * offset > 0:
                if a["idx"] - onset <= 600:
                    right += 1
                ratios.append(e["offset_deg"] / offset)
            else:
                wrong += 1
        ratios.sort()
        within = sum(1 for q in ratios if abs(q - 1) <= 0.3)
        med = (f"{ratios[len(ratios) // 2]:.2f} ({ratios[0]:.2f}–{ratios[-1]:.2f})" if ratios else "–")
        print(f"| {key[0]} | {key[1]} | {len(rows)} | {right} | {wrong} | {missed} | {med} | {within} of {len(ratios)} named right |", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--materials", default="walkway", help="comma-separated simulator material presets")
    ap.add_argument("--every", type=int, default=100)
    ap.add_argument("--presets", default="realistic,clean")
    ap.add_argument("--only", help="run only the scenarios whose name contains this text")
    ap.add_argument("--match", help="run only the scenarios whose name matches this regular expression")
    ap.add_argument("--keep", help="keep the recorded sessions in this folder")
    ap.add_argument("--replay", help="re-evaluate the sessions kept in this folder (or these, comma-separated) instead of running the rig")
    ap.add_argument("--replay-out", help="with --replay: keep each replay's output in this folder, and score a run "
                                         "whose output is already there from it instead of replaying it (one folder per binary)")
    ap.add_argument("--json", help="also write one record per run to this file (for benches/detection_curves.py)")
    ap.add_argument("--jobs", type=int, default=1, help="runs (or replays) at once; the CPU column stays per run")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="gw-detect-")
    path = f"probes every {a.every} captures" if a.every else "no probes: isotropy classes"
    key = "probe_drift" if a.every else "isotropy_drift"
    how = f"replayed from {a.replay} with the current binary" if a.replay else "live"
    print(f"{path}, {a.seeds} seeds per row, full 6,561-capture runs, {how}.\n")
    print("| preset | scenario | runs with a drift alarm (first code) | first alarm: captures after onset (hours) | final rate %/h (truth) | positioning / outlier alarms after onset (first: joint, estimate, captures after onset) | daemon CPU per capture |")
    print("|---|---|---|---|---|---|---|")
    curves = []
    joint_runs = []
    records = []
    rows = [(material, preset, name, faults, truth)
            for material, preset in [(m, p) for m in a.materials.split(",") for p in a.presets.split(",")]
            for name, faults, truth in SCENARIOS
            if not (a.only and a.only not in name) and not (a.match and not re.search(a.match, name))]
    seeds = range(a.first_seed, a.first_seed + a.seeds)

    def one(task):
        material, preset, name, faults, truth, seed = task
        if a.replay:
            return replay(a.replay.split(","), name, material, preset, seed, a.replay_out)
        return run(tmp, name, material, preset, faults, seed, a.every, a.keep)

    if not os.access(BIN, os.X_OK):
        sys.exit(f"no goniowatch binary at {BIN}: run `cargo build --release` or set GONIOWATCH_BIN")
    # every run of a row is done before its line is printed; rows keep their order; the first
    # failure (or Ctrl-C) cancels the runs not yet started
    pool = ThreadPoolExecutor(max_workers=max(1, a.jobs))
    pending = [[pool.submit(one, (*row, seed)) for seed in seeds] for row in rows]
    try:
        report(a, rows, seeds, pending, key, curves, joint_runs, records)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    if joint_runs:
        joint_summary(joint_runs)
    if curves:
        # the estimate's error against hours into the run; truth up to t: the mean ln-gain slope
        # of the linear decay 1 − a·t over [0, t]
        print("\nDrift-rate estimate against hours into the run (isotropy classes): error in %/h "
              "(estimate − truth), ± its standard error; – where no estimate existed yet.\n")
        print("| preset | scenario | seed | " + " | ".join(f"{h} h" for h in CURVE_H) + " |")
        print("|---|---|---|" + "---|" * len(CURVE_H))
        for preset, name, seed, (form, _, rate), pts in curves:
            cells = []
            for h in CURVE_H:
                if h in pts:
                    truth_h = truth_rate(form, rate, h)
                    cells.append(f"{pts[h][0] - truth_h:+.3f} ± {pts[h][1]:.3f}")
                else:
                    cells.append("–")
            print(f"| {preset} | {name} | {seed} | " + " | ".join(cells) + " |", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(records, f, indent=1)
    shutil.rmtree(tmp, ignore_errors=True)


def report(a, rows, seeds, pending, key, curves, joint_runs, records):
    """Prints the table's rows as their runs finish, and collects the curves, joint runs and
    records for the summaries."""
    for (material, preset, name, faults, truth), futures in zip(rows, pending):
        label = preset if material == "walkway" else f"{preset}, {material}"
        hits, delays, rates, cpu, geo, kinds = 0, [], [], [], [], []
        runs = 0
        for seed, fut in zip(seeds, futures):
            got = fut.result()
            if got is None:
                continue
            alarms, summary, daemon_cpu, pts = got
            if truth and truth[0] in ("rate", "rate-exp") and not a.every:
                curves.append((label, name, seed, truth, pts))
            runs += 1
            if daemon_cpu is not None:
                cpu.append(1000 * daemon_cpu / max(1, summary["checked"]["captures"]))
            drift = [x for x in alarms if x["kind"] == "drift" and x["code"] != "gain-drift-cleared"]
            kinds.append(min(drift, key=lambda x: x["idx"] or 0)["code"] if drift else "–")
            onset = truth[1] if truth else 0
            g = [x for x in alarms if x["kind"] in ("positioning", "reciprocity-outlier") and (x["idx"] or 0) >= onset]
            js = [x for x in g if x["code"] == "joint-offset-suspected"]
            first = (f"joint {js[0]['evidence']['joint']} {js[0]['evidence']['offset_deg']:+.2f}° +{js[0]['idx'] - onset}" if js
                     else f"{g[0]['code']} +{g[0]['idx'] - onset}" if g else "")
            if truth and truth[0] == "encoder":
                ch = summary["checked"]
                first += (f", {ch['pairs_needs_resampling']} of {ch['pairs_exact'] + ch['pairs_needs_resampling']} pairs"
                          f" to resample, {ch.get('placed_by_command', 0)} placed by command")
            geo.append(f"{len(g)}" + (f" ({first})" if first else ""))
            if truth and truth[0] == "joint":
                offset = fault_size(faults)
                joint_runs.append((label, truth[2], offset, name, js[0] if js else None, onset))
            records.append(run_record(material, preset, name, faults, truth, seed, alarms, summary, key, a.every))
            hits += bool(drift)
            after = [x["idx"] for x in drift if x["idx"] is not None and x["idx"] >= (truth[1] if truth else 0)]
            if after and truth:
                delays.append(min(after) - truth[1])
            pd = summary.get(key) or {}
            if "rate_pct_per_h" in pd:
                steps = "".join(f" (step {100 * math.expm1(st['ln_size']):+.2f} % at {st['t_h']:.2f} h)"
                                for st in summary.get("isotropy_steps") or [])
                rates.append(f"{pd['rate_pct_per_h']:+.3f}{steps}")
        delay = (f"{sorted(delays)[len(delays) // 2]} ({sorted(delays)[len(delays) // 2] * T_CAPTURE_H:.2f} h), "
                 f"max {max(delays)}") if delays else "–"
        truth_text = f" ({truth_rate(truth[0], truth[2]):+.3f})" if truth and truth[0] in ("rate", "rate-exp") else ""
        rate = ", ".join(rates) + truth_text
        if runs == 0:
            continue
        print(f"| {label} | {name} | {hits} of {runs} ({', '.join(kinds)}) | {delay} | {rate} | {'; '.join(geo)} | {f'{min(cpu):.2f}–{max(cpu):.2f} ms' if cpu else '–'} |", flush=True)


def run_record(material, preset, name, faults, truth, seed, alarms, summary, key, every):
    """One run for `--json`: the fault, and the first drift and positioning alarms before and
    after its onset (a fault-free run's onset is 0: every alarm is a false one)."""
    onset = truth[1] if truth else 0
    drift = sorted((x for x in alarms if x["kind"] == "drift" and x["code"] != "gain-drift-cleared" and x["idx"] is not None),
                   key=lambda x: x["idx"])
    geo = sorted((x for x in alarms if x["kind"] == "positioning" and x["severity"] != "info" and x["idx"] is not None),
                 key=lambda x: x["idx"])
    first = lambda xs, after: next((x for x in xs if (x["idx"] >= onset) == after), None)

    def brief(x):
        if x is None:
            return None
        e = x.get("evidence") or {}
        return {"idx": x["idx"], "code": x["code"], "joint": e.get("joint"), "offset_deg": e.get("offset_deg"),
                "rate_pct_per_h": e.get("rate_pct_per_h"), "level_pct": e.get("level_pct")}

    fault = None
    if faults:
        kinds = {"rate": ("lamp-decay",), "rate-exp": ("lamp-decay",), "step": ("lamp-step",), "encoder": ("encoder-mismatch",),
                 "joint": ("joint-offset", "wagon-offset", "wagon-backlash")}[truth[0]]
        f = next(f for f in faults if f["kind"] in kinds)
        fault = {"kind": truth[0], "onset": onset, "size": next((f[k] for k in ("step_pct", "rate_pct_per_h", "offset_deg", "backlash_deg") if k in f), None),
                 "axis": truth[2] if truth[0] in ("joint", "encoder") else None}
    pd = summary.get(key) or {}
    joint = next((x for x in geo if x["idx"] >= onset and x["code"] == "joint-offset-suspected"), None)
    return {"material": material, "preset": preset, "scenario": name, "seed": seed, "every": every, "fault": fault,
            "joint_after": brief(joint),
            "captures": summary["checked"]["captures"],
            "drift_before": brief(first(drift, False)) if truth else None,
            "positioning_before": brief(first(geo, False)) if truth else None,
            "drift_after": brief(first(drift, True)), "positioning_after": brief(first(geo, True)),
            "final_rate_pct_per_h": pd.get("rate_pct_per_h"),
            "steps": [100 * math.expm1(st["ln_size"]) for st in summary.get("isotropy_steps") or []]}


if __name__ == "__main__":
    main()
