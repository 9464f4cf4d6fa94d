"""Capture-to-capture scatter inside light sweeps, from kept detection sessions: how far a lamp
flicker stands above the sample's own pattern when there are no probes.

Per completed light sweep of a θi layer between 10° and 62° (the grazing layer's footprint
pattern is left out), every capture whose isotropy class has another member gets the residual
ln Y − mean ln Y of its class (over the part of the run read); along each θo ring the
differences of neighbouring cameras' residuals are taken, and their robust SD
(1.4826·MAD / √2) is the sweep's scatter. A lamp's gain that scatters from capture to capture
adds to it in quadrature; the sample's own pattern, smooth in the camera azimuth, mostly cancels
in the differences. A run is summarised by the median over its sweeps and by the largest median
of 8 consecutive sweeps (what a windowed alarm would compare against a threshold).

Only the part before a row's onset is read for the fault rows (`--before`), so the sessions of
any row serve as fault-free data up to their onset.

Run, on session folders KEEP_DIR/<name>/s with their captures.jsonl (a lab recording keeps only
its journal: replay it first, e.g. `target/release/goniowatch replay
target/lab/runs/<id>/s --out KEEP_DIR/<id>/s --recorded-outcomes`):
  python3 benches/sweep_scatter.py KEEP_DIR [KEEP_DIR...] [--match REGEX]
Prints a Markdown table: one line per session, grouped by preset and material."""

import argparse
import collections
import json
import math
import os
import re
import statistics

# onsets of the detection rows (benches/detection.py), by the words their folder name holds
ONSETS = [("late-in-the-75-layer", 5200), ("early-in-the-75-layer", 5200), ("at-mid-run", 3280),
          ("mid-run", 3280), ("sweep-boundary", 3240), ("early", 1700)]
WINDOW = 8


def onset_of(run):
    if run.startswith(("no-fault", "flicker")):
        return None
    return next((at for words, at in ONSETS if words in run), 0)


def sweep_scatter(session, upto):
    caps = []
    with open(os.path.join(session, "captures.jsonl")) as f:
        for line in f:
            c = json.loads(line)
            if c["status"] == "ok" and not c["probe"] and (upto is None or c["idx"] < upto) and c["xyz"][1] > 0:
                caps.append(c)

    def key(c):
        a = c["angles"]
        dphi = abs((a["phi_o_deg"] - a["phi_i_deg"] + 180.0) % 360.0 - 180.0)
        return round(a["theta_i_deg"]), round(a["theta_o_deg"]), round(dphi)

    classes = collections.defaultdict(list)
    for c in caps:
        classes[key(c)].append(math.log(c["xyz"][1]))
    mean = {k: statistics.fmean(v) for k, v in classes.items()}
    sweeps = collections.defaultdict(list)
    for c in caps:
        sweeps[c["light"]].append(c)
    out = []
    for light in sorted(sweeps):
        cs = sweeps[light]
        theta_i = round(cs[-1]["angles"]["theta_i_deg"])
        if not 10 <= theta_i <= 62:
            continue
        rings = collections.defaultdict(list)
        for c in cs:
            if len(classes[key(c)]) > 1:
                rings[round(c["angles"]["theta_o_deg"])].append((c["camera"], math.log(c["xyz"][1]) - mean[key(c)]))
        diffs = []
        for ring in rings.values():
            ring.sort()
            diffs += [b[1] - a[1] for a, b in zip(ring, ring[1:])]
        if len(diffs) < 10:
            continue
        m = statistics.median(diffs)
        out.append(100.0 * 1.4826 * statistics.median([abs(x - m) for x in diffs]) / math.sqrt(2.0))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("keep", nargs="+")
    ap.add_argument("--match", help="only the kept runs whose folder name matches this regular expression")
    a = ap.parse_args()
    rows = []
    for k in a.keep:
        for run in sorted(os.listdir(k)):
            s = os.path.join(k, run, "s")
            if not os.path.exists(os.path.join(s, "summary.json")) or (a.match and not re.search(a.match, run)):
                continue
            sc = sweep_scatter(s, onset_of(run))
            if len(sc) < WINDOW:
                continue
            windows = [statistics.median(sc[i - WINDOW:i]) for i in range(WINDOW, len(sc) + 1)]
            rows.append((run, statistics.median(sc), max(windows), len(sc)))
    print("| session | sweeps read | median scatter % | largest 8-sweep median % |")
    print("|---|---|---|---|")
    for run, med, top, n in rows:
        print(f"| {run} | {n} | {med:.2f} | {top:.2f} |")


if __name__ == "__main__":
    main()
