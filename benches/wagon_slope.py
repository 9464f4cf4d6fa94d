"""How fast a capture's luminance turns with the wagon on the simulated rig, against the slope
goniowatch's smooth model reads, at the poses its question of approach re-captured in the
detection lab (BENCHMARKS.md, "The wagon's lag with probes").

At each plan entry the wagon is moved off its command with the joints held, and the capture is
rendered noise-free as the simulator's controller does (rig.plan_pose, rig.forward,
render.render with the run's albedo texture and holder) and averaged as goniowatch does (the
region inside a 10 % margin, Y = 0.2126 R + 0.7152 G + 0.0722 B). Printed per entry: ln Y at
the offsets, the slope over ±0.1° and ±0.5°, ln Y(w − 1°) − ln Y(w + 1°) (what a 1° lag read
from both sides shows), the secant over ±15° (the plan's grid of camera directions, which the
model's slope follows), and the same with each part of the `realistic` model left out.

  python3 benches/wagon_slope.py [image_px]     (default 16, the lab's image size)
"""

import dataclasses
import math
import os
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "sim"))

import numpy as np  # noqa: E402

from goniosim import scenario as S  # noqa: E402
from goniosim.geometry import vec_to_sph  # noqa: E402
from goniosim.material import PRESETS, REALISM, albedo_texture  # noqa: E402
from goniosim.render import render  # noqa: E402

IMG = int(sys.argv[1]) if len(sys.argv) > 1 else 16
# plan entry, material, seed, the model's slope (%/°) and the question's reading (%) in the lab
CASES = [(202, "ceiling", 1, -4.94, 14.45), (697, "walkway", 1, -3.55, 11.70)]
DS = (-1.0, -0.5, -0.1, 0.0, 0.1, 0.5, 1.0)
YROW = np.array([0.2126, 0.7152, 0.0722])
ROI_F = 0.1


def scenario(material, seed, tmp):
    data = {
        "rig_config": os.path.join(REPO, "config", "sim.toml"),
        "session": {"image_size": [IMG, IMG], "seed": seed, "capture_root": os.path.join(tmp, "unused")},
        "material": {"preset": material, "realism": "realistic"},
    }
    return S.from_dict(data, base_dir=tmp)


def mean_y(img):
    h, w, _ = img.shape
    my, mx = int(math.floor(h * ROI_F)), int(math.floor(w * ROI_F))
    roi = img[my : h - my, mx : w - mx].reshape(-1, 3)
    return float(roi.mean(axis=0) @ YROW)


def main():
    print(f"image {IMG}x{IMG}")
    tmp = tempfile.mkdtemp(prefix="wagon-slope-")
    for entry, mat_name, seed, model_pct, read_pct in CASES:
        sc = scenario(mat_name, seed, tmp)
        mat = PRESETS[sc.material]
        real = REALISM[sc.realism]
        w_, h_ = sc.image_size
        albedo = albedo_texture(mat, h_, w_, sc.seed)
        holder_px = max(1, int(round(sc.holder_fraction * min(w_, h_))))
        light, camera = sc.plan.entry(entry)
        ld, cd = sc.plan.directions[light], sc.plan.directions[camera]
        cmd, _, _, sub = sc.rig.plan_pose(ld, cd)
        wi0, wo0 = sc.rig.forward(cmd)
        ti, pi_ = vec_to_sph(wi0)
        to, po = vec_to_sph(wo0)
        print(f"\nentry {entry} ({mat_name}, realistic, seed {seed}): light {light} {ld}, camera {camera} {cd}, "
              f"substitute theta_i {sub}")
        print(f"  cmd pose q1 q2 q3 w = {[round(x, 4) for x in cmd]}; holder_px {holder_px}")
        print(f"  true angles at cmd: theta_i {ti:.3f}  phi_i {pi_:.3f}  theta_o {to:.3f}  phi_o {po:.3f}  "
              f"|phi_i-phi_o| {abs((pi_ - po + 180) % 360 - 180):.3f}")
        print(f"  goniowatch model slope {model_pct:+.2f} %/deg; reading lnY(w-1)-lnY(w+1) = {read_pct / 100:+.4f}")
        variants = [
            ("realistic (as run)", real, render),
            ("bleed_px = 0", dataclasses.replace(real, bleed_px=0.0), render),
            ("footprint = 0", dataclasses.replace(real, footprint=0.0), render),
            ("clean (no realism)", REALISM["clean"], render),
        ]
        hdr = "  variant                   " + " ".join(f"lnY(d={d:+.1f})" for d in DS)
        print(hdr + "   slope±0.1 slope±0.5 lnY(-1)-lnY(+1) [=> %/deg] secant±15")
        for name, rz, fn in variants:
            lys = {}
            for d in DS + (-15.0, 15.0):
                pose = list(cmd)
                pose[3] += d
                wi, wo = sc.rig.forward(pose)
                lys[d] = math.log(mean_y(fn(albedo, wi, wo, mat, rz, 1.0, holder_px)))
            s01 = (lys[0.1] - lys[-0.1]) / 0.2
            s05 = (lys[0.5] - lys[-0.5]) / 1.0
            s15 = (lys[15.0] - lys[-15.0]) / 30.0
            diff = lys[-1.0] - lys[1.0]
            row = " ".join(f"{lys[d]:11.5f}" for d in DS)
            print(f"  {name:25s} {row}   {100 * s01:+7.2f}%  {100 * s05:+7.2f}%  {diff:+.4f} [{-50 * diff:+.2f}]"
                  f"  {100 * s15:+7.2f}%")
        # components: d ln(cos theta_i)/dw, d theta_o/dw, d theta_i/dw, bleed width in px
        def angles(d):
            pose = list(cmd)
            pose[3] += d
            wi, wo = sc.rig.forward(pose)
            return vec_to_sph(wi) + vec_to_sph(wo)
        a_m, a_p = angles(-0.1), angles(0.1)
        print("  d(theta_i,phi_i,theta_o,phi_o)/dw (deg/deg): "
              + ", ".join(f"{(p - m) / 0.2:+.3f}" for m, p in zip(a_m, a_p)))
        for d in (-1.0, 0.0, 1.0):
            t_o = angles(d)[2]
            print(f"    d={d:+.1f}: theta_o {t_o:.3f}, bleed {real.bleed_px * min(math.tan(math.radians(t_o)), 10):.3f} px")


if __name__ == "__main__":
    main()
