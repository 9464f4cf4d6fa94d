"""What an anisotropic sample lets the images see, measured on kept sessions: two questions the
daemon's design rests on.

1. Can reciprocal pairs alone see a lamp step (no probes)?

In a light-outer order a pair's difference is the gain change between its two captures plus a
per-direction non-reciprocity W(light) − W(camera) (`detect::drift`, `detect::identifiability`).
A step at capture τ is identifiable, but only through the pairs of the one light direction whose
sweep τ falls in; every other straddling pair is absorbed by the W's. This script fits that model
to the exact reciprocal pairs of kept sessions (weighted least squares on the 81-node graph, the
weights from a robust scale per (θ, θ') class, two Huber passes) and reports:

- the pairs' residual scale after the W's, per layer (max of the two θ), in %: the "noise" a pair
  step test has to beat (it is the sample's own non-reciprocity, fixed by geometry, not camera
  noise);
- fault-free runs: the largest |z| of a step scan (every candidate τ in the last 1,600 captures,
  re-scanned every 81 captures), which is the threshold a pair step detector would need for no
  false alarm in that run;
- lamp steps: z of a step at its *true* onset (the best any scan can do) after 300 and 800
  captures, with the step's estimate in %.

2. How much does any pose's luminance change with arm joint 3 (the sample turning about its
normal)? A turn by δ moves both azimuths in the sample frame by δ, so the sensitivity is
∂ln Y/∂φi + ∂ln Y/∂φo, each a central difference over the ring neighbours of the plan (the
light's in the neighbouring sweeps, the camera's in the same sweep). The joint-3 sentinel needs
a pose where a 1° turn clears its own threshold (5 × √2 × 0.3 % = 2.1 %/°, `detect::sentinel`);
this is the largest |sensitivity| over every pose, off grazing (θo ≤ 60°) and at θo = 75°.

It reads the sessions `benches/probe_plan.py --keep DIR` records (probes are left out; they do not
change the pairs or the sweeps). Run:
  python3 benches/probe_plan.py --materials brushed,fabric --keep DIR   # and --presets realistic-b
  python3 benches/anisotropic_limits.py DIR [--materials brushed,fabric] [--presets realistic,realistic-b]
Prints two Markdown tables. Needs numpy (benches/requirements.txt)."""

import argparse
import glob
import json
import math
import os

import numpy as np

DIRS = 81


def ring(theta_deg):
    return int(round(theta_deg / 15.0))


def load(session):
    """Exact reciprocal pairs as (late idx, early idx, late light, late camera, ln(Y late / Y early),
    θi, θo of the late capture), sorted by the late capture."""
    caps = [json.loads(line) for line in open(os.path.join(session, "captures.jsonl"))]
    by_entry = {c["entry"]: c for c in caps if not c.get("probe") and c["status"] == "ok"}
    out = []
    for line in open(os.path.join(session, "pairs.jsonl")):
        p = json.loads(line)
        if p["status"] != "exact":
            continue
        a, b = p["entries"]
        ca, cb = by_entry.get(a), by_entry.get(b)
        if ca is None or cb is None:
            continue
        ya, yb = p["xyz_a"][1], p["xyz_b"][1]
        if ca["idx"] < cb["idx"]:
            ca, cb, ya, yb = cb, ca, yb, ya
        if not (ya > 0 and yb > 0):
            continue
        ang = ca["angles"]
        out.append((ca["idx"], cb["idx"], ca["light"], ca["camera"], math.log(ya / yb),
                    ang["theta_i_deg"], ang["theta_o_deg"]))
    out.sort()
    return out, caps


def wfit(pairs, w):
    lap = np.zeros((DIRS, DIRS))
    rhs = np.zeros(DIRS)
    for wi, (_, _, l, c, d, _, _) in zip(w, pairs):
        lap[l, l] += wi
        lap[c, c] += wi
        lap[l, c] -= wi
        lap[c, l] -= wi
        rhs[l] += wi * d
        rhs[c] -= wi * d
    lp = np.linalg.pinv(lap)
    wdir = lp @ rhs
    r = np.array([d - (wdir[l] - wdir[c]) for (_, _, l, c, d, _, _) in pairs])
    return r, lp


def class_scales(pairs, r):
    key = np.array([10 * min(ring(p[5]), ring(p[6])) + max(ring(p[5]), ring(p[6])) for p in pairs])
    s = np.zeros(len(pairs))
    for k in np.unique(key):
        m = key == k
        s[m] = max(1.4826 * np.median(np.abs(r[m])), 0.003)
    return s


def scan(pairs, now, taus):
    """z and the step estimate for a step at each τ, from the pairs complete at `now`."""
    q = [p for p in pairs if p[0] <= now]
    if len(q) < 30:
        return None
    w = np.ones(len(q))
    r, lp = wfit(q, w)
    for _ in range(2):
        s = class_scales(q, r)
        u = np.abs(r) / s
        w = np.minimum(1.0, 3.0 / np.maximum(u, 1e-9)) / s ** 2
        r, lp = wfit(q, w)
    tl = np.array([p[0] for p in q])
    te = np.array([p[1] for p in q])
    li = np.array([p[2] for p in q])
    ci = np.array([p[3] for p in q])
    x = ((te[:, None] < taus[None, :]) & (tl[:, None] >= taus[None, :])).astype(float)
    wx = w[:, None] * x
    num = (wx * r[:, None]).sum(0)
    b = np.zeros((DIRS, len(taus)))
    np.add.at(b, li, wx)
    np.add.at(b, ci, -wx)
    info = (wx * x).sum(0) - np.einsum("it,ij,jt->t", b, lp, b)
    ok = info > 1e-9
    z = np.where(ok, num / np.sqrt(np.where(ok, info, 1.0)), 0.0)
    est = np.where(ok, num / np.where(ok, info, 1.0), 0.0)
    return z, est


def layer_scales(pairs):
    r, _ = wfit(pairs, np.ones(len(pairs)))
    layer = np.array([max(ring(p[5]), ring(p[6])) for p in pairs])
    return {15 * k: 100 * 1.4826 * np.median(np.abs(r[layer == k])) for k in sorted(set(layer)) if k > 0}


def max_scan_z(pairs, every=81, window=1600):
    n = max(p[0] for p in pairs) + 1
    best = 0.0
    for now in range(5 * every, n + 1, every):
        got = scan(pairs, now, np.arange(max(1, now - window), now + 1, 2))
        if got is not None:
            best = max(best, float(np.max(np.abs(got[0]))))
    return best


def onset_z(pairs, caps, at_capture):
    first = next(c["idx"] for c in caps if c["t"] >= at_capture * 7.0 and not c.get("probe"))
    out = []
    for d in (300, 800):
        got = scan(pairs, first + d, np.array([first]))
        out.append((0.0, 0.0) if got is None else (float(got[0][0]), 100 * float(got[1][0])))
    return out


def joint3_sensitivity(session):
    """(largest |∂ln Y/∂q3| in %/° with θo ≤ 60°, its pose (θi, θo); the same at θo = 75°)."""
    caps = [json.loads(line) for line in open(os.path.join(session, "captures.jsonl"))]
    y = {(c["light"], c["camera"]): math.log(c["xyz"][1]) for c in caps
         if not c.get("probe") and c["status"] == "ok" and c["xyz"][1] > 0}
    # the plan's directions from the pole light's sweep: (θ, φ) of each camera index
    dirs = {c["camera"]: (round(c["angles"]["theta_o_deg"]), c["angles"]["phi_o_deg"] % 360.0)
            for c in caps if not c.get("probe") and c["light"] == 0}
    rings = {}
    for k, (t, p) in dirs.items():
        rings.setdefault(t, []).append((p, k))
    for t in rings:
        rings[t].sort()

    def neighbour(k, step):
        t, _ = dirs[k]
        r = rings[t]
        i = [j for j, (_, kk) in enumerate(r) if kk == k][0]
        return r[(i + step) % len(r)][1], 360.0 / len(r)

    best = {False: (0.0, None), True: (0.0, None)}
    for light, (ti, _) in dirs.items():
        if ti == 0:
            continue
        lp, dl = neighbour(light, 1)
        lm, _ = neighbour(light, -1)
        for cam, (to, _) in dirs.items():
            if to == 0:
                continue
            cp, dc = neighbour(cam, 1)
            cm, _ = neighbour(cam, -1)
            try:
                s = 100 * ((y[(light, cp)] - y[(light, cm)]) / (2 * dc) + (y[(lp, cam)] - y[(lm, cam)]) / (2 * dl))
            except KeyError:
                continue
            grazing = to > 60
            if abs(s) > best[grazing][0]:
                best[grazing] = (abs(s), (ti, to))
    return best[False], best[True]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--materials", default="brushed,fabric")
    ap.add_argument("--presets", default="realistic,realistic-b")
    a = ap.parse_args()
    sens = []
    print("| material | preset | pair residual after the W's, % (max θ = 30 / 45 / 60 / 75°) | fault-free: largest scan |z| (median, range) | −2 % step: z at its true onset after 300 / 800 captures (estimate %) |")
    print("|---|---|---|---|---|")
    for material in a.materials.split(","):
        for preset in a.presets.split(","):
            # kept sessions are named "<scenario>-<material>-<preset>-<seed>"
            ours = lambda d: os.path.basename(d).rsplit("-", 1)[0].endswith(f"-{material}-{preset}")
            ff = sorted(d for d in glob.glob(os.path.join(a.dir, "no-fault-*")) if ours(d))
            steps = sorted(d for d in glob.glob(os.path.join(a.dir, "step-*")) if ours(d))
            if not ff and not steps:
                continue
            scales, zs = [], []
            for d in ff:
                pairs, _ = load(os.path.join(d, "s"))
                scales.append(layer_scales(pairs))
                zs.append(max_scan_z(pairs))
            cells = []
            for d in steps:
                pairs, caps = load(os.path.join(d, "s"))
                at = int(os.path.basename(d).split("-at-")[1].split("-")[0])
                (z3, e3), (z8, e8) = onset_z(pairs, caps, at)
                cells.append(f"{at}: {z3:+.1f} / {z8:+.1f} ({e8:+.1f})")
            med = lambda k: np.median([s[k] for s in scales if k in s]) if scales else float("nan")
            lay = " / ".join(f"{med(k):.1f}" for k in (30, 45, 60, 75)) if scales else "–"
            zcell = (f"{np.median(zs):.1f} ({min(zs):.1f}–{max(zs):.1f}; {len(zs)} runs)" if zs else "–")
            print(f"| {material} | {preset} | {lay} | {zcell} | {'; '.join(cells) or '–'} |", flush=True)
            if ff:
                sens.append((material, preset, [joint3_sensitivity(os.path.join(d, "s")) for d in ff[:3]]))
    print()
    print("| material | preset | largest joint-3 sensitivity, θo ≤ 60° (%/°, pose θi/θo) | at θo = 75° | fault-free runs |")
    print("|---|---|---|---|---|")
    for material, preset, runs in sens:
        cell = lambda k: ", ".join(f"{r[k][0]:.2f} ({r[k][1][0]}/{r[k][1][1]})" for r in runs)
        print(f"| {material} | {preset} | {cell(0)} | {cell(1)} | {len(runs)} |", flush=True)


if __name__ == "__main__":
    main()
