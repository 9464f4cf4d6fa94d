"""The MERL export's error against the simulator's analytic BRDF, against θ, and its time.

For each uniform sample with a known BRDF (sim presets `lambert` and `ggx`, realism "clean":
noise only), the simulator writes the UBO plan's 6,561 captures, `goniowatch check` checks
them, `goniowatch export --format merl --sigma` writes the grid (timed), and the file is read
back by hil-tests/merl.py (a reader written from the format's description). At every filled
cell (or every --stride-th) the exported value is compared with albedo/π + the simulator's
specular lobe at the cell's centre; the error is given per channel-worst relative error, by θi
and by θh of the cell, with the share of cells whose error is within 2σ of the export's own σ.

Run:
  python3 benches/export_accuracy.py [--bin target/release/goniowatch] [--size 32] [--stride 5]
Prints Markdown tables (BENCHMARKS.md's "MERL export") and, with --json FILE, the numbers."""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "hil-tests"))
sys.path.insert(0, os.path.join(REPO, "sim"))
import merl  # noqa: E402
from goniosim.material import PRESETS, specular  # noqa: E402


def scenario(tmp, preset, size, seed):
    path = os.path.join(tmp, f"export-{preset}.toml")
    with open(path, "w") as f:
        f.write(
            f'rig_config = "{os.path.join(REPO, "config", "sim.toml")}"\n[session]\nid = "export-{preset}"\n'
            f'capture_root = "{tmp}"\nimage_size = [{size}, {size}]\nspeed = 0\nseed = {seed}\n'
            f'[material]\npreset = "{preset}"\nrealism = "clean"\n'
        )
    return path


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} exited {r.returncode}:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    return r


def session_for(binary, tmp, preset, size, seed):
    """Write, check; returns the session folder."""
    run([sys.executable, "-m", "goniosim", "archive", scenario(tmp, preset, size, seed), "--out", tmp, "--naming", "bonn"], cwd=os.path.join(REPO, "sim"))
    session = os.path.join(tmp, f"{preset}.check")
    run([binary, "check", os.path.join(tmp, f"export-{preset}"), "--config", os.path.join(REPO, "config", "sim.toml"), "--session", session, "--quiet"])
    return session


def export(binary, session, out, threads=None, nodes=None, across=None):
    """Export the MERL file and its σ; returns the wall time (s)."""
    cmd = [binary, "export", session, "--format", "merl", "--out", out, "--sigma", out + ".sigma"]
    if across:
        cmd += ["--across-layers", across]
    if nodes:
        cmd += ["--fit-nodes", str(nodes[0]), "--weight-nodes", str(nodes[1])]
    if threads:
        cmd += ["--threads", str(threads)]
    t0 = time.perf_counter()
    run(cmd)
    return time.perf_counter() - t0


def truth(preset, wi, wo):
    m = PRESETS[preset]
    s = specular(wi, wo, m)
    return np.array([a / math.pi + s for a in m.albedo])


def cell_errors(path, preset, stride):
    """Per sampled filled cell: (θi°, θh°, worst relative error, error / σ worst)."""
    brdf = merl.read(path)
    sigma = merl.read(path + ".sigma")
    filled = np.argwhere(~np.isnan(brdf[1]))
    out = []
    for ih, id_, ip in filled[::stride]:
        wi, wo = merl.cell_directions(ih, id_, ip)
        f = truth(preset, wi, wo)
        got = brdf[:, ih, id_, ip]
        sg = sigma[:, ih, id_, ip]
        rel = np.abs(got - f) / f
        zs = np.abs(got - f) / np.maximum(sg, 1e-12)
        theta_i = math.degrees(math.acos(max(-1.0, min(1.0, wi[2]))))
        theta_h = ((ih + 0.5) / 90.0) ** 2 * 90.0
        out.append((theta_i, theta_h, float(rel.max()), float(zs.max())))
    return out, int(filled.shape[0])


def capture_bias(session, preset):
    """The corrected captures themselves against the analytic BRDF at their own directions:
    median ratio (worst channel's departure) — what the export cannot do better than."""
    ratios = []
    for line in open(os.path.join(session, "export", "captures-table.jsonl")):
        r = json.loads(line)
        if not r["in_grid"]:
            continue
        wi = merl.direction(r["theta_i_deg"], r["phi_i_deg"])
        wo = merl.direction(r["theta_o_deg"], r["phi_o_deg"])
        f = truth(preset, wi, wo)
        ratios.append(np.array([r["brdf_r"], r["brdf_g"], r["brdf_b"]]) / f)
    ratios = np.array(ratios)
    return [float(np.median(ratios[:, c])) for c in range(3)], float(np.quantile(np.abs(ratios - 1).max(axis=1), 0.95))


def capture_errors(path, session, scatter):
    """At each capture's own direction: the file read there (trilinear between cell centres)
    against the corrected capture (the table's BRDF), relative, and in units of
    √(σ² + (scatter × value)²): the cells' interpolation σ with one capture's own scatter."""
    brdf = merl.read(path)
    sigma = merl.read(path + ".sigma")
    rows = [json.loads(line) for line in open(os.path.join(session, "export", "captures-table.jsonl"))]
    out = []
    for r in rows:
        if not r["in_grid"] or r["theta_i_deg"] is None:
            continue
        wi = merl.direction(r["theta_i_deg"], r["phi_i_deg"])
        wo = merl.direction(r["theta_o_deg"], r["phi_o_deg"])
        got = merl.lookup_trilinear(brdf, wi, wo)
        sg = np.sqrt(merl.lookup_trilinear(sigma, wi, wo) ** 2 + (scatter * got) ** 2)
        if np.isnan(got).any():
            out.append((r["theta_i_deg"], r["theta_o_deg"], None, None))
            continue
        want = np.array([r["brdf_r"], r["brdf_g"], r["brdf_b"]])
        out.append((r["theta_i_deg"], r["theta_o_deg"], float((np.abs(got - want) / want).max()), float((np.abs(got - want) / np.maximum(sg, 1e-12)).max())))
    return out


def q(xs, p):
    return float(np.quantile(np.asarray(xs), p)) if xs else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(REPO, "target", "release", "goniowatch"))
    ap.add_argument("--presets", default="lambert,ggx")
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--stride", type=int, default=5, help="compare every STRIDE-th filled cell")
    ap.add_argument("--nodes", help="NC,NW of the interpolant (default: the export's)")
    ap.add_argument("--across-layers", help="cosine-weighted or brdf (default: the export's)")
    ap.add_argument("--json")
    a = ap.parse_args()
    results = {}
    for preset in a.presets.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            session = session_for(a.bin, tmp, preset, a.size, a.seed)
            run([a.bin, "export", session, "--format", "table"])
            path = os.path.join(tmp, "brdf.binary")
            nodes = tuple(int(x) for x in a.nodes.split(",")) if a.nodes else None
            times = {t: export(a.bin, session, path, t, nodes, a.across_layers) for t in (1, 2)}
            side = json.load(open(path + ".json"))
            scatter = (side.get("capture_scatter") or {}).get("relative_pct", 0.0) / 100.0
            cells, filled = cell_errors(path, preset, a.stride)
            caps = capture_errors(path, session, scatter)
            bias, bias95 = capture_bias(session, preset)
        bins = [(0, 15), (15, 30), (30, 45), (45, 60), (60, 76)]
        by_ti = []
        for lo, hi in bins:
            sel = [c for c in cells if lo <= c[0] < hi]
            by_ti.append({"theta_i": f"{lo}–{min(hi, 75)}°", "cells": len(sel), "median": q([c[2] for c in sel], 0.5), "p95": q([c[2] for c in sel], 0.95), "max": max([c[2] for c in sel], default=float("nan")), "within_2sigma": sum(c[3] <= 2 for c in sel) / max(len(sel), 1)})
        hbins = [(0, 2), (2, 10), (10, 30), (30, 90)]
        by_th = []
        for lo, hi in hbins:
            sel = [c for c in cells if lo <= c[1] < hi]
            by_th.append({"theta_h": f"{lo}–{hi}°", "cells": len(sel), "median": q([c[2] for c in sel], 0.5), "p95": q([c[2] for c in sel], 0.95), "max": max([c[2] for c in sel], default=float("nan")), "within_2sigma": sum(c[3] <= 2 for c in sel) / max(len(sel), 1)})
        covered = [c for c in caps if c[2] is not None]
        results[preset] = {
            "filled": filled,
            "filled_fraction_above_horizon": side["filled_fraction_above_horizon"],
            "seconds": times,
            "by_theta_i": by_ti,
            "by_theta_h": by_th,
            "capture_scatter_pct": 100 * scatter,
            "capture_ratio_median_rgb": bias,
            "capture_error_p95": bias95,
            "captures": {"n": len(caps), "looked_up": len(covered), "median": q([c[2] for c in covered], 0.5), "p95": q([c[2] for c in covered], 0.95), "within_1sigma": sum(c[3] <= 1 for c in covered) / max(len(covered), 1), "within_2sigma": sum(c[3] <= 2 for c in covered) / max(len(covered), 1)},
        }
    print(f"{a.size} × {a.size} px, seed {a.seed}, interpolant nodes {a.nodes or 'default'}, across layers {a.across_layers or 'default'}, every {a.stride}th filled cell; relative error = |exported − analytic| / analytic, worst channel\n")
    for preset, r in results.items():
        print(f"**{preset}**: {r['filled']:,} cells filled ({100 * r['filled_fraction_above_horizon']:.1f} % of those above the horizon); export {r['seconds'][1]:.2f} s on 1 thread, {r['seconds'][2]:.2f} s on 2\n")
        print("| θi of the cell | cells | median | 95 % | max | within 2σ |\n|---|---|---|---|---|---|")
        for b in r["by_theta_i"]:
            print(f"| {b['theta_i']} | {b['cells']:,} | {100 * b['median']:.2f} % | {100 * b['p95']:.2f} % | {100 * b['max']:.1f} % | {100 * b['within_2sigma']:.0f} % |")
        print("\n| θh of the cell | cells | median | 95 % | max | within 2σ |\n|---|---|---|---|---|---|")
        for b in r["by_theta_h"]:
            print(f"| {b['theta_h']} | {b['cells']:,} | {100 * b['median']:.2f} % | {100 * b['p95']:.2f} % | {100 * b['max']:.1f} % | {100 * b['within_2sigma']:.0f} % |")
        print(f"\nThe corrected captures themselves against the analytic BRDF at their own directions: median ratio R {r['capture_ratio_median_rgb'][0]:.4f}, G {r['capture_ratio_median_rgb'][1]:.4f}, B {r['capture_ratio_median_rgb'][2]:.4f}; 95 % within {100 * r['capture_error_p95']:.2f} %")
        c = r["captures"]
        print(f"\nAt the {c['n']:,} captures' own directions (the file read there, trilinear between cell centres, against the corrected capture): {c['looked_up']:,} where the file has a value; median {100 * c['median']:.2f} %, 95 % {100 * c['p95']:.2f} %; within 1σ {100 * c['within_1sigma']:.0f} %, within 2σ {100 * c['within_2sigma']:.0f} % (σ: the cells' interpolation σ with one capture's scatter, {r['capture_scatter_pct']:.2f} %)\n")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
