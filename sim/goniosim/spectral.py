"""Spectral colour for the reference measurement: the CIE 1931 2° observer and CIE D65 on the 30
bands 400, 410, …, 690 nm (the Integra data's band set), XYZ of a reflectance spectrum with
goniowatch's normalisation (a perfect reflector has Y = 100), and metamers of linear-sRGB
reflectances: spectrum(rgb) = Σ_k rgb_k S_k with XYZ(spectrum(rgb)) = 100 · M · rgb exactly (M the
IEC sRGB matrix, as goniowatch applies it to session RGB with rgb_scale 100)."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .colour import M as SRGB_TO_XYZ

# wavelength (nm), xbar, ybar, zbar, D65 relative SPD (100 at 560 nm): the rows 400–690 nm of
# /work/shared/reference/cmf1931_d65_10nm.csv, copied exactly (CIE 018:2019 CMFs and the CIE S 014-2
# D65 table as distributed by colour-science/colour, snapshot 9d743142ed97a5cfae347b559aca14c43464eb70;
# the same figures as goniowatch's src/measure/data/cmf1931_d65_5nm_380_780.csv at these bands).
CIE1931_D65_10NM = (
    (400, 0.01431, 0.000396, 0.06785001, 82.7549),
    (410, 0.04351, 0.00121, 0.2074, 91.486),
    (420, 0.13438, 0.004, 0.6456, 93.4318),
    (430, 0.2839, 0.0116, 1.3856, 86.6823),
    (440, 0.34828, 0.023, 1.74706, 104.865),
    (450, 0.3362, 0.038, 1.77211, 117.008),
    (460, 0.2908, 0.06, 1.6692, 117.812),
    (470, 0.19536, 0.09098, 1.28764, 114.861),
    (480, 0.09564, 0.13902, 0.8129501, 115.923),
    (490, 0.03201, 0.20802, 0.46518, 108.811),
    (500, 0.0049, 0.323, 0.272, 109.354),
    (510, 0.0093, 0.503, 0.1582, 107.802),
    (520, 0.06327, 0.71, 0.07824999, 104.79),
    (530, 0.1655, 0.862, 0.04216, 107.689),
    (540, 0.2904, 0.954, 0.0203, 104.405),
    (550, 0.4334499, 0.9949501, 0.008749999, 104.046),
    (560, 0.5945, 0.995, 0.0039, 100),
    (570, 0.7621, 0.952, 0.0021, 96.3342),
    (580, 0.9163, 0.87, 0.001650001, 95.788),
    (590, 1.0263, 0.757, 0.0011, 88.6856),
    (600, 1.0622, 0.631, 0.0008, 90.0062),
    (610, 1.0026, 0.503, 0.00034, 89.5991),
    (620, 0.8544499, 0.381, 0.00019, 87.6987),
    (630, 0.6424, 0.265, 4.999999e-05, 83.2886),
    (640, 0.4479, 0.175, 2e-05, 83.6992),
    (650, 0.2835, 0.107, 0, 80.0268),
    (660, 0.1649, 0.061, 0, 80.2146),
    (670, 0.0874, 0.032, 0, 82.2778),
    (680, 0.04677, 0.017, 0, 78.2842),
    (690, 0.0227, 0.00821, 0, 69.7213),
)

BANDS_NM = np.array([row[0] for row in CIE1931_D65_10NM], dtype=float)
_TABLE = np.array(CIE1931_D65_10NM, dtype=float)

# XYZ weights per band (30, 3): xbar·D65, ybar·D65, zbar·D65 scaled by k = 100 / Σ ybar·D65. The
# bands are evenly spaced, so goniowatch's band width (from the spacing) is the same for every band
# and cancels in k.
XYZ_WEIGHTS = _TABLE[:, 1:4] * _TABLE[:, 4:5]
XYZ_WEIGHTS = XYZ_WEIGHTS * (100.0 / XYZ_WEIGHTS[:, 1].sum())

M = np.array(SRGB_TO_XYZ, dtype=float)


def xyz_of_spectrum(values) -> np.ndarray:
    """XYZ of a reflectance spectrum on BANDS_NM under D65 (perfect reflector: Y = 100).
    `values` has 30 entries in its last axis; leading axes are kept."""
    v = np.asarray(values, dtype=float)
    if v.shape[-1] != len(BANDS_NM):
        raise ValueError(f"a spectrum needs {len(BANDS_NM)} values (400–690 nm), got {v.shape[-1]}")
    return v @ XYZ_WEIGHTS


# The 30-band D65 white (a perfect reflector, all 1.0): (94.889…, 100, 108.739…). It differs from
# the white of the rounded IEC matrix, 100·M·(1, 1, 1) = (95.05, 100, 108.9), by about 0.16 in X
# and Z; the metamers below follow the matrix (what goniowatch does with session RGB).
D65_WHITE_30 = xyz_of_spectrum(np.ones(len(BANDS_NM)))


def rgb_to_xyz(rgb) -> np.ndarray:
    """goniowatch's session conversion: 100 · M · rgb (rgb_scale 100). Last axis = RGB."""
    return 100.0 * np.asarray(rgb, dtype=float) @ M.T


def _logistic(t: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * t))


# Shape of the basis. A smooth partition of unity: blue below a logistic edge at 490 nm (width
# 9 nm), red above one at 590 nm (width 5 nm: the sRGB red is close to the limit of what a
# reflectance can reach, so its edge must be fairly steep), green the rest. Each is then
# corrected with broad Gaussians (σ = 35 nm) centred at 450, 545 and 610 nm, whose weights solve a
# 3×3 system per channel so that the XYZ comes out exactly. With these parameters every S_k is
# non-negative, every S_k ≤ 1, and S_R + S_G + S_B (the white) is flat within 0.4 %.
BLUE_EDGE_NM, BLUE_EDGE_WIDTH_NM = 490.0, 9.0
RED_EDGE_NM, RED_EDGE_WIDTH_NM = 590.0, 5.0
CORRECTION_CENTRES_NM = (450.0, 545.0, 610.0)
CORRECTION_SIGMA_NM = 35.0


@lru_cache(maxsize=1)
def _basis() -> np.ndarray:
    wl = BANDS_NM
    red = _logistic((wl - RED_EDGE_NM) / RED_EDGE_WIDTH_NM)
    blue = 1.0 - _logistic((wl - BLUE_EDGE_NM) / BLUE_EDGE_WIDTH_NM)
    green = 1.0 - red - blue
    partition = np.stack([red, green, blue], axis=1)  # (30, 3), rows sum to 1
    bumps = np.stack([np.exp(-0.5 * ((wl - c) / CORRECTION_SIGMA_NM) ** 2) for c in CORRECTION_CENTRES_NM], axis=1)
    # XYZ(partition_k + bumps @ c_k) = 100 M_k  <=>  (W^T bumps) c_k = 100 M_k - W^T partition_k
    a = XYZ_WEIGHTS.T @ bumps  # (3, 3)
    rhs = 100.0 * M - XYZ_WEIGHTS.T @ partition  # (3, 3), column k for channel k
    coeffs = np.linalg.solve(a, rhs)
    basis = partition + bumps @ coeffs
    basis.setflags(write=False)
    return basis


def basis_spectra() -> np.ndarray:
    """(30, 3): the reflectance spectra S_R, S_G, S_B of the linear-sRGB unit colours (columns)."""
    return _basis().copy()


def spectrum_of_rgb(rgb) -> np.ndarray:
    """A metamer of the linear-sRGB reflectance `rgb` (last axis RGB): Σ_k rgb_k S_k on BANDS_NM,
    with xyz_of_spectrum(spectrum_of_rgb(rgb)) = rgb_to_xyz(rgb)."""
    return np.asarray(rgb, dtype=float) @ _basis().T


# Planck's law: the second radiation constant c2 = h·c/k (m·K), CODATA 2018.
PLANCK_C2_M_K = 1.438776877e-2


def planck(wavelength_nm, temperature_k: float) -> np.ndarray:
    """Relative spectral radiance of a black body at `temperature_k` (the first radiation
    constant is left out: only ratios are used)."""
    lam = np.asarray(wavelength_nm, dtype=float) * 1e-9
    return 1.0 / (lam**5 * np.expm1(PLANCK_C2_M_K / (lam * temperature_k)))


def lamp_colour_matrix(cct_k: float, reference_cct_k: float = 3000.0) -> np.ndarray:
    """The 3×3 matrix C with rendered linear sRGB = C · rgb for a lamp that has moved from
    `reference_cct_k` (where the camera was white-balanced: C = I) to `cct_k`.

    The lamp's spectrum changes by r(λ) = B(λ, cct) / B(λ, reference), normalised so that a
    perfect white reflector keeps its luminance. A surface of linear-sRGB reflectance rgb has the
    metamer Σ_k rgb_k S_k (`spectrum_of_rgb`), the same spectral path as the reference output;
    under the changed lamp its XYZ is W^T (r ∘ S) rgb, and the camera, calibrated as goniowatch's
    conversion assumes, reports M⁻¹ XYZ / 100."""
    if not (math.isfinite(cct_k) and cct_k > 0 and math.isfinite(reference_cct_k) and reference_cct_k > 0):
        raise ValueError(f"colour temperature must be positive, got {cct_k} K (reference {reference_cct_k} K)")
    r = planck(BANDS_NM, cct_k) / planck(BANDS_NM, reference_cct_k)
    r = r * (XYZ_WEIGHTS[:, 1].sum() / (XYZ_WEIGHTS[:, 1] @ r))
    xyz = XYZ_WEIGHTS.T @ (r[:, None] * _basis())  # (3, 3): XYZ of each unit colour
    return np.linalg.solve(M, xyz) / 100.0
