"""Python peer for benches/average.rs: the same decode + mean with numpy and the OpenEXR /
OpenCV readers. Prints one JSON line per file: median seconds over --repeat runs and the mean
linear RGB over finite pixels (float64 accumulation, like goniowatch)."""
import argparse
import json
import os
import statistics
import time

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import numpy as np  # noqa: E402


def load(path):
    if path.endswith(".exr"):
        import OpenEXR

        with OpenEXR.File(path) as f:
            ch = f.channels()
            if "RGB" in ch:
                rgb = ch["RGB"].pixels
            else:
                rgb = np.stack([ch[c].pixels for c in "RGB"], axis=-1)
        return rgb.astype(np.float32, copy=False)
    import cv2

    bgr = cv2.imread(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
    if bgr is None:
        raise RuntimeError(f"cannot decode {path}")
    return bgr[..., ::-1]


def mean_rgb(rgb):
    px = rgb.reshape(-1, 3)
    finite = np.isfinite(px).all(axis=1)
    return px[finite].astype(np.float64).mean(axis=0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=9)
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    for path in a.files:
        times, decode_times = [], []
        m = None
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            rgb = load(path)
            t1 = time.perf_counter()
            m = mean_rgb(rgb)
            times.append(time.perf_counter() - t0)
            decode_times.append(t1 - t0)
        print(
            json.dumps(
                {
                    "file": path,
                    "median_seconds": statistics.median(times),
                    "median_decode_seconds": statistics.median(decode_times),
                    "mean_rgb": [float(v) for v in m],
                }
            )
        )


if __name__ == "__main__":
    main()
