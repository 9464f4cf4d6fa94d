"""An independent "reference BRDF measurement" of the simulated material, written in goniowatch's
tabulated reference format (docs/reference-format.md, parsed by src/reference.rs), for the
cross-validation of a session against another instrument.

The reference instrument is a different, well-behaved machine after the paper's Integra data: a
spectral instrument (30 bands, 400–690 nm) on an irregular grid, with the sample measured in its
plane of incidence (φi = 0; the sample is isotropic) and outgoing directions dense around the
mirror direction. It sees the material's mean albedo (no texture) and none of the UBO rig's
"realism" deviations (lamp footprint, holder bleed). Its values are the spectrum of the
reflectance factor R_c = albedo_c + π·f_s(wi, wo) (BRDF × π, per linear-sRGB channel, the same
quantity a capture pixel carries divided by gain·cos θi), made spectral with a metamer
(goniosim.spectral), so that goniowatch's XYZ of a reference value equals 100·M·R exactly.
Optionally the instrument is left uncalibrated (overall scale and a gentle spectral tilt), and
every value carries multiplicative Gaussian noise.
"""

from __future__ import annotations

import math
import os

import numpy as np

from . import spectral
from .geometry import sph_to_vec, vec_to_sph
from .material import PRESETS, Material, specular

VERSION_LINE = "# goniowatch reference BRDF, version 1"

# The paper's Integra data has incidences 0/10/20/30/45/60/90°. At θi = 90° no light reaches the
# sample (cos θi = 0), and the session's largest θi is 75°, so this grid stops at 75°.
INCIDENCE_DEG = (0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0)
PHI_I_DEG = 0.0  # the reference instrument measures the (isotropic) sample in its plane of incidence
# rings around the mirror direction: angular distance (deg) -> number of azimuths on the ring
MIRROR_RINGS = ((2.0, 8), (4.0, 8), (7.0, 12), (10.0, 12), (15.0, 16), (20.0, 16), (30.0, 16))
# the coarse hemisphere grid
HEMISPHERE_THETA_DEG = tuple(float(t) for t in range(0, 81, 10))
HEMISPHERE_DPHI_DEG = 30.0
MAX_THETA_O_DEG = 82.0  # the instrument does not measure closer to the horizon
MIN_SEPARATION_DEG = 0.5  # directions closer than this to one already taken are dropped
ANGLE_DECIMALS = 3  # the angles are written (and evaluated) at this precision

# The "uncalibrated instrument": overall scale and a linear spectral tilt around 545 nm.
CALIBRATION_SCALE = 0.93
CALIBRATION_TILT = 0.08  # relative change per 145 nm (i.e. ±8 % at 400 / 690 nm)


def _round_angles(theta: float, phi: float) -> tuple[float, float]:
    theta = round(min(max(theta, 0.0), 90.0), ANGLE_DECIMALS)
    phi = round(phi % 360.0, ANGLE_DECIMALS)
    if theta == 0.0 or phi >= 360.0:
        phi = 0.0
    return theta + 0.0, phi + 0.0  # no "-0"


def _angle_between_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(a, b))))))


def outgoing_directions(theta_i: float, phi_i: float = PHI_I_DEG) -> list[tuple[float, float]]:
    """(θo, φo) in degrees for one incidence: the mirror direction, the rings around it, then the
    coarse hemisphere grid; θo > MAX_THETA_O_DEG and near-duplicates (< MIN_SEPARATION_DEG from a
    direction already taken, in that order) dropped; sorted by (θo, φo)."""
    mirror = sph_to_vec(theta_i, phi_i + 180.0)
    # an orthonormal frame around the mirror direction: e2 normal to the plane of incidence
    e2 = np.array([-math.sin(math.radians(phi_i)), math.cos(math.radians(phi_i)), 0.0])
    e1 = np.cross(e2, mirror)
    e1 /= np.linalg.norm(e1)
    candidates: list[tuple[float, float]] = [vec_to_sph(mirror)]
    for dist, count in MIRROR_RINGS:
        d = math.radians(dist)
        for k in range(count):
            a = 2.0 * math.pi * k / count
            v = math.cos(d) * mirror + math.sin(d) * (math.cos(a) * e1 + math.sin(a) * e2)
            candidates.append(vec_to_sph(v))
    for t in HEMISPHERE_THETA_DEG:
        if t == 0.0:
            candidates.append((0.0, 0.0))
            continue
        steps = int(round(360.0 / HEMISPHERE_DPHI_DEG))
        candidates.extend((t, HEMISPHERE_DPHI_DEG * k) for k in range(steps))
    kept: list[tuple[float, float]] = []
    kept_vecs: list[np.ndarray] = []
    for theta, phi in candidates:
        theta, phi = _round_angles(theta, phi)
        if theta > MAX_THETA_O_DEG:
            continue
        v = sph_to_vec(theta, phi)
        if any(_angle_between_deg(v, w) < MIN_SEPARATION_DEG for w in kept_vecs):
            continue
        kept.append((theta, phi))
        kept_vecs.append(v)
    return sorted(kept)


def reference_grid() -> list[tuple[float, float, float, float]]:
    """Every (θi, φi, θo, φo) of the reference measurement, in file order."""
    return [(ti, PHI_I_DEG, to, po) for ti in INCIDENCE_DEG for (to, po) in outgoing_directions(ti)]


def reflectance_rgb(material: Material, theta_i: float, phi_i: float, theta_o: float, phi_o: float) -> np.ndarray:
    """R_c = albedo_c + π·f_s(wi, wo): BRDF × π per linear-sRGB channel (mean albedo, no texture)."""
    wi = sph_to_vec(theta_i, phi_i)
    wo = sph_to_vec(theta_o, phi_o)
    return np.asarray(material.albedo, dtype=float) + math.pi * specular(wi, wo, material)


def instrument_response() -> np.ndarray:
    """The uncalibrated instrument's factor per band: scale × (1 + tilt·(λ − 545)/145)."""
    return CALIBRATION_SCALE * (1.0 + CALIBRATION_TILT * (spectral.BANDS_NM - 545.0) / 145.0)


def _material(material) -> Material:
    if isinstance(material, Material):
        return material
    if material in PRESETS:
        return PRESETS[material]
    raise ValueError(f"material {material!r} is not one of {sorted(PRESETS)}")


def reference_values(material, seed: int, calibration: bool = True, noise_pct: float = 0.5):
    """(grid, values): the directions of reference_grid() and a (n, 30) array of spectral values."""
    m = _material(material)
    if not (math.isfinite(noise_pct) and noise_pct >= 0.0):
        raise ValueError(f"noise_pct must be a finite number >= 0, got {noise_pct}")
    grid = reference_grid()
    rgb = np.array([reflectance_rgb(m, *g) for g in grid])
    values = spectral.spectrum_of_rgb(rgb)  # (n, 30)
    if calibration:
        values = values * instrument_response()
    if noise_pct > 0.0:
        rng = np.random.default_rng(seed)
        values = values * (1.0 + rng.normal(0.0, noise_pct / 100.0, values.shape))
    return grid, values


def _fmt_angle(v: float) -> str:
    s = f"{v:.{ANGLE_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if s in ("", "-0") else s


def reference_text(material, seed: int, calibration: bool = True, noise_pct: float = 0.5) -> str:
    m = _material(material)
    grid, values = reference_values(m, seed, calibration, noise_pct)
    bands = " ".join(f"{b:g}" for b in spectral.BANDS_NM)
    if calibration:
        response = (
            f"uncalibrated: scale {CALIBRATION_SCALE:g}, spectral tilt 1 + {CALIBRATION_TILT:g}·(λ − 545 nm)/145 nm"
        )
    else:
        response = "calibrated"
    lines = [
        VERSION_LINE,
        "# written by goniosim (python -m goniosim reference): a simulated independent measurement,",
        f"# {len(INCIDENCE_DEG)} incidences (θi = {', '.join(f'{t:g}' for t in INCIDENCE_DEG)}°, φi = 0),",
        "# outgoing directions dense around the mirror direction; mean albedo, no texture, no rig effects;",
        f"# instrument {response}; noise {noise_pct:g} % per value (seed {seed})",
        f"name = {m.name} (goniosim reference, Integra-like grid, seed {seed})",
        "format = spectral",
        f"bands = {bands}",
        "# theta_i phi_i theta_o phi_o   then BRDF x pi (reflectance factor) per band",
    ]
    for (ti, pi, to, po), vals in zip(grid, values):
        angles = " ".join(_fmt_angle(a) for a in (ti, pi, to, po))
        lines.append(angles + "   " + " ".join(f"{v:.6g}" for v in vals))
    return "\n".join(lines) + "\n"


def write_reference(material, path: str, seed: int, calibration: bool = True, noise_pct: float = 0.5) -> int:
    """Write the reference file (atomically: a temporary name, then renamed into place); returns
    the number of data lines. `material` is a Material or a preset name."""
    text = reference_text(material, seed, calibration, noise_pct)
    d = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(d, f".{os.path.basename(path)}.tmp{os.getpid()}")
    try:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return len(reference_grid())
