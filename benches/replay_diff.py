"""Replay recorded sessions with two goniowatch binaries and compare their result files.

Usage:
  python3 benches/replay_diff.py OLD_BINARY NEW_BINARY KEPT_DIR [--tolerate dh,dc] [--rel 1e-4] [--abs 1e-9]

KEPT_DIR holds sessions as `benches/detection.py --keep KEPT_DIR` leaves them
(KEPT_DIR/<run>/s). Each is replayed by both binaries (`goniowatch replay --out`), and every
result file is reported as byte-identical, identical but for the tolerated fields (numbers within
the relative or absolute tolerance), or different (the first differences named). Exit status 1 when any file
differs beyond that. Use it to show that a change which should not alter results does not, and to
see exactly what a change that should alter them altered.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile


def walk(a, b, path, tolerate, tol, diffs):
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            diffs.append(f"{path}: keys {sorted(set(a) ^ set(b))}")
            return
        for k in a:
            walk(a[k], b[k], f"{path}.{k}", tolerate, tol, diffs)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{path}[{i}]", tolerate, tol, diffs)
    elif a != b:
        leaf = path.split(".")[-1].split("[")[0]
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))
        rel, absolute = tol
        if leaf in tolerate and numbers and (abs(a - b) <= rel * max(abs(a), abs(b)) or abs(a - b) <= absolute):
            return
        diffs.append(f"{path}: {a!r} != {b!r}")


def compare_file(a, b, name, tolerate, tol):
    """None when identical up to the tolerated fields, else the differences."""
    if name.endswith(".json"):
        la, lb = [a.decode()], [b.decode()]
    else:
        la, lb = a.decode().splitlines(), b.decode().splitlines()
    if len(la) != len(lb):
        return [f"{len(la)} records against {len(lb)}"]
    diffs = []
    for i, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            walk(json.loads(x), json.loads(y), f"record {i + 1}", tolerate, tol, diffs)
    return diffs


def replay(binary, session):
    out = os.path.join(tempfile.mkdtemp(prefix="gw-replay-diff-"), "r")
    r = subprocess.run([binary, "replay", session, "--out", out, "--quiet"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{binary} replay {session} failed ({r.returncode}): {r.stderr[-2000:]}")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("kept")
    ap.add_argument("--tolerate", default="", help="comma-separated field names compared with --rel")
    ap.add_argument("--rel", type=float, default=1e-4)
    ap.add_argument("--abs", type=float, default=1e-9, dest="absolute")
    a = ap.parse_args()
    tolerate = {f for f in a.tolerate.split(",") if f}
    counts = {"byte-identical": 0, "within tolerance": 0, "different": 0}
    for run in sorted(os.listdir(a.kept)):
        session = os.path.join(a.kept, run, "s")
        if not os.path.isdir(session):
            continue
        old, new = replay(a.old, session), replay(a.new, session)
        for name in sorted(os.listdir(old)):
            if not (name.endswith(".jsonl") or name == "summary.json"):
                continue
            x = open(os.path.join(old, name), "rb").read()
            y = open(os.path.join(new, name), "rb").read()
            if x == y:
                verdict = "byte-identical"
            else:
                diffs = compare_file(x, y, name, tolerate, (a.rel, a.absolute))
                verdict = "different" if diffs else "within tolerance"
                if diffs:
                    print(f"{run}/{name}: {len(diffs)} differences, first: {diffs[:3]}")
            counts[verdict] += 1
            if verdict != "different":
                print(f"{run}/{name}: {verdict}")
    print(counts)
    sys.exit(1 if counts["different"] else 0)


if __name__ == "__main__":
    main()
