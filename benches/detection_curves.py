"""Detection curves and per-material figures from the runs `benches/detection.py --json` wrote.

Run (after recording a matrix with `detection.py --keep DIR`, or on its replay):
  python3 benches/detection.py --replay DIR --seeds 20 --every 0 --presets realistic,realistic-b \
      --materials walkway,ceiling,floortile,pinkwall --json runs.json > /dev/null
  python3 benches/detection_curves.py runs.json [more.json ...] [--plot docs/detection-curves.png]

Prints Markdown tables, per material and nuisance preset:
- false alarms: fault-free runs with any drift or positioning alarm (info alarms aside), and
  alarms raised before the onset of a fault;
- lamp decays: runs flagged, when (in % of the run), and the final rate against the truth;
- lamp steps: per size, runs caught within 300 captures of the onset (by any drift alarm; how
  many of them as a rate is said apart), the median delay, the fitted step;
- positioning: per axis, runs whose first `joint-offset-suspected` after the onset names the
  right axis and sign within 600 captures ("not named": no positioning alarm at all after the
  onset), and its estimate against the truth.
With `--plot` it also draws the probability of detection against the delay after onset, one
panel per fault class, one line per material and preset (matplotlib, no display needed).
A run is one simulated 6,561-capture acquisition; nothing here is timed."""

import argparse
import json
import math
import statistics

from detection import truth_rate

RUN = 6561
AXIS = {1: "joint 1", 2: "joint 2", 3: "joint 3", 4: "wagon"}


def load(paths):
    runs = []
    for p in paths:
        runs.extend(json.load(open(p)))
    # one record per (material, preset, scenario, seed, probe cadence): a later file wins
    return list({(r["material"], r["preset"], r["scenario"], r["seed"], r.get("every")): r for r in runs}.values())


def groups(runs):
    return sorted({(r["material"], r["preset"]) for r in runs})


def delay(r, key):
    a = r.get(key)
    return None if a is None else a["idx"] - r["fault"]["onset"]


def named(r):
    """The first `joint-offset-suspected` after the onset names the fault's axis with its sign."""
    a = r.get("joint_after")
    f = r["fault"]
    if a is None or a["joint"] != f["axis"]:
        return False
    return (a["offset_deg"] or 0) * f["size"] > 0


def false_alarms(runs):
    print("\n| material | preset | fault-free runs | with a false drift or positioning alarm | runs with a fault | alarmed before its onset |")
    print("|---|---|---|---|---|---|")
    for m, p in groups(runs):
        g = [r for r in runs if (r["material"], r["preset"]) == (m, p)]
        free = [r for r in g if r["fault"] is None]
        bad = [r for r in free if r["drift_after"] or r["positioning_after"]]
        faulty = [r for r in g if r["fault"] and r["fault"]["onset"] > 0]
        early = [r for r in faulty if r["drift_before"] or r["positioning_before"]]
        codes = ", ".join(sorted({(r["drift_after"] or r["positioning_after"])["code"] for r in bad}))
        print(f"| {m} | {p} | {len(free)} | {len(bad)}{f' ({codes})' if codes else ''} | {len(faulty)} | {len(early)} |")


def decays(runs):
    print("\n| material | preset | decay | runs | flagged | flagged at, % of the run: median (max) | final rate − truth, %/h: range |")
    print("|---|---|---|---|---|---|---|")
    for m, p in groups(runs):
        for form in ("rate", "rate-exp"):
            for size in (0.5, 1.0):
                g = [r for r in runs if (r["material"], r["preset"]) == (m, p) and r["fault"] and r["fault"]["kind"] == form
                     and r["fault"]["size"] == size and "joint" not in r["scenario"]]
                if not g:
                    continue
                truth = truth_rate(form, size)
                at = sorted(100 * r["drift_after"]["idx"] / RUN for r in g if r["drift_after"])
                err = [r["final_rate_pct_per_h"] - truth for r in g if r["final_rate_pct_per_h"] is not None]
                when = f"{statistics.median(at):.0f} ({max(at):.0f})" if at else "–"
                span = f"{min(err):+.3f} … {max(err):+.3f}" if err else "–"
                name = f"{'exponential' if form == 'rate-exp' else 'linear'} {size} %/h"
                print(f"| {m} | {p} | {name} | {len(g)} | {len(at)} | {when} | {span} |")


def steps(runs):
    print("\n| material | preset | step | runs | caught within 300 | caught at all (of them as a rate, `gain-drift`) | first alarm of the wrong sign | delay: median (max) | fitted step: range |")
    print("|---|---|---|---|---|---|---|---|---|")
    for m, p in groups(runs):
        for size in sorted({r["fault"]["size"] for r in runs if r["fault"] and r["fault"]["kind"] == "step"}):
            g = [r for r in runs if (r["material"], r["preset"]) == (m, p) and r["fault"] and r["fault"]["kind"] == "step"
                 and r["fault"]["size"] == size]
            if not g:
                continue
            d = sorted(x for x in (delay(r, "drift_after") for r in g) if x is not None)
            fitted = [s for r in g for s in r["steps"][:1]]
            when = f"{statistics.median(d):.0f} ({max(d)})" if d else "–"
            span = f"{min(fitted):+.2f} … {max(fitted):+.2f} %" if fitted else "–"
            as_rate = sum(1 for r in g if r["drift_after"] and r["drift_after"]["code"] == "gain-drift")
            wrong = sum(1 for r in g if r["drift_after"] and alarm_sign(r["drift_after"]) == -math.copysign(1, size))
            print(f"| {m} | {p} | {size:+g} % | {len(g)} | {sum(1 for x in d if x <= 300)} | {len(d)} ({as_rate}) | {wrong} | {when} | {span} |")


def alarm_sign(x):
    """The sign of a drift alarm's change: a step's level, a rate's slope (0 when it has neither)."""
    v = x.get("level_pct")
    if v is None:
        v = x.get("rate_pct_per_h")
    return math.copysign(1, v) if v else 0


def positioning(runs):
    print("\n| material | preset | axis | runs | named right within 600 | named wrong or late | not named | estimate / truth: median (range) |")
    print("|---|---|---|---|---|---|---|---|")
    for m, p in groups(runs):
        for axis in (1, 2, 3, 4):
            g = [r for r in runs if (r["material"], r["preset"]) == (m, p) and r["fault"] and r["fault"]["kind"] == "joint"
                 and r["fault"]["axis"] == axis and "decay" not in r["scenario"]]
            if not g:
                continue
            right = [r for r in g if named(r) and delay(r, "joint_after") <= 600]
            silent = [r for r in g if r["positioning_after"] is None]
            q = sorted(r["joint_after"]["offset_deg"] / r["fault"]["size"] for r in g if named(r))
            est = f"{statistics.median(q):.2f} ({q[0]:.2f}–{q[-1]:.2f})" if q else "–"
            print(f"| {m} | {p} | {AXIS[axis]} | {len(g)} | {len(right)} | {len(g) - len(right) - len(silent)} | {len(silent)} | {est} |")


def plot(runs, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("lamp step −1.5 %", lambda r: r["fault"]["kind"] == "step" and r["fault"]["size"] == -1.5, "drift_after", 1200),
              ("lamp step −2 … −3 %", lambda r: r["fault"]["kind"] == "step" and r["fault"]["size"] <= -2, "drift_after", 1200),
              ("lamp decay 0.5 %/h (linear and exponential)", lambda r: r["fault"]["kind"] in ("rate", "rate-exp") and r["fault"]["size"] == 0.5
               and "joint" not in r["scenario"], "drift_after", RUN),
              ("lamp decay 1 %/h (linear and exponential)", lambda r: r["fault"]["kind"] in ("rate", "rate-exp") and r["fault"]["size"] == 1.0
               and "joint" not in r["scenario"], "drift_after", RUN),
              ("joint 1 or 2 slip ±1° (named right)", lambda r: r["fault"]["kind"] == "joint" and r["fault"]["axis"] in (1, 2)
               and abs(r["fault"]["size"]) == 1 and "decay" not in r["scenario"], "named", 1200),
              ("wagon offset or backlash 1° (named right)", lambda r: r["fault"]["kind"] == "joint" and r["fault"]["axis"] == 4, "named", 1200)]
    panels = [pn for pn in panels if any(r["fault"] and pn[1](r) for r in runs)]
    if not panels:
        print(f"\nno run with a fault to plot: {path} not written")
        return
    cols = 2
    rows = (len(panels) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(11, 3.6 * rows), squeeze=False)
    for ax, (title, pick, key, horizon) in zip(axes.flat, panels):
        colours = {m: f"C{i}" for i, m in enumerate(sorted({m for m, _ in groups(runs)}))}
        for m, p in groups(runs):
            g = [r for r in runs if (r["material"], r["preset"]) == (m, p) and r["fault"] and pick(r)]
            if not g:
                continue
            if key == "named":
                d = sorted(delay(r, "joint_after") for r in g if named(r))
            else:
                d = sorted(x for x in (delay(r, key) for r in g) if x is not None)
            xs = list(range(0, horizon + 1, max(1, horizon // 200)))
            ys = [sum(1 for v in d if v <= x) / len(g) for x in xs]
            if horizon == RUN:
                xs = [100 * x / RUN for x in xs]
            ax.plot(xs, ys, label=f"{m}, {p} ({len(g)})", color=colours[m],
                    linestyle="-" if p == "realistic" else "--")
        ax.set_title(title, fontsize=10)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("% of the run" if horizon == RUN else "captures after the onset")
        ax.set_ylabel("share of runs detected")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", nargs="+", help="files written by detection.py --json")
    ap.add_argument("--plot", help="write the detection curves to this image (PNG)")
    a = ap.parse_args()
    runs = load(a.runs)
    print(f"{len(runs)} runs from {', '.join(a.runs)}")
    false_alarms(runs)
    decays(runs)
    steps(runs)
    positioning(runs)
    if a.plot:
        plot(runs, a.plot)


if __name__ == "__main__":
    main()
