#!/usr/bin/env python3
"""What the light sweeps can tell of the wagon: replays recorded matrix runs
(`detection.py record`) with a goniowatch binary and reads each sweep's `wagon` fit from
sweeps.jsonl (the smooth model's fit of the sweep with the joints, the wagon's offset and its
backlash together). Prints, per θi layer, the median standard error of the wagon's offset and
backlash and their correlation with joint 1, and for the wagon, joint-1 and fault-free rows
the mean offset/backlash after the fault's onset (before it for the fault-free), in degrees
and in standard errors. Usage:

    python3 benches/wagon_identifiability.py --bin target/release/goniowatch \
        --match '^(wagon|joint-1|no-fault)-.*-realistic(-b)?-s[1-4]$'
"""
import argparse
import json
import os
import shutil
import statistics as st
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import matrix as M  # noqa: E402

LAYERS_DEG = (0, 15, 30, 45, 60, 75)


def sd(v: list[float]) -> float:
    return st.stdev(v) if len(v) > 1 else float("nan")


def sweeps_of(binary: str, lab: str, run: M.Run) -> list[dict]:
    s = os.path.join(lab, "runs", run.id, "s")
    out = tempfile.mkdtemp(prefix="gw-wagon-")
    try:
        shutil.rmtree(out)
        p = subprocess.run([binary, "replay", s, "--out", out, "--recorded-outcomes", "--quiet"],
                           capture_output=True, text=True)
        if p.returncode not in (0, 4):
            raise RuntimeError(f"{run.id}: replay exit {p.returncode}: {p.stderr.strip()}")
        with open(os.path.join(out, "sweeps.jsonl")) as f:
            return [json.loads(line) for line in f if line.strip()]
    finally:
        shutil.rmtree(out, ignore_errors=True)


def layer_of(light: int) -> int:
    # the UBO plan's lights by θi layer: 0 | 1–6 | 7–18 | 19–36 | 37–56 | 57–80 (Δφ –, 60°, 30°,
    # 20°, 18°, 15°)
    for k, last in enumerate((0, 6, 18, 36, 56, 80)):
        if light <= last:
            return LAYERS_DEG[k]
    return -1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--lab", default=os.path.join(M.REPO, "target", "lab"))
    ap.add_argument("--match", required=True)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args()
    runs = [r for r in M.select(a.match)
            if os.path.isdir(os.path.join(a.lab, "runs", r.id, "s"))]
    if not runs:
        print("no recorded runs match", file=sys.stderr)
        return 2
    with ThreadPoolExecutor(a.jobs) as pool:
        records = list(pool.map(lambda r: sweeps_of(a.bin, a.lab, r), runs))
    per_layer: dict[int, list[dict]] = {}
    for recs in records:
        for r in recs:
            if r.get("wagon"):
                per_layer.setdefault(layer_of(r["light"]), []).append(r["wagon"])
    print("| θi layer | sweeps | wagon offset SE (°), median | backlash SE (°), median | corr. with joint 1, median |")
    print("|---|---|---|---|---|")
    for layer in sorted(per_layer):
        w = per_layer[layer]
        print(f"| {layer}° | {len(w)} | {st.median(x['offset_se_deg'] for x in w):.3f} | "
              f"{st.median(x['backlash_se_deg'] for x in w):.3f} | "
              f"{st.median(x['corr_joint1'] for x in w):.2f} |")
    print()
    print("| row | runs | sweeps | offset (°), mean | offset / SE, mean | backlash (°), mean | backlash / SE, mean | joint 1 (°), mean | first 3 sweeps: offset / SE | backlash / SE | joint 1 / SE |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows: dict[str, list] = {}
    for run, recs in zip(runs, records):
        onset = run.row.truth.onset if run.row.truth else None
        after = [r for r in recs if r.get("wagon") and (onset is None or r["idx"] >= onset + 81)]
        if onset is None:
            after = after[20:]
        rows.setdefault(run.row.name, []).append((run, after))
    # a fault's first three sweeps after its onset (a fault-free run's every sweep from the 21st)
    def head(items, after):
        return after if items[0][0].row.truth is None else after[:3]

    def first3(items, v, se):
        return [r["wagon"][v] / r["wagon"][se] for _, after in items for r in head(items, after)]

    def first3j(items):
        return [f["offset_deg"] / f["se_deg"] for _, after in items for r in head(items, after)
                for f in r["joints"] if f["joint"] == 1 and f["se_deg"] > 0]

    for name, items in sorted(rows.items()):
        ws = [r["wagon"] for _, after in items for r in after]
        j1 = [f["offset_deg"] for _, after in items for r in after for f in r["joints"] if f["joint"] == 1]
        if not ws:
            continue
        def m(v):
            return sum(v) / len(v) if v else float("nan")
        print(f"| {name} | {len(items)} | {len(ws)} | {m([w['offset_deg'] for w in ws]):+.2f} | "
              f"{m([w['offset_deg'] / w['offset_se_deg'] for w in ws]):+.1f} | "
              f"{m([w['backlash_deg'] for w in ws]):+.2f} | "
              f"{m([w['backlash_deg'] / w['backlash_se_deg'] for w in ws]):+.1f} | "
              f"{m(j1) if j1 else float('nan'):+.2f} | "
              f"{m(first3(items, 'offset_deg', 'offset_se_deg')):+.1f} ± {sd(first3(items, 'offset_deg', 'offset_se_deg')):.1f} | "
              f"{m(first3(items, 'backlash_deg', 'backlash_se_deg')):+.1f} ± {sd(first3(items, 'backlash_deg', 'backlash_se_deg')):.1f} | "
              f"{m(first3j(items)):+.1f} ± {sd(first3j(items)):.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
