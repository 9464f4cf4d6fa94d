"""A MERL BRDF reader written from the format's description (the MERL BRDF database's
BRDFRead.cpp conventions), not from goniowatch's writer: three little-endian int32 dimensions
(90, 90, 180), then 3 x 1,458,000 little-endian float64 values, red block, green, blue; cell =
phi_d_i + 180 * theta_d_i + 180 * 90 * theta_h_i with theta_h_i = floor(sqrt(theta_h / (pi/2)) * 90),
theta_d_i = floor(theta_d / (pi/2) * 90), phi_d_i = floor(phi_d / pi * 180) after phi_d < 0 -> phi_d + pi;
BRDF = stored value x (1/1500, 1.15/1500, 1.66/1500); a negative value is no value."""

import math
import struct

import numpy as np

DIMS = (90, 90, 180)
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def read(path):
    """(3, 90, 90, 180) array of the BRDF in sr^-1, NaN where the file holds no value."""
    with open(path, "rb") as f:
        data = f.read()
    dims = struct.unpack("<3i", data[:12])
    assert dims == DIMS, dims
    n = dims[0] * dims[1] * dims[2]
    values = np.frombuffer(data[12:], dtype="<f8")
    assert values.size == 3 * n, values.size
    v = values.reshape(3, n).copy()
    empty = v < 0
    v = v * SCALE[:, None]
    v[empty] = np.nan
    return v.reshape(3, *DIMS)


def read_raw(path):
    """The stored values as they are, (3, 90, 90, 180)."""
    with open(path, "rb") as f:
        data = f.read()
    return np.frombuffer(data[12:], dtype="<f8").reshape(3, *DIMS)


def _rotate(v, axis, angle):
    """Rodrigues' rotation of v about a unit axis."""
    c, s = math.cos(angle), math.sin(angle)
    cross = np.cross(axis, v)
    return v * c + cross * s + axis * np.dot(axis, v) * (1.0 - c)


def half_diff(wi, wo):
    """(theta_h, theta_d, phi_d) of a direction pair (BRDFRead.cpp's std_coords_to_half_diff_coords)."""
    wi = np.asarray(wi, float) / np.linalg.norm(wi)
    wo = np.asarray(wo, float) / np.linalg.norm(wo)
    h = wi + wo
    h = h / np.linalg.norm(h)
    theta_h = math.acos(max(-1.0, min(1.0, h[2])))
    phi_h = math.atan2(h[1], h[0])
    d = _rotate(wi, np.array([0.0, 0.0, 1.0]), -phi_h)
    d = _rotate(d, np.array([0.0, 1.0, 0.0]), -theta_h)
    theta_d = math.acos(max(-1.0, min(1.0, d[2])))
    phi_d = math.atan2(d[1], d[0])
    return theta_h, theta_d, phi_d


def index(wi, wo):
    """(theta_h_i, theta_d_i, phi_d_i) of a direction pair, by the format's lookup."""
    th, td, pd = half_diff(wi, wo)
    ih = 0 if th <= 0 else min(89, int(math.sqrt(th / (math.pi / 2)) * 90))
    id_ = min(89, max(0, int(td / (math.pi / 2) * 90)))
    if pd < 0:
        pd += math.pi
    ip = min(179, max(0, int(pd / math.pi * 180)))
    return ih, id_, ip


def lookup(brdf, wi, wo):
    """The (R, G, B) a reader gets for a direction pair (NaN: no value)."""
    ih, id_, ip = index(wi, wo)
    return brdf[:, ih, id_, ip]


def cell_directions(ih, id_, ip):
    """A cell centre's incoming and outgoing directions (phi_h = 0): the half-difference rotation
    undone (BRDFRead.cpp's convention read backwards)."""
    th = ((ih + 0.5) / 90.0) ** 2 * (math.pi / 2)
    td = (id_ + 0.5) / 90.0 * (math.pi / 2)
    pd = (ip + 0.5) / 180.0 * math.pi
    d = np.array([math.sin(td) * math.cos(pd), math.sin(td) * math.sin(pd), math.cos(td)])
    y = np.array([0.0, 1.0, 0.0])
    wi = _rotate(d, y, th)
    wo = _rotate(np.array([-d[0], -d[1], d[2]]), y, th)
    return wi, wo


def direction(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def lookup_trilinear(brdf, wi, wo):
    """(R, G, B) at a direction pair, interpolated trilinearly between the cell centres around it
    (theta_h in the format's square-root index, phi_d periodic over pi); corners without a value
    are left out and the weights renormalised; NaN when none has one."""
    th, td, pd = half_diff(wi, wo)
    if pd < 0:
        pd += math.pi
    u = [math.sqrt(max(th, 0.0) / (math.pi / 2)) * 90 - 0.5, td / (math.pi / 2) * 90 - 0.5, pd / math.pi * 180 - 0.5]
    lo, frac = [], []
    for k, v in enumerate(u):
        if k < 2:
            v = min(max(v, 0.0), 89.0)
        f = math.floor(v)
        lo.append(int(f))
        frac.append(v - f)
    total, weight = np.zeros(3), 0.0
    for dh in (0, 1):
        for dd in (0, 1):
            for dp in (0, 1):
                ih, id_, ip = min(lo[0] + dh, 89), min(lo[1] + dd, 89), (lo[2] + dp) % 180
                w = (frac[0] if dh else 1 - frac[0]) * (frac[1] if dd else 1 - frac[1]) * (frac[2] if dp else 1 - frac[2])
                v = brdf[:, ih, id_, ip]
                if w > 0 and not np.isnan(v).any():
                    total += w * v
                    weight += w
    return total / weight if weight > 0 else np.full(3, np.nan)
