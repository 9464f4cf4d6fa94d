"""Colour-drift detection: full 6,561-capture simulated runs without probes (isotropy classes),
a 3000 K lamp cooling by `--rate` K/h from the start (`lamp-colour-drift`) and fault-free runs,
per material, nuisance preset and seed. Reports the `colour-drift` alarms of fault-free runs,
when the drift was first flagged (captures, and the fraction of the run), the final estimate in
K/h against the truth, its standard error and ΔE00/h, and any gain alarm the colour drift caused.

Run (after `cargo build --release`):
  python3 benches/colour_drift.py [--seeds 3] [--fault-free-seeds 10] [--first-seed 1] [--rate -20]
                                  [--materials walkway,ceiling,floortile,pinkwall]
                                  [--presets realistic,realistic-b] [--keep DIR]
  python3 benches/colour_drift.py --replay DIR [...]   # re-score kept sessions with the current binary
Prints a Markdown table. Uses benches/detection.py's runner (same rig config, 16 × 16 images)."""

import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import detection as D  # noqa: E402

PLAN = 6561


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--fault-free-seeds", type=int, default=0, help="seeds for the fault-free rows (default: --seeds)")
    ap.add_argument("--rate", type=float, default=-20.0, help="K/h of the drifting lamp")
    ap.add_argument("--materials", default="walkway,ceiling,floortile,pinkwall")
    ap.add_argument("--presets", default="realistic,realistic-b")
    ap.add_argument("--keep", help="keep the recorded sessions in this folder")
    ap.add_argument("--replay", help="re-score the sessions kept in this folder")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="gw-colour-")
    scenarios = [
        ("no fault", [], None),
        (f"colour {a.rate:+g} K/h", [{"kind": "lamp-colour-drift", "at_capture": 0, "cct_k_per_h": a.rate}], a.rate),
    ]
    print(f"No probes (isotropy classes), {a.seeds} seeds per fault row, {a.fault_free_seeds or a.seeds} per fault-free row, full {PLAN}-capture runs, "
          f"{'replayed from ' + a.replay if a.replay else 'live'}.\n")
    print("| material | preset | scenario | runs with a colour-drift alarm | first flagged: capture (fraction of the run) | final K/h ± SE (truth) | ΔE00/h | gain alarms |")
    print("|---|---|---|---|---|---|---|---|")
    for material in a.materials.split(","):
        for preset in a.presets.split(","):
            for name, faults, truth in scenarios:
                hits, firsts, finals, des, gains, runs = 0, [], [], [], 0, 0
                n = a.fault_free_seeds if (truth is None and a.fault_free_seeds) else a.seeds
                for seed in range(a.first_seed, a.first_seed + n):
                    if a.replay:
                        got = D.replay(a.replay, name, material, preset, seed)
                        if got is None:
                            continue
                        code, alarms, summary, _, _ = got
                    else:
                        code, alarms, summary, _, _ = D.run(tmp, name, material, preset, faults, seed, 0, a.keep)
                    runs += 1
                    col = [x for x in alarms if x["code"] == "colour-drift"]
                    hits += bool(col)
                    if col:
                        firsts.append(min(x["idx"] for x in col if x["idx"] is not None))
                    gains += sum(x["code"] in ("gain-drift", "gain-step") for x in alarms)
                    c = summary.get("colour_drift")
                    if c:
                        finals.append(f"{c['k_per_h']:+.1f} ± {c['se_k_per_h']:.1f}")
                        des.append(f"{c['de00_per_h']:.3f}")
                if runs == 0:
                    continue
                first = ", ".join(f"{f} ({f / PLAN:.0%})" for f in firsts) or "–"
                t = f" ({truth:+g})" if truth is not None else " (0)"
                print(f"| {material} | {preset} | {name} | {hits} of {runs} | {first} | {', '.join(finals)}{t} | "
                      f"{', '.join(des)} | {gains} |", flush=True)


if __name__ == "__main__":
    main()
