"""Just enough colour science to document the simulator's presets (Table 2 figures): sRGB (IEC)
-> XYZ -> CIE L*a*b* (D65, Y_n = 100), dE*ab, dC, dH and CIEDE2000 (Sharma et al. 2005)."""

from __future__ import annotations

import math

M = ((0.4124, 0.3576, 0.1805), (0.2126, 0.7152, 0.0722), (0.0193, 0.1192, 0.9505))
WHITE = (0.3127 / 0.3290 * 100.0, 100.0, (1 - 0.3127 - 0.3290) / 0.3290 * 100.0)


def rgb_to_xyz(rgb):
    return tuple(sum(M[r][c] * rgb[c] for c in range(3)) for r in range(3))


def _f(t):
    d = 6 / 29
    return t ** (1 / 3) if t > d**3 else t / (3 * d * d) + 4 / 29


def xyz_to_lab(xyz):
    fx, fy, fz = (_f(xyz[i] / WHITE[i]) for i in range(3))
    return (116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz))


def de76(a, b):
    return math.dist(a, b)


def dc(a, b):
    return abs(math.hypot(b[1], b[2]) - math.hypot(a[1], a[2]))


def dh(a, b):
    return math.sqrt(max(0.0, 2 * (math.hypot(a[1], a[2]) * math.hypot(b[1], b[2]) - a[1] * b[1] - a[2] * b[2])))


def de2000(lab1, lab2):
    L1, a1, b1 = lab1
    L2, a2, b2 = lab2
    c1, c2 = math.hypot(a1, b1), math.hypot(a2, b2)
    cb7 = ((c1 + c2) / 2) ** 7
    g = 0.5 * (1 - math.sqrt(cb7 / (cb7 + 25**7)))
    a1p, a2p = (1 + g) * a1, (1 + g) * a2
    c1p, c2p = math.hypot(a1p, b1), math.hypot(a2p, b2)

    def hue(a, b):
        return 0.0 if a == 0 and b == 0 else math.degrees(math.atan2(b, a)) % 360

    h1, h2 = hue(a1p, b1), hue(a2p, b2)
    dl, dcp = L2 - L1, c2p - c1p
    if c1p * c2p == 0:
        dhp = 0.0
    else:
        dhp = h2 - h1
        dhp = dhp - 360 if dhp > 180 else dhp + 360 if dhp < -180 else dhp
    dH = 2 * math.sqrt(c1p * c2p) * math.sin(math.radians(dhp) / 2)
    lb, cb = (L1 + L2) / 2, (c1p + c2p) / 2
    if c1p * c2p == 0:
        hb = h1 + h2
    elif abs(h1 - h2) <= 180:
        hb = (h1 + h2) / 2
    else:
        hb = (h1 + h2 + 360) / 2 if h1 + h2 < 360 else (h1 + h2 - 360) / 2
    t = 1 - 0.17 * math.cos(math.radians(hb - 30)) + 0.24 * math.cos(math.radians(2 * hb)) + 0.32 * math.cos(math.radians(3 * hb + 6)) - 0.20 * math.cos(math.radians(4 * hb - 63))
    dtheta = 30 * math.exp(-(((hb - 275) / 25) ** 2))
    rc = 2 * math.sqrt(cb**7 / (cb**7 + 25**7))
    sl = 1 + 0.015 * (lb - 50) ** 2 / math.sqrt(20 + (lb - 50) ** 2)
    sc, sh = 1 + 0.045 * cb, 1 + 0.015 * cb * t
    rt = -math.sin(math.radians(2 * dtheta)) * rc
    return math.sqrt((dl / sl) ** 2 + (dcp / sc) ** 2 + (dH / sh) ** 2 + rt * (dcp / sc) * (dH / sh))


def recorrect(xyz1, ti1, xyz2, ti2):
    c1, c2 = math.cos(math.radians(ti1)), math.cos(math.radians(ti2))
    f1, f2 = math.sqrt(c2 / c1), math.sqrt(c1 / c2)
    return tuple(v * f1 for v in xyz1), tuple(v * f2 for v in xyz2)


def table2(records, rgb_scale=100.0):
    """Mean |dX| |dY| |dZ| dE dC dH dE00 over reciprocal pairs of truth records."""
    by_entry = {}
    for r in records:
        if not r.get("probe"):
            by_entry[(r["light"], r["camera"])] = r
    sums = [0.0] * 7
    n = 0
    for (l, c), r1 in by_entry.items():
        if l >= c or (c, l) not in by_entry:
            continue
        r2 = by_entry[(c, l)]
        x1 = rgb_to_xyz([v * rgb_scale for v in r1["mean_rgb_noiseless_roi"]])
        x2 = rgb_to_xyz([v * rgb_scale for v in r2["mean_rgb_noiseless_roi"]])
        a, b = recorrect(x1, r1["true_angles"][0], x2, r2["true_angles"][0])
        la, lb = xyz_to_lab(a), xyz_to_lab(b)
        vals = [abs(a[0] - b[0]), abs(a[1] - b[1]), abs(a[2] - b[2]), de76(la, lb), dc(la, lb), dh(la, lb), de2000(la, lb)]
        sums = [s + v for s, v in zip(sums, vals)]
        n += 1
    return n, [s / max(n, 1) for s in sums]
