"""The detection tables and curves, made from the records `benches/detection.py score` writes.

  python3 benches/detection_tables.py [RECORDS] [--write] [--plot docs/detection-curves.png]

RECORDS defaults to benches/detection-records.json. Without --write it prints the tables; with
--write it puts them into BENCHMARKS.md and README.md between their markers
(`<!-- detection:NAME -->` … `<!-- /detection:NAME -->`), so that no detection figure there is
typed by hand. `tables(records)` is a pure function of the records (tested against a fixture).

How a run is judged (the onset is the fault's first capture; a fault-free run's is 0):
- a drift alarm is any `drift` alarm that raises (not one cleared or withdrawn) other than
  `lamp-unstable`; a positioning alarm is a `positioning` alarm of warning severity or above;
- a lamp step is caught when a drift alarm comes within 300 captures of the onset; its sign is
  wrong when the alarm's level or rate has the other sign; it is taken for a joint when a
  `joint-offset-suspected` follows the onset (a `gain-step` it explains is then withdrawn);
- a decay is flagged by any drift alarm; its final rate is compared with the mean ln-gain slope
  of the true decay over the run;
- a positioning fault is named right when the first `joint-offset-suspected`,
  `wagon-backlash-suspected` or `wagon-offset-suspected` after the onset names its axis (the
  wagon is axis 4; its lag as `wagon-backlash-suspected`, its offset as
  `wagon-offset-suspected`) with its sign within 600 captures; named wrong when a positioning alarm after the onset names another axis
  or sign (or comes late); a `camera-pose-moved` (the wagon or joint 1, not told apart) is
  counted on its own;
- a flickering lamp is flagged by `lamp-unstable` within 1,000 captures;
- an encoder episode is right when after its onset there is an `encoder-mismatch` and neither
  a drift nor a `joint-offset-suspected` alarm;
- a false alarm is a drift or positioning alarm in a fault-free run, or before a fault's onset.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from detection import truth_rate  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RUN = 6561
AXIS = {1: "joint 1", 2: "joint 2", 3: "joint 3", 4: "wagon"}
STEP_WITHIN, JOINT_WITHIN, FLICKER_WITHIN = 300, 600, 1000


def load(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as f:
        return json.load(f)["records"]


def delay(r: dict, key: str):
    a = r.get(key)
    return None if a is None else a["idx"] - r["fault"]["onset"]


def alarm_sign(x: dict) -> float:
    v = x.get("level_pct")
    if v is None:
        v = x.get("rate_pct_per_h")
    return math.copysign(1, v) if v else 0


def named(r: dict) -> bool:
    a, f = r.get("joint_after"), r["fault"]
    if a is None or a["joint"] != f["axis"] or (a["offset_deg"] or 0) * f["size"] <= 0:
        return False
    # the wagon's lag is named as a lag, its constant offset as an offset
    return f["axis"] != 4 or (a["code"] == "wagon-backlash-suspected") == ("backlash" in r["row"])


def wrong_kind(r: dict) -> bool:
    """The wagon named with the other of its faults: a lag as an offset, or the reverse."""
    a, f = r.get("joint_after"), r["fault"]
    return (a is not None and f["axis"] == 4 and a["joint"] == 4
            and (a["code"] == "wagon-backlash-suspected") != ("backlash" in r["row"]))


def false_alarm(r: dict) -> bool:
    """A drift or positioning alarm in a fault-free run (a `lamp-unstable` too: the lamp is
    steady there), or one before a fault's onset."""
    if r["fault"] is None:
        return bool(r["drift_after"] or r["positioning_after"] or r.get("unstable_after"))
    return bool(r["drift_before"] or r["positioning_before"])


def median_max(xs) -> str:
    xs = sorted(xs)
    return f"{statistics.median(xs):.0f} ({max(xs):.0f})" if xs else "–"


def signed(text: str) -> str:
    """A number as the tables print it: a true minus sign."""
    return text.replace("-", "−")


def span(xs, fmt="{:+.2f}") -> str:
    return signed(f"{fmt.format(min(xs))} … {fmt.format(max(xs))}") if xs else "–"


def by_row(records):
    rows = {}
    for r in records:
        rows.setdefault((r["row"], r["every"], r["material"] in ("brushed", "fabric")), []).append(r)
    return rows


def of(n, m) -> str:
    return f"{n} of {m}"


def table(header, rows) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def models(records):
    return sorted({r["model"] for r in records})


def fault_models(records):
    """The models the fault rows run on (the fault-free-only image sizes have no column)."""
    return models([r for r in records if r["fault"]])


def false_alarm_table(records) -> str:
    rows = []
    for every in sorted({r["every"] for r in records}):
        for m in sorted({r["material"] for r in records if r["every"] == every}):
            for p in models(records):
                g = [r for r in records if (r["material"], r["model"], r["every"]) == (m, p, every)]
                if not g:
                    continue
                free = [r for r in g if r["fault"] is None]
                faulty = [r for r in g if r["fault"] and r["fault"]["onset"] > 0]
                bad = [r for r in free if false_alarm(r)]
                codes = sorted({x["code"] for r in bad
                                for x in (r["drift_after"], r["positioning_after"], r.get("unstable_after")) if x})
                early = [r for r in faulty if false_alarm(r)]
                rows.append([m, p, f"every {every}" if every else "none", len(free),
                             f"{len(bad)}" + (f" ({', '.join(codes)})" if codes else ""), len(faulty), len(early)])
    return table(["material", "model", "probes", "fault-free runs", "with a drift, positioning or lamp-unstable alarm",
                  "runs with a later fault", "alarmed before the onset"], rows)


def step_table(records) -> str:
    rows = []
    for (name, every, aniso), g in by_row(records).items():
        if not g[0]["fault"] or g[0]["fault"]["kind"] != "step":
            continue
        cells = [name, f"every {every}" if every else "none"] + (["anisotropic"] if aniso else ["isotropic"])
        for p in fault_models(records):
            h = [r for r in g if r["model"] == p]
            d = [x for x in (delay(r, "drift_after") for r in h) if x is not None]
            cells.append(of(sum(1 for x in d if x <= STEP_WITHIN), len(h)) if h else "–")
        d = [x for x in (delay(r, "drift_after") for r in g) if x is not None]
        size = g[0]["fault"]["size"]
        wrong = sum(1 for r in g if r["drift_after"] and alarm_sign(r["drift_after"]) == -math.copysign(1, size))
        fitted = [s for r in g for s in r["steps"][:1]]
        as_joint = sum(1 for r in g if r["joint_after"])
        cells += [of(len(d), len(g)), wrong, as_joint, median_max(d), span(fitted) + (" %" if fitted else "")]
        rows.append(cells)
    return table(["row", "probes", "sample"] + [f"within {STEP_WITHIN}, {p}" for p in fault_models(records)]
                 + ["caught at all", "first alarm of the wrong sign", "taken for a joint", "delay (captures): median (max)",
                    "fitted step"], rows)


def decay_table(records) -> str:
    rows = []
    for (name, every, aniso), g in by_row(records).items():
        f = g[0]["fault"]
        if not f or f["kind"] not in ("rate", "rate-exp"):
            continue
        truth = truth_rate(f["kind"], f["size"])
        at = [100 * r["drift_after"]["idx"] / RUN for r in g if r["drift_after"]]
        err = [r["final_rate_pct_per_h"] - truth for r in g if r["final_rate_pct_per_h"] is not None]
        within = sum(1 for e in err if abs(e) <= 0.1)
        rows.append([name, f"every {every}" if every else "none", len(g), len(at), median_max(at),
                     signed(f"{truth:+.3f}"), span(err, "{:+.3f}"), of(within, len(err))])
    return table(["row", "probes", "runs", "flagged", "flagged at, % of the run: median (max)", "truth, %/h",
                  "final rate − truth, %/h", "within ±0.1 %/h"], rows)


def positioning_table(records) -> str:
    rows = []
    for (name, every, aniso), g in by_row(records).items():
        f = g[0]["fault"]
        if not f or f["kind"] != "joint":
            continue
        cells = [name, f"every {every}" if every else "none"]
        for p in fault_models(records):
            h = [r for r in g if r["model"] == p]
            cells.append(of(sum(1 for r in h if named(r) and delay(r, "joint_after") <= JOINT_WITHIN), len(h)) if h else "–")
        right = [r for r in g if named(r) and delay(r, "joint_after") <= JOINT_WITHIN]
        silent = [r for r in g if r["positioning_after"] is None]
        untold = [r for r in g if r["joint_after"] is None and "camera-pose-moved" in r["codes_after"]]
        wrong_axis = [r for r in g if r["joint_after"] and (r["joint_after"]["joint"] != f["axis"] or wrong_kind(r))]
        q = sorted(r["joint_after"]["offset_deg"] / f["size"] for r in g if named(r))
        est = f"{statistics.median(q):.2f} ({q[0]:.2f} … {q[-1]:.2f})" if q else "–"
        rows.append(cells + [of(len(right), len(g)), len(wrong_axis), len(untold), len(silent), est])
    return table(["row", "probes"] + [f"named right within {JOINT_WITHIN}, {p}" for p in fault_models(records)]
                 + ["named right", "named as another axis (or the wagon's other fault)",
                    "`camera-pose-moved`: the wagon or joint 1, not told", "no positioning alarm",
                    "estimate / truth: median (range)"], rows)


def other_table(records) -> str:
    rows = []
    for (name, every, aniso), g in by_row(records).items():
        f = g[0]["fault"]
        if not f or f["kind"] not in ("encoder", "unstable"):
            continue
        if f["kind"] == "unstable":
            ok = [r for r in g if r["unstable_after"] and delay(r, "unstable_after") <= FLICKER_WITHIN]
            what = f"`lamp-unstable` within {FLICKER_WITHIN} captures"
        else:
            ok = [r for r in g if "encoder-mismatch" in r.get("codes_after", []) and not r["drift_after"]
                  and not r["joint_after"]]
            what = "`encoder-mismatch`, no drift or joint alarm"
        codes = sorted({c for r in g for c in r.get("codes_after", [])})
        rows.append([name, f"every {every}" if every else "none", what, of(len(ok), len(g)), ", ".join(codes) or "–"])
    return table(["row", "probes", "right when", "right", "alarm codes after the onset (all runs)"], rows)


def curve_table(records) -> str:
    """The isotropy drift-rate estimate's error against hours into the run (no probes)."""
    hours = ["1", "2", "3", "4", "6", "8", "10", "12"]
    rows = []
    for (name, every, aniso), g in by_row(records).items():
        f = g[0]["fault"]
        if every or not f or f["kind"] not in ("rate", "rate-exp") or "joint" in name:
            continue
        cells = [name, len(g)]
        for h in hours:
            errs = [abs(r["curve"][h][0] - truth_rate(f["kind"], f["size"], float(h))) for r in g if h in (r.get("curve") or {})]
            cells.append(f"{statistics.median(errs):.3f} ({max(errs):.3f})" if errs else "–")
        rows.append(cells)
    return table(["row", "runs"] + [f"{h} h" for h in hours], rows)


def _catches_lines(records) -> list[list[str]]:
    """The compact table's rows for one set of records: per fault class, without and with probes."""
    def share(pick, ok):
        g = [r for r in records if r["fault"] and pick(r)]
        return of(sum(1 for r in g if ok(r)), len(g)) if g else "–"

    iso = [r for r in records if r["material"] not in ("brushed", "fabric")]
    lines = []
    for every in (0, 75):
        rs = [r for r in iso if r["every"] == every]
        free = [r for r in rs if r["fault"] is None]
        lines.append(["no fault (false drift, positioning or lamp-unstable alarms)", "every 75" if every else "none",
                      of(sum(1 for r in free if false_alarm(r)), len(free)) if free else "–"])
        for size in (-1.5, -2.0, -3.0, 1.5):
            lines.append([f"lamp step {signed(f'{size:+g}')} %, within {STEP_WITHIN} captures", "every 75" if every else "none",
                          share(lambda r, s=size: r in rs and r["fault"]["kind"] == "step" and r["fault"]["size"] == s,
                                lambda r: (delay(r, "drift_after") or 10**9) <= STEP_WITHIN)])
        lines.append(["lamp decay 0.5 %/h, flagged before 25 % of the run", "every 75" if every else "none",
                      share(lambda r: r in rs and r["fault"]["kind"] in ("rate", "rate-exp") and r["fault"]["size"] == 0.5
                            and "joint" not in r["row"], lambda r: r["drift_after"] is not None and r["drift_after"]["idx"] <= RUN / 4)])
        lines.append([f"lamp flicker 3 %, within {FLICKER_WITHIN} captures", "every 75" if every else "none",
                      share(lambda r: r in rs and r["fault"]["kind"] == "unstable",
                            lambda r: r["unstable_after"] is not None and delay(r, "unstable_after") <= FLICKER_WITHIN)])
        # the wagon's lag (backlash) and its constant offset are separate rows: the sweeps name the
        # lag, a re-captured pair (probes) the offset
        for label, axis, lag in (("joint 1 slip", 1, None), ("joint 2 slip", 2, None),
                                 ("wagon backlash", 4, True), ("wagon offset", 4, False)):
            lines.append([f"{label}, named right within {JOINT_WITHIN} captures", "every 75" if every else "none",
                          share(lambda r, a=axis, b=lag: r in rs and r["fault"]["kind"] == "joint" and r["fault"]["axis"] == a
                                and (b is None or ("backlash" in r["row"]) == b),
                                lambda r: named(r) and delay(r, "joint_after") <= JOINT_WITHIN)])
    aniso = [r for r in records if r["material"] in ("brushed", "fabric")]
    lines.append(["anisotropic: joint 3 +1°, named right within 600 captures", "every 75",
                  share(lambda r: r in aniso and r["fault"]["kind"] == "joint", lambda r: named(r) and delay(r, "joint_after") <= JOINT_WITHIN)
                  if aniso else "–"])
    free = [r for r in aniso if r["fault"] is None]
    lines.append(["anisotropic: no fault (false alarms)", "every 75", of(sum(1 for r in free if false_alarm(r)), len(free)) if free else "–"])
    return lines


# the nuisance models detectors were designed and tuned on, at the lab's image size; every
# other model or size is out of sample
DESIGN_MODELS = ("realistic", "realistic-b")


def catches(records) -> str:
    """The README's compact table: per fault class, without and with probes, on the models the
    detectors were designed on and, beside it, out of sample."""
    inside = [r for r in records if r["model"] in DESIGN_MODELS]
    outside = [r for r in records if r["model"] not in DESIGN_MODELS]
    rows = [[a[0], a[1], a[2], b[2]] for a, b in zip(_catches_lines(inside), _catches_lines(outside))]
    rows = [r for r in rows if (r[2], r[3]) != ("–", "–")]
    iso = [r for r in records if r["material"] not in ("brushed", "fabric")]
    n_in = len({r["model"] for r in inside})
    labels = {r["model"] for r in outside}
    kinds = (["a model not designed on"] if any(m.split(",")[0] not in DESIGN_MODELS for m in labels) else []) \
        + (["other image sizes"] if any("," in m for m in labels) else [])
    out_models = ", ".join(kinds) or "none"
    return table([f"fault (simulated rig: {len({r['material'] for r in iso})} isotropic materials)", "probes",
                  f"runs right, the {n_in} models designed on", f"runs right, out of sample ({out_models})"], rows)


def tables(records: list[dict]) -> dict[str, str]:
    """Every generated block, by marker name."""
    n = len(records)
    return {
        "count": f"{n} runs scored.",
        "false-alarms": false_alarm_table(records),
        "steps": step_table(records),
        "decays": decay_table(records),
        "curve": curve_table(records),
        "positioning": positioning_table(records),
        "other": other_table(records),
        "catches": catches(records),
    }


def fill(text: str, blocks: dict[str, str]) -> str:
    """`text` with every `<!-- detection:NAME -->` … `<!-- /detection:NAME -->` block replaced
    by its generated content (a marker without a block is an error)."""
    def sub(m):
        name = m.group(1)
        if name not in blocks:
            raise KeyError(f"no generated block named {name!r}")
        return f"<!-- detection:{name} -->\n{blocks[name]}\n<!-- /detection:{name} -->"

    return re.sub(r"<!-- detection:([a-z-]+) -->.*?<!-- /detection:\1 -->", sub, text, flags=re.S)


def plot(records, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    iso = [r for r in records if r["fault"] and r["material"] not in ("brushed", "fabric") and not r["every"]]
    panels = [("lamp step −1.5 %", lambda r: r["fault"]["kind"] == "step" and r["fault"]["size"] == -1.5, "drift_after", 1200),
              ("lamp step −2 … −3 %", lambda r: r["fault"]["kind"] == "step" and r["fault"]["size"] <= -2, "drift_after", 1200),
              ("lamp decay 0.5 %/h", lambda r: r["fault"]["kind"] in ("rate", "rate-exp") and r["fault"]["size"] == 0.5
               and "joint" not in r["row"], "drift_after", RUN),
              ("joint 1 slip (named right)", lambda r: r["fault"]["kind"] == "joint" and r["fault"]["axis"] == 1, "named", 1200),
              ("joint 2 slip (named right)", lambda r: r["fault"]["kind"] == "joint" and r["fault"]["axis"] == 2, "named", 1200),
              ("wagon offset or backlash (named right)", lambda r: r["fault"]["kind"] == "joint" and r["fault"]["axis"] == 4, "named", 1200)]
    panels = [pn for pn in panels if any(pn[1](r) for r in iso)]
    if not panels:
        return False
    fig, axes = plt.subplots((len(panels) + 1) // 2, 2, figsize=(11, 3.4 * ((len(panels) + 1) // 2)), squeeze=False)
    groups = sorted({(r["material"], r["model"]) for r in iso})
    colours = {m: f"C{i}" for i, m in enumerate(sorted({m for m, _ in groups}))}
    for ax, (title, pick, key, horizon) in zip(axes.flat, panels):
        for m, p in groups:
            g = [r for r in iso if (r["material"], r["model"]) == (m, p) and pick(r)]
            if not g:
                continue
            d = sorted(delay(r, "joint_after") for r in g if named(r)) if key == "named" else \
                sorted(x for x in (delay(r, key) for r in g) if x is not None)
            xs = list(range(0, horizon + 1, max(1, horizon // 200)))
            ys = [sum(1 for v in d if v <= x) / len(g) for x in xs]
            if horizon == RUN:
                xs = [100 * x / RUN for x in xs]
            ax.plot(xs, ys, label=f"{m}, {p} ({len(g)})", color=colours[m], linestyle="-" if p == "realistic" else "--")
        ax.set_title(title, fontsize=10)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("% of the run" if horizon == RUN else "captures after the onset")
        ax.set_ylabel("share of runs")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.suptitle("Detection without probes: share of runs detected against the delay after the onset", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=80, metadata={"Software": None})
    return True


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("records", nargs="?", default=os.path.join(REPO, "benches", "detection-records.json"))
    ap.add_argument("--write", action="store_true", help="fill the blocks of BENCHMARKS.md and README.md")
    ap.add_argument("--plot", help="draw the detection curves to this PNG")
    a = ap.parse_args()
    blocks = tables(load(a.records))
    if a.write:
        for doc in ("BENCHMARKS.md", "README.md"):
            path = os.path.join(REPO, doc)
            with open(path, encoding="utf-8") as f:
                text = f.read()
            new = fill(text, blocks)
            if new != text:
                with open(path, "w", encoding="utf-8") as f:
                    f.write(new)
                print(f"{doc}: tables written")
    else:
        for name, text in blocks.items():
            print(f"## {name}\n\n{text}\n")
    if a.plot:
        plot(load(a.records), a.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
