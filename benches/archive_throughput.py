"""Throughput of `goniowatch check` on a capture set of 2048 × 1536 captures, per format, against
a Python peer computing the same means over the same files on all cores (numpy with the OpenEXR
and OpenCV readers, a process per core).

    pip install -r benches/requirements.txt
    cargo build --release
    python3 benches/archive_throughput.py                 # the full 6,561 captures per format
    python3 benches/archive_throughput.py --captures 656  # a tenth of the set
    python3 benches/archive_throughput.py --peer-captures 656  # check on the whole set, the peer on a tenth

Per format the script writes `--distinct` different textures (2048 × 1536, the benchmark texture
of benches/average.rs at different phases) and gives them the Bonn names of the first
`--captures` plan entries as hard links, so the set costs `--distinct` files of disk. The files
are then in the page cache for both tools: the figures are decode and averaging, not the disk.
Every capture's mean is compared between the two (max relative difference, over R, G, B).
`--peer-captures N` runs the peer on the first N captures only (its time per capture does not
depend on the set: one process per file, nothing kept), and compares rates; check always runs on
the whole set, where its journal and session files grow. check's peak memory is /usr/bin/time's.
Prints a Markdown table for BENCHMARKS.md; the working folder is target/archive-bench.
"""

import argparse
import json
import math
import multiprocessing as mp
import os
import shutil
import subprocess
import sys
import time

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import numpy as np  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 2048, 1536
THETAS = [0, 15, 30, 45, 60, 75]
DPHI = [0, 60, 30, 20, 18, 15]
FORMATS = [
    ("hdr", ".hdr (RLE RGBE)"),
    ("exr-zip-half", ".exr ZIP half"),
    ("exr-piz-half", ".exr PIZ half"),
    ("exr-zip-float", ".exr ZIP float"),
    ("exr-piz-float", ".exr PIZ float"),
    ("png16", ".png 16-bit sRGB"),
    ("jpeg", ".jpg 8-bit sRGB"),
]


def directions():
    out = []
    for t, d in zip(THETAS, DPHI):
        if t == 0:
            out.append((0, 0))
        else:
            out.extend((t, d * k) for k in range(int(round(360 / d))))
    return out


def bonn_names(n, ext):
    dirs = directions()
    names = []
    for e in range(n):
        (tl, pl), (tv, pv) = dirs[e // len(dirs)], dirs[e % len(dirs)]
        names.append(f"tl{tl:03d}_pl{pl:03d}_tv{tv:03d}_pv{pv:03d}.{ext}")
    return names


def texture(phase):
    """benches/average.rs's texture (a smooth pattern, fine detail and hash noise), shifted."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    fx, fy = x / W, y / H
    h = (x.astype(np.uint32) * np.uint32(0x9E3779B1)) ^ (y.astype(np.uint32) * np.uint32(0x85EBCA77))
    h ^= h >> 15
    h = h * np.uint32(0x2C1B3C6D)
    n = (h >> 8).astype(np.float64) / (1 << 24)
    base = 0.5 + 4.0 * np.abs(np.sin(fx * 6.0 + phase)) * np.abs(np.cos(fy * 4.0 + phase)) + 0.2 * n
    return np.stack([base * 1.2 + 0.05, base, base * 0.7 + 8.0 * fx * fy], axis=-1).astype(np.float32)


def write(path, fmt, img):
    import cv2

    if fmt == "hdr":
        assert cv2.imwrite(path, img[..., ::-1].copy())
    elif fmt.startswith("exr"):
        import OpenEXR

        _, comp, kind = fmt.split("-")
        arr = img.astype(np.float16 if kind == "half" else np.float32)
        c = OpenEXR.ZIP_COMPRESSION if comp == "zip" else OpenEXR.PIZ_COMPRESSION
        with OpenEXR.File({"compression": c, "type": OpenEXR.scanlineimage}, {"RGB": arr}) as f:
            f.write(path)
    else:
        # sRGB-encode an exposure that puts the brightest value at 1
        lin = np.clip(img / img.max(), 0, 1)
        enc = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
        if fmt == "png16":
            assert cv2.imwrite(path, np.rint(enc * 65535).astype(np.uint16)[..., ::-1].copy())
        else:
            assert cv2.imwrite(path, np.rint(enc * 255).astype(np.uint8)[..., ::-1].copy(), [cv2.IMWRITE_JPEG_QUALITY, 95])


def ext_of(fmt):
    return {"hdr": "hdr", "png16": "png", "jpeg": "jpg"}.get(fmt, "exr")


def build_set(root, fmt, n, distinct):
    folder = os.path.join(root, fmt)
    shutil.rmtree(folder, ignore_errors=True)
    os.makedirs(folder)
    src = os.path.join(root, "src-" + fmt)
    os.makedirs(src, exist_ok=True)
    ext = ext_of(fmt)
    originals = []
    for k in range(distinct):
        p = os.path.join(src, f"t{k}.{ext}")
        if not os.path.exists(p):
            write(p, fmt, texture(0.37 * k))
        originals.append(p)
    for i, name in enumerate(bonn_names(n, ext)):
        os.link(originals[i % distinct], os.path.join(folder, name))
    # both tools read from the page cache
    for p in originals:
        with open(p, "rb") as f:
            f.read()
    return folder


# -- the peer -----------------------------------------------------------------------------------
def peer_load(path):
    if path.endswith(".exr"):
        import OpenEXR

        with OpenEXR.File(path) as f:
            ch = f.channels()
            rgb = ch["RGB"].pixels if "RGB" in ch else np.stack([ch[c].pixels for c in "RGB"], axis=-1)
        return rgb.astype(np.float32, copy=False)
    import cv2

    img = cv2.imread(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
    if img is None:
        raise RuntimeError(f"cannot decode {path}")
    img = img[..., ::-1]
    if path.endswith((".png", ".jpg")):
        top = 65535.0 if img.dtype == np.uint16 else 255.0
        lut = np.arange(int(top) + 1, dtype=np.float64) / top
        lut = np.where(lut <= 0.04045, lut / 12.92, ((lut + 0.055) / 1.055) ** 2.4).astype(np.float32)
        img = lut[img]
    return img


def peer_mean(path):
    px = peer_load(path).reshape(-1, 3)
    finite = np.isfinite(px).all(axis=1)
    return px[finite].astype(np.float64).mean(axis=0).tolist()


def run_peer(folder, names, cores):
    paths = [os.path.join(folder, n) for n in names]
    t0 = time.perf_counter()
    with mp.Pool(cores) as pool:
        means = pool.map(peer_mean, paths, chunksize=4)
    return time.perf_counter() - t0, dict(zip(names, means))


# -- goniowatch ---------------------------------------------------------------------------------
def run_check(binary, folder, session, cores):
    cfg = os.path.join(os.path.dirname(session), "bench.toml")
    with open(cfg, "w") as f:
        # the whole image, as the peer averages it; the files were just written: no settle wait
        f.write('[capture]\nroi = { kind = "full" }\n[ingest]\nsettle_ms = 0\nqueue = 64\n[source]\nkind = "files"\n')
    shutil.rmtree(session, ignore_errors=True)
    rss_file = os.path.join(os.path.dirname(session), "check.rss")
    cmd = [binary, "check", folder, "--quiet", "--config", cfg, "--session", session, "--workers", str(cores)]
    t0 = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-o", rss_file, "-f", "%M"] + cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    with open(rss_file) as f:
        rss_mb = int(f.read().split()[-1]) / 1024
    if r.returncode not in (0, 4):
        raise RuntimeError(r.stderr[-3000:])
    caps = [json.loads(line) for line in open(os.path.join(session, "captures.jsonl"))]
    return dt, {os.path.basename(c["file"]): c.get("mean_rgb") for c in caps}, caps, rss_mb


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--captures", type=int, default=6561)
    ap.add_argument("--distinct", type=int, default=4)
    ap.add_argument("--formats", default=",".join(f for f, _ in FORMATS))
    ap.add_argument("--binary", default=os.path.join(REPO, "target", "release", "goniowatch"))
    ap.add_argument("--cores", type=int, default=os.cpu_count())
    ap.add_argument("--peer-captures", type=int, default=0, help="run the peer on the first N captures only (0: all)")
    a = ap.parse_args()
    root = os.path.join(REPO, "target", "archive-bench")
    os.makedirs(root, exist_ok=True)
    wanted = a.formats.split(",")
    print(f"{a.captures} captures of {W} × {H} per format, {a.cores} cores, {a.distinct} distinct files hard-linked", file=sys.stderr)
    print("| format | check: captures | s | captures/s | peak MB | peer: captures | s | captures/s | check vs peer | max rel. diff of the means |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for fmt, label in FORMATS:
        if fmt not in wanted:
            continue
        folder = build_set(root, fmt, a.captures, a.distinct)
        names = bonn_names(a.captures, ext_of(fmt))
        t_check, ours, caps, rss_mb = run_check(a.binary, folder, os.path.join(root, fmt + ".check"), a.cores)
        bad = [c for c in caps if c["status"] != "ok"]
        if bad:
            raise RuntimeError(f"{fmt}: {len(bad)} captures not ok, e.g. {bad[0]}")
        peer_names = names[: a.peer_captures] if a.peer_captures > 0 else names
        t_peer, theirs = run_peer(folder, peer_names, a.cores)
        diff = 0.0
        for n in peer_names:
            for x, y in zip(ours[n], theirs[n]):
                diff = max(diff, abs(x - y) / max(abs(y), 1e-30))
        print(
            f"| {label} | {a.captures} | {t_check:.1f} | {a.captures / t_check:.1f} | {rss_mb:.0f} | {len(peer_names)} | {t_peer:.1f} | "
            f"{len(peer_names) / t_peer:.1f} | {(a.captures / t_check) / (len(peer_names) / t_peer):.2f}× | {diff:.1e} |",
            flush=True,
        )
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
