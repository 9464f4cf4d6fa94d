"""Colour-drift detection: full 6,561-capture simulated runs, without probes (isotropy classes) or
with drift probes (`--every N`, or `--every plan` for the cadence `goniowatch plan` recommends), a
3000 K lamp cooling by `--rate` K/h from the start (`lamp-colour-drift`) and fault-free runs,
per material, nuisance preset and seed. Reports the `colour-drift` alarms of fault-free runs,
when the drift was first flagged (captures, and the fraction of the run), the final estimate in
K/h against the truth, its standard error and ΔE00/h, and any gain alarm the colour drift caused.

Run (after `cargo build --release`):
  python3 benches/colour_drift.py [--seeds 3] [--fault-free-seeds 10] [--first-seed 1] [--rate -20]
                                  [--materials walkway,ceiling,floortile,pinkwall]
                                  [--presets realistic,realistic-b] [--every 0|N|plan] [--only TEXT] [--keep DIR]
  python3 benches/colour_drift.py --replay DIR [...]   # re-score kept sessions with the current binary
The anisotropic materials (brushed, fabric) run with config/sim-anisotropic.toml, the others with
config/sim.toml. With probes, "first flagged" counts regular captures (probes left out), so the
fraction of the run is comparable with the runs without probes.
Prints a Markdown table. Uses benches/detection.py's runner (same rig config, 16 × 16 images)."""

import argparse
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import detection as D  # noqa: E402
import probe_plan as P  # noqa: E402

PLAN = 6561
ANISOTROPIC = {"brushed", "fabric"}


def cadence(every, config):
    """The probe cadence: a number, or the one `goniowatch plan` recommends for `config`."""
    return int(every) if every != "plan" else P.plan_cadence(config)


def regular_index(session, idx):
    """Regular captures before capture `idx` in a kept session (probes left out)."""
    path = os.path.join(session, "captures.jsonl")
    if not os.path.exists(path):
        return idx
    return P.regular_index([json.loads(line) for line in open(path)], idx)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--fault-free-seeds", type=int, default=0, help="seeds for the fault-free rows (default: --seeds)")
    ap.add_argument("--rate", type=float, default=-20.0, help="K/h of the drifting lamp")
    ap.add_argument("--materials", default="walkway,ceiling,floortile,pinkwall")
    ap.add_argument("--presets", default="realistic,realistic-b")
    ap.add_argument("--only", help="run only the scenarios whose name contains this text")
    ap.add_argument("--every", default="0", help="drift probes every N captures, or 'plan' (default 0: none)")
    ap.add_argument("--keep", help="keep the recorded sessions in this folder")
    ap.add_argument("--replay", help="re-score the sessions kept in this folder")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="gw-colour-")
    # with probes the scoring reads the captures: the sessions are kept (in tmp without --keep)
    keep = a.keep or (os.path.join(tmp, "keep") if a.every != "0" else None)
    scenarios = [
        ("no fault", [], None),
        (f"colour {a.rate:+g} K/h", [{"kind": "lamp-colour-drift", "at_capture": 0, "cct_k_per_h": a.rate}], a.rate),
    ]
    scenarios = [sc for sc in scenarios if not a.only or a.only in sc[0]]
    print(f"{'No probes (isotropy classes)' if a.every == '0' else 'Drift probes every ' + a.every}, {a.seeds} seeds per fault row, {a.fault_free_seeds or a.seeds} per fault-free row, full {PLAN}-capture runs, "
          f"{'replayed from ' + a.replay if a.replay else 'live'}.\n")
    print("| material | preset | scenario | runs with a colour-drift alarm | first flagged: capture (fraction of the run) | final K/h ± SE (truth) | ΔE00/h | gain alarms |")
    print("|---|---|---|---|---|---|---|---|")
    for material in a.materials.split(","):
        config = "sim-anisotropic.toml" if material in ANISOTROPIC else "sim.toml"
        every = cadence(a.every, config)
        for preset in a.presets.split(","):
            for base, faults, truth in scenarios:
                # the probe runs carry the cadence in their name, as benches/probe_plan.py's do
                name = f"{base} every {every}" if every else base
                hits, firsts, finals, des, gains, runs = 0, [], [], [], 0, 0
                n = a.fault_free_seeds if (truth is None and a.fault_free_seeds) else a.seeds
                for seed in range(a.first_seed, a.first_seed + n):
                    if a.replay:
                        got = D.replay(a.replay, name, material, preset, seed)
                        if got is None:
                            continue
                        code, alarms, summary, _, _ = got
                    else:
                        code, alarms, summary, _, _ = D.run(tmp, name, material, preset, faults, seed, every, keep, config)
                    runs += 1
                    col = [x for x in alarms if x["code"] == "colour-drift"]
                    hits += bool(col)
                    if col:
                        first_idx = min(x["idx"] for x in col if x["idx"] is not None)
                        if every:
                            session = os.path.join(a.replay or keep, D.run_name(name, material, preset, seed), "s")
                            first_idx = regular_index(session, first_idx)
                        firsts.append(first_idx)
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
