"""The drift probes' scatter against their original capture, per channel, measured on kept
fault-free sessions: ln Y (what `goniowatch plan --probe-scatter-pct` assumes) and ln X/Y, ln Z/Y
(what `--colour-scatter-pct` assumes), as the SD over a run's lamp probes (sentinel probes left
out), in %.

Run:
  python3 benches/probe_plan.py --materials brushed,fabric --keep DIR   # or colour_drift.py --every N --keep DIR
  python3 benches/probe_scatter.py DIR
Prints a Markdown table: per material and preset, the range over the fault-free sessions."""

import argparse
import glob
import json
import math
import os
import statistics


def scatter(session):
    caps = [json.loads(line) for line in open(os.path.join(session, "captures.jsonl"))]
    orig = {c["entry"]: c for c in caps if not c.get("probe") and c["status"] == "ok"}
    summary = json.load(open(os.path.join(session, "summary.json")))
    entry = (summary.get("probe_pose") or {}).get("entry")
    d = {"Y": [], "X/Y": [], "Z/Y": []}
    for c in caps:
        if not (c.get("probe") and not c.get("sentinel") and c["entry"] == entry and c["status"] == "ok"):
            continue
        a, b = orig[entry]["xyz"], c["xyz"]
        if min(a + b) <= 0:
            continue
        d["Y"].append(math.log(b[1] / a[1]))
        d["X/Y"].append(math.log(b[0] / b[1]) - math.log(a[0] / a[1]))
        d["Z/Y"].append(math.log(b[2] / b[1]) - math.log(a[2] / a[1]))
    return {k: 100 * statistics.stdev(v) for k, v in d.items() if len(v) > 2}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    a = ap.parse_args()
    rows = {}
    for d in sorted(glob.glob(os.path.join(a.dir, "no-fault-*"))):
        s = os.path.join(d, "s")
        if not os.path.exists(os.path.join(s, "summary.json")):
            continue
        # "no-fault-every-N-<material>-<preset>-<seed>"
        parts = os.path.basename(d).rsplit("-", 1)[0].split("-every-")[-1].split("-", 2)
        if len(parts) < 3:
            continue
        got = scatter(s)
        if got:
            rows.setdefault((parts[1], parts[2]), []).append(got)
    print("| material | preset | fault-free runs | ln Y % | ln X/Y % | ln Z/Y % |")
    print("|---|---|---|---|---|---|")
    for (material, preset), runs in sorted(rows.items()):
        cell = lambda k: f"{min(r[k] for r in runs):.2f}–{max(r[k] for r in runs):.2f}"
        print(f"| {material} | {preset} | {len(runs)} | {cell('Y')} | {cell('X/Y')} | {cell('Z/Y')} |")


if __name__ == "__main__":
    main()
