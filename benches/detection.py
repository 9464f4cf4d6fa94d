"""The detection lab: record the whole detection matrix (benches/matrix.py), score it with any
goniowatch binary, and compare the fast path with live runs.

  python3 benches/detection.py record   [--jobs 2] [--match REGEX] [--lab target/lab]
  python3 benches/detection.py score    [--jobs 2] [--match REGEX] [--lab target/lab] [--bin BIN]
                                        [--out benches/detection-records.json]
  python3 benches/detection.py equivalence [--match REGEX] [--limit N] [--lab target/lab]
  python3 benches/detection.py diff BEFORE.json AFTER.json

- `record` runs every run of the matrix that has no recording yet through the fast path: the
  simulator in lockstep with `goniowatch lockstep` (no pty, no wall-clock waits), the session
  folder a live run writes. A recording keeps the session's journal, config and results
  (LAB/runs/<id>/s) and its score (LAB/runs/<id>/record.json), written last: an interrupted
  recording is redone, a finished one kept. Captures are written to a scratch folder in
  /dev/shm (or the temp folder) and removed when the run is recorded.
- `score` replays every recording with the binary (`goniowatch replay --recorded-outcomes`:
  the engine and the checks on the journal, without decoding), scores it, and writes all
  records, in matrix order, to --out. Scores are kept per binary (LAB/scores/<sha256 of the
  binary>/<id>.json) so an interrupted scoring resumes. A run not recorded yet is left out and
  counted.
- `equivalence` runs rows live over the pty (the simulator at full speed, `goniowatch run`) and
  through the fast path with the same scenario and seed, and prints what differs: alarms,
  capture records, sweeps and pairs byte for byte, and the summary less the link counters.
  Rows with probes are run with the rig paced (25 ms a capture) so that the live daemon keeps
  up, as it does beside a real rig at 7 s a capture.

- `diff` lists the runs whose first alarms differ between two score files (a detector change
  judged on every run of the matrix).

Each prints its progress (runs done, left, the rate and the time left) and can be interrupted
and resumed. Recorders and scorers may run side by side on one lab, with overlapping matches:
each run is taken under a lock (LAB/locks), and one another process holds is left to it. GONIOWATCH_BIN overrides the binary (default target/release/goniowatch)."""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import matrix as M  # noqa: E402

REPO = M.REPO
SIM = os.path.join(REPO, "sim")
DEFAULT_BIN = os.environ.get("GONIOWATCH_BIN") or os.path.join(REPO, "target", "release", "goniowatch")
RUN_H = M.CAPTURES * M.T_CAPTURE_S / 3600.0
CURVE_H = [1, 2, 3, 4, 6, 8, 10, 12]
# the result files a recording keeps beside its journal (the rest is remade by a replay)
KEEP = ("config.toml", "session.json", "journal.jsonl", "summary.json", "alarms.jsonl")


def scratch_root() -> str:
    shm = "/dev/shm"
    return shm if os.path.isdir(shm) and os.access(shm, os.W_OK) else tempfile.gettempdir()


def truth_rate(form: str, rate_pct_per_h: float, hours: float = RUN_H) -> float:
    """The ln-gain slope (%/h) a decay of `rate_pct_per_h` has over [0, hours]: −r for an
    exponential decay (`rate-exp`), the mean slope of ln(1 − r·t) for a linear one."""
    if form == "rate-exp":
        return -rate_pct_per_h
    return 100 * math.log(1 - rate_pct_per_h / 100 * hours) / hours


def curve(captures_path: str) -> dict:
    """The isotropy drift estimate at hours into the run: each capture's gain correction (g =
    exp(r·t) from the rate known at its time) gives r = ln g / t and its SE = σ_rel / t."""
    pts = {}
    with open(captures_path, encoding="utf-8") as f:
        for line in f:
            c = json.loads(line)
            g = c.get("gain_corrected")
            t_h = c["t"] / 3600.0
            if not g or g.get("source") != "isotropy classes" or t_h <= 0 or c.get("probe"):
                continue
            for h in CURVE_H:
                if t_h <= h:
                    pts[str(h)] = [round(100 * math.log(g["gain"]) / t_h, 6), round(100 * g["sigma_rel"] / t_h, 6)]
    return pts


def brief(x):
    if x is None:
        return None
    e = x.get("evidence") or {}
    # the wagon is axis 4 (matrix.Truth); its lag's size is the lag, its offset's the offset
    lag = x["code"] == "wagon-backlash-suspected"
    wagon = lag or x["code"] == "wagon-offset-suspected"
    return {"idx": x["idx"], "code": x["code"], "joint": 4 if wagon else e.get("joint"),
            "offset_deg": e.get("backlash_deg") if lag else e.get("offset_deg"),
            "rate_pct_per_h": e.get("rate_pct_per_h"), "level_pct": e.get("level_pct")}


def score(run: M.Run, session: str) -> dict:
    """One run's record from its session folder (live, lockstep or replayed): the fault, the
    first drift and positioning alarms before and after its onset (a fault-free run's onset is
    0: every alarm is a false one), the final rate, the fitted steps and, for a decay, the rate
    estimate against hours into the run."""
    with open(os.path.join(session, "alarms.jsonl"), encoding="utf-8") as f:
        alarms = [json.loads(line) for line in f if line.strip()]
    with open(os.path.join(session, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    t = run.row.truth
    onset = t.onset if t else 0
    # a drift alarm: a lamp change raised (not one cleared or withdrawn, nor the lamp's
    # capture-to-capture instability, scored on its own, nor an advisory of severity info)
    drift = sorted((x for x in alarms if x["kind"] == "drift" and x["severity"] != "info" and x["code"] != "lamp-unstable"
                    and not x["code"].endswith(("-cleared", "-withdrawn")) and x["idx"] is not None), key=lambda x: x["idx"])
    geo = sorted((x for x in alarms if x["kind"] == "positioning" and x["severity"] != "info" and x["idx"] is not None),
                 key=lambda x: x["idx"])
    unstable = sorted((x for x in alarms if x["code"] == "lamp-unstable" and x["idx"] is not None), key=lambda x: x["idx"])

    def first(xs, after):
        return next((x for x in xs if (x["idx"] >= onset) == after), None)

    key = "probe_drift" if run.every else "isotropy_drift"
    pd = summary.get(key) or {}
    joint = next((x for x in geo if x["idx"] >= onset
                  and x["code"] in ("joint-offset-suspected", "wagon-backlash-suspected", "wagon-offset-suspected")), None)
    ch = summary.get("checked") or {}
    rec = {"id": run.id, "row": run.row.name, "material": run.material, "model": run.label, "seed": run.seed,
           "every": run.every,
           "fault": None if t is None else {"kind": t.kind, "onset": t.onset, "size": t.size, "axis": t.axis},
           "captures": ch.get("captures"), "probes": ch.get("probes"),
           "drift_before": brief(first(drift, False)) if t else None,
           "positioning_before": brief(first(geo, False)) if t else None,
           "drift_after": brief(first(drift, True)), "positioning_after": brief(first(geo, True)),
           "joint_after": brief(joint), "unstable_after": brief(first(unstable, True)),
           "codes_after": sorted({x["code"] for x in alarms if x["severity"] != "info" and (x["idx"] or 0) >= onset}),
           "final_rate_pct_per_h": pd.get("rate_pct_per_h"),
           "steps": [100 * math.expm1(st["ln_size"]) for st in summary.get("isotropy_steps") or []]}
    if t and t.kind in ("rate", "rate-exp") and not run.every and os.path.exists(os.path.join(session, "captures.jsonl")):
        rec["curve"] = curve(os.path.join(session, "captures.jsonl"))
    return rec


def write_json_atomic(path: str, value) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(value, f, indent=None, sort_keys=True)
        f.write("\n")
    os.replace(tmp, path)


def cpu_of(cmd: list[str], cwd: str | None = None, timeout: float = 1800) -> tuple[int, float, str]:
    """Runs `cmd` and returns its exit code, the CPU seconds it and its children used (wait4 on
    it alone, so parallel runs keep their own) and the tail of its stderr."""
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=err)
        deadline = time.monotonic() + timeout
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid == p.pid:
                break
            if time.monotonic() > deadline:
                p.kill()
                os.wait4(p.pid, 0)
                raise TimeoutError(f"{' '.join(cmd[:3])} … took more than {timeout} s")
            time.sleep(0.05)
        err.seek(0)
        tail = err.read()[-2000:].decode("utf-8", "replace")
    return os.waitstatus_to_exitcode(status), ru.ru_utime + ru.ru_stime, tail


def lockstep_into(run: M.Run, d: str, binary: str, label: str) -> tuple[int, float]:
    """Records `run` through the fast path into the new folder D/s (its scenario and config
    beside it, its captures in a scratch folder removed after); returns the exit code and the
    CPU seconds of simulator and daemon."""
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    cap = tempfile.mkdtemp(prefix="gw-lab-", dir=scratch_root())
    try:
        with open(os.path.join(d, "scenario.toml"), "w", encoding="utf-8") as f:
            f.write(run.scenario_toml(cap))
        with open(os.path.join(d, "config.toml"), "w", encoding="utf-8") as f:
            f.write(run.config_toml())
        rc, cpu, err = cpu_of([sys.executable, "-m", "goniosim", "lockstep", os.path.join(d, "scenario.toml"),
                               "--session", os.path.join(d, "s"), "--config", os.path.join(d, "config.toml"),
                               "--goniowatch", binary, "--truth", os.path.join(cap, "truth.jsonl")], cwd=SIM)
        if rc not in (0, 4):
            raise RuntimeError(f"{label}: the lockstep run failed (exit {rc}): {err.strip()}")
        return rc, cpu
    finally:
        shutil.rmtree(cap, ignore_errors=True)


@contextlib.contextmanager
def run_lock(lab: str, name: str):
    """Holds the lab's lock called `name` while the block runs; yields False, holding nothing,
    when another process (or another open of it) holds it."""
    locks = os.path.join(lab, "locks")
    os.makedirs(locks, exist_ok=True)
    with open(os.path.join(locks, name + ".lock"), "w", encoding="utf-8") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def record_one(run: M.Run, lab: str, binary: str) -> float:
    """Records one run through the fast path; returns its CPU seconds (simulator and daemon), 0
    when another recorder has it or has finished it."""
    with run_lock(lab, f"record-{run.id}") as mine:
        if not mine or os.path.exists(os.path.join(lab, "runs", run.id, "record.json")):
            return 0.0
        return _record_one(run, lab, binary)


def _record_one(run: M.Run, lab: str, binary: str) -> float:
    d = os.path.join(lab, "runs", run.id)
    _, cpu = lockstep_into(run, d, binary, run.id)
    s = os.path.join(d, "s")
    rec = score(run, s)
    rec["record_cpu_s"] = round(cpu, 2)
    for name in os.listdir(s):
        if name not in KEEP:
            os.unlink(os.path.join(s, name))
    write_json_atomic(os.path.join(d, "record.json"), rec)
    return cpu


def binary_id(binary: str) -> str:
    h = hashlib.sha256()
    with open(binary, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def score_one(run: M.Run, lab: str, binary: str, scores: str) -> float:
    """Replays one recording with `binary` and scores it; returns the replay's CPU seconds, 0
    when another scorer of the binary has it or has finished it."""
    with run_lock(lab, f"score-{os.path.basename(scores)}-{run.id}") as mine:
        if not mine or os.path.exists(os.path.join(scores, f"{run.id}.json")):
            return 0.0
        return _score_one(run, lab, binary, scores)


def _score_one(run: M.Run, lab: str, binary: str, scores: str) -> float:
    s = os.path.join(lab, "runs", run.id, "s")
    out = tempfile.mkdtemp(prefix="gw-score-", dir=scratch_root())
    try:
        shutil.rmtree(out)
        rc, cpu, err = cpu_of([binary, "replay", s, "--out", out, "--recorded-outcomes", "--quiet"])
        if rc not in (0, 4):
            raise RuntimeError(f"{run.id}: the replay failed (exit {rc}): {err.strip()}")
        rec = score(run, out)
        rec["replay_cpu_s"] = round(cpu, 2)
        write_json_atomic(os.path.join(scores, f"{run.id}.json"), rec)
        return cpu
    finally:
        shutil.rmtree(out, ignore_errors=True)


class Progress:
    def __init__(self, verb: str, total: int, jobs: int) -> None:
        self.verb, self.total, self.jobs = verb, total, jobs
        self.done, self.cpu, self.started = 0, 0.0, time.monotonic()

    def step(self, run_id: str, cpu: float) -> None:
        self.done += 1
        self.cpu += cpu
        wall = time.monotonic() - self.started
        left = (self.total - self.done) * wall / self.done
        print(f"{self.verb} {self.done}/{self.total}  {run_id}  {cpu:.1f} s CPU  "
              f"[{wall / 60:.1f} min, about {left / 60:.1f} min left]", flush=True)

    def end(self) -> None:
        wall = time.monotonic() - self.started
        per = self.cpu / self.done if self.done else 0.0
        print(f"{self.verb}: {self.done} runs in {wall / 60:.1f} min wall, {per:.2f} s CPU a run, {self.jobs} at once", flush=True)


def pool_map(fn, runs, jobs, progress):
    pool = ThreadPoolExecutor(max_workers=max(1, jobs))
    futures = {pool.submit(fn, r): r for r in runs}
    try:
        for fut in as_completed(futures):
            progress.step(futures[fut].id, fut.result())
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    progress.end()


def cmd_record(a) -> int:
    runs = [r for r in M.select(a.match) if not os.path.exists(os.path.join(a.lab, "runs", r.id, "record.json"))]
    have = len(M.select(a.match)) - len(runs)
    print(f"record: {len(runs)} runs to record, {have} already recorded, {a.jobs} at once, into {a.lab}/runs", flush=True)
    if runs:
        pool_map(lambda r: record_one(r, a.lab, a.bin), runs, a.jobs, Progress("recorded", len(runs), a.jobs))
    return 0


def score_runs(wanted: list[M.Run], lab: str, binary: str, jobs: int, label: str = "score") -> tuple[str, list[dict], int, int]:
    """Scores the recorded runs of `wanted` with `binary` (each replayed once, its score kept per
    binary): the binary's id, the records of the recorded runs (in `wanted`'s order), how many
    are recorded, and how many of those another scorer has not finished yet (left out)."""
    bid = binary_id(binary)
    scores = os.path.join(lab, "scores", bid)
    os.makedirs(scores, exist_ok=True)
    recorded = [r for r in wanted if os.path.exists(os.path.join(lab, "runs", r.id, "record.json"))]
    todo = [r for r in recorded if not os.path.exists(os.path.join(scores, f"{r.id}.json"))]
    print(f"{label}: binary {binary} ({bid}); {len(recorded)} of {len(wanted)} runs recorded, "
          f"{len(todo)} to replay, {jobs} at once", flush=True)
    if todo:
        pool_map(lambda r: score_one(r, lab, binary, scores), todo, jobs, Progress("scored", len(todo), jobs))
    records, elsewhere = [], 0
    for r in recorded:
        path = os.path.join(scores, f"{r.id}.json")
        if not os.path.exists(path):
            # left to another scorer that has not finished it
            elsewhere += 1
            continue
        with open(path, encoding="utf-8") as f:
            rec = json.load(f)
        rec.pop("replay_cpu_s", None)
        records.append(rec)
    if elsewhere:
        print(f"{label}: {elsewhere} runs are being scored by another process; run it again when that ends", flush=True)
    return bid, records, len(recorded), elsewhere


def cmd_score(a) -> int:
    wanted = M.select(a.match)
    bid, records, recorded, elsewhere = score_runs(wanted, a.lab, a.bin, a.jobs)
    if elsewhere:
        return 1
    if a.out:
        with open(a.out, "w", encoding="utf-8") as f:
            json.dump({"binary": bid, "runs_in_matrix": len(M.RUNS), "records": records}, f, indent=0, sort_keys=True)
            f.write("\n")
        print(f"score: {len(records)} records to {a.out}" + (f"; {len(wanted) - recorded} runs not recorded yet" if recorded < len(wanted) else ""))
    return 0 if recorded == len(wanted) else 1


# --- one run outside the matrix (benches/colour_drift.py, benches/probe_plan.py) -----------------

BIN = DEFAULT_BIN


def run_name(name: str, material: str, preset: str, seed: int) -> str:
    """The kept session's folder name of a run outside the matrix."""
    slug = re.sub(r"[^a-z0-9.]+", "-", re.sub(r"\+(?=[0-9.]+)", "plus ", re.sub(r"−(?=[0-9.]+)", "minus ", name)).lower()).strip("-")
    return f"{slug}-{material}-{preset}-{seed}"


def run(tmp, name, material, preset, faults, seed, every, keep=None, config="sim.toml"):
    """Records one run (any faults, any config of config/) through the fast path into
    KEEP/<run_name>/s (or a scratch folder); returns (exit code, alarms, summary, CPU s, drift
    curve)."""
    r = M.Run(M.Row(name, tuple(faults)), material, preset, seed, every=every, config=config)
    d = os.path.join(keep or tmp, run_name(name, material, preset, seed))
    try:
        rc, cpu = lockstep_into(r, d, BIN, name)
        return _results(os.path.join(d, "s"), rc, cpu)
    finally:
        if not keep:
            shutil.rmtree(d, ignore_errors=True)


def _results(session, rc, cpu):
    with open(os.path.join(session, "alarms.jsonl"), encoding="utf-8") as f:
        alarms = [json.loads(line) for line in f if line.strip()]
    with open(os.path.join(session, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    return rc, alarms, summary, cpu, curve(os.path.join(session, "captures.jsonl"))


def replay(keeps, name, material, preset, seed, replay_out=None):
    """Replays the kept session of a run outside the matrix (the first of `keeps` that has it)
    with BIN; returns what `run` does, or None when no folder has it."""
    keeps = keeps.split(",") if isinstance(keeps, str) else keeps
    rn = run_name(name, material, preset, seed)
    d = next((os.path.join(k, rn) for k in keeps if os.path.isdir(os.path.join(k, rn, "s"))), None)
    if d is None:
        return None
    out = os.path.join(replay_out, rn) if replay_out else tempfile.mkdtemp(prefix="gw-replay-", dir=scratch_root())
    try:
        shutil.rmtree(out, ignore_errors=True)
        rc, cpu, err = cpu_of([BIN, "replay", os.path.join(d, "s"), "--out", out, "--recorded-outcomes", "--quiet"])
        if rc not in (0, 4):
            raise RuntimeError(f"{rn}: the replay failed (exit {rc}): {err.strip()}")
        return _results(out, rc, cpu)
    finally:
        if not replay_out:
            shutil.rmtree(out, ignore_errors=True)


# --- fast path against live ---------------------------------------------------------------------

COMPARED = ("alarms.jsonl", "captures.jsonl", "sweeps.jsonl", "pairs.jsonl", "isotropy.jsonl", "manifest.jsonl")
# what only a live link has
LIVE_ONLY = ("link",)


def live_session(run: M.Run, d: str, binary: str, pace_s: float = 0.0) -> str:
    """Records `run` live: the simulator on a pty, `goniowatch run` beside it."""
    os.makedirs(d, exist_ok=True)
    sc = os.path.join(d, "scenario.toml")
    text = run.scenario_toml(os.path.join(d, "cap"))
    text = text.replace("speed = 0\n", f'port = "{d}/port"\nspeed = {M.T_CAPTURE_S / pace_s if pace_s else 0}\n')
    with open(sc, "w", encoding="utf-8") as f:
        f.write(text)
    cfg = os.path.join(d, "config.toml")
    with open(cfg, "w", encoding="utf-8") as f:
        f.write(run.config_toml())
    sim = subprocess.Popen([sys.executable, "-m", "goniosim", "run", sc, "--linger", "60"], cwd=SIM,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while not os.path.exists(f"{d}/port"):
            if sim.poll() is not None:
                raise RuntimeError(f"the simulator exited ({sim.returncode}) before opening its port")
            time.sleep(0.05)
        rc, _, err = cpu_of([binary, "run", "--config", cfg, "--session", f"{d}/live", "--port", f"{d}/port",
                             "--capture-root", f"{d}/cap", "--quiet"])
        if rc not in (0, 4):
            raise RuntimeError(f"{run.id}: the live run failed (exit {rc}): {err.strip()}")
    finally:
        sim.terminate()
        sim.wait()
    return f"{d}/live"


def differences(live: str, fast: str) -> list[str]:
    """What differs between two session folders' results: the result files byte for byte, and
    the summary less what only a live link has."""
    out = []
    for name in COMPARED:
        a, b = (open(os.path.join(x, name), "rb").read() for x in (live, fast))
        if a != b:
            la, lb = a.splitlines(), b.splitlines()
            n = next((i for i, (x, y) in enumerate(zip(la, lb)) if x != y), min(len(la), len(lb)))
            out.append(f"{name}: {len(la)} lines live, {len(lb)} fast; first difference at line {n + 1}")
    sa, sb = (json.load(open(os.path.join(x, "summary.json"))) for x in (live, fast))
    for k in sorted(set(sa) | set(sb)):
        if k in LIVE_ONLY:
            continue
        if sa.get(k) != sb.get(k):
            out.append(f"summary.{k}: live {json.dumps(sa.get(k))[:200]}, fast {json.dumps(sb.get(k))[:200]}")
    return out


def cmd_equivalence(a) -> int:
    runs = M.select(a.match)[: a.limit]
    bad = 0
    root = tempfile.mkdtemp(prefix="gw-equiv-", dir=a.lab)
    try:
        for run in runs:
            d = os.path.join(root, run.id)
            started = time.monotonic()
            live = live_session(run, d, a.bin, pace_s=0.025 if run.every else 0.0)
            t_live = time.monotonic() - started
            started = time.monotonic()
            cap = os.path.join(d, "fast-cap")
            with open(os.path.join(d, "fast.toml"), "w", encoding="utf-8") as f:
                f.write(run.scenario_toml(cap))
            rc, _, err = cpu_of([sys.executable, "-m", "goniosim", "lockstep", os.path.join(d, "fast.toml"), "--session",
                                 os.path.join(d, "fast"), "--config", os.path.join(d, "config.toml"), "--goniowatch", a.bin], cwd=SIM)
            if rc not in (0, 4):
                raise RuntimeError(f"{run.id}: the lockstep run failed (exit {rc}): {err.strip()}")
            t_fast = time.monotonic() - started
            diff = differences(live, os.path.join(d, "fast"))
            bad += bool(diff)
            print(f"{run.id}: {'same' if not diff else 'DIFFERS'} (live {t_live:.1f} s, fast {t_fast:.1f} s wall)", flush=True)
            for line in diff:
                print(f"  {line}", flush=True)
            shutil.rmtree(d, ignore_errors=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"equivalence: {len(runs) - bad} of {len(runs)} runs give the same results live and through the fast path")
    return 1 if bad else 0


JUDGED = ("drift_before", "positioning_before", "drift_after", "positioning_after", "joint_after", "unstable_after")


def cmd_diff(a) -> int:
    """The runs whose first alarms differ between two score files (two binaries on the same
    recordings): what a detector change did to every run of the matrix."""
    with open(a.before, encoding="utf-8") as f:
        before = {r["id"]: r for r in json.load(f)["records"]}
    with open(a.after, encoding="utf-8") as f:
        after = {r["id"]: r for r in json.load(f)["records"]}
    both = [i for i in before if i in after]
    changed = 0
    for i in both:
        diffs = [k for k in JUDGED if before[i].get(k) != after[i].get(k)]
        if not diffs:
            continue
        changed += 1
        def show(x):
            return "–" if x is None else f"{x['code']} @{x['idx']}"
        print(f"{i}: " + "; ".join(f"{k} {show(before[i].get(k))} → {show(after[i].get(k))}" for k in diffs))
    print(f"diff: {changed} of {len(both)} runs changed their first alarms ({len(before) - len(both)} only before, {len(after) - len(both)} only after)")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("record", "score", "equivalence"):
        p = sub.add_parser(name)
        p.add_argument("--lab", default=os.path.join(REPO, "target", "lab"), help="where recordings and scores are kept")
        p.add_argument("--match", help="only the runs whose id matches this regular expression")
        p.add_argument("--bin", default=DEFAULT_BIN, help="the goniowatch binary")
        if name != "equivalence":
            p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="runs at once (default: one per core)")
        if name == "score":
            p.add_argument("--out", default=os.path.join(REPO, "benches", "detection-records.json"),
                           help="the records of every scored run (benches/detection_tables.py reads it)")
        if name == "equivalence":
            p.add_argument("--limit", type=int, default=4, help="at most this many runs")
    p = sub.add_parser("diff", help="runs whose first alarms differ between two score files")
    p.add_argument("before")
    p.add_argument("after")
    a = ap.parse_args()
    if a.cmd == "diff":
        return cmd_diff(a)
    if not os.access(a.bin, os.X_OK):
        sys.exit(f"no goniowatch binary at {a.bin}: run `cargo build --release` or set GONIOWATCH_BIN")
    a.bin = os.path.abspath(a.bin)
    a.lab = os.path.abspath(a.lab)
    os.makedirs(a.lab, exist_ok=True)
    return {"record": cmd_record, "score": cmd_score, "equivalence": cmd_equivalence}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
