"""The reference BRDF measurement (goniosim.reference, goniosim.spectral): exact sRGB metamers,
the D65 white, the file format of docs/reference-format.md, the Integra-like grid, determinism and
the command line."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from simtest import REPO, SIM

from goniosim import reference as R
from goniosim import spectral as SP
from goniosim.material import PRESETS

VERSION_LINE = "# goniowatch reference BRDF, version 1"


def parse_reference(text):
    """A small checker after goniowatch::reference::parse (src/reference.rs): version line, header
    `key = value` lines (format, bands, name; no unknown or repeated keys; before the data), data
    lines of 4 angles and one value per band (spectral) or 3 (rgb, xyz), all finite, θ in [0, 90]."""
    lines = text.split("\n")
    if text.endswith("\n"):
        lines = lines[:-1]
    assert lines and lines[0] == VERSION_LINE, "line 1"
    header, samples = {}, []
    for n, raw in enumerate(lines[1:], start=2):
        content = raw.split("#", 1)[0]
        if not content.strip():
            continue
        if "=" in content:
            assert not samples, f"line {n}: header after data"
            key, value = (s.strip() for s in content.split("=", 1))
            assert key in ("format", "bands", "name"), f"line {n}: unknown key {key!r}"
            assert key not in header, f"line {n}: {key!r} twice"
            header[key] = value
            continue
        assert "format" in header, f"line {n}: data before format"
        if header["format"] == "spectral":
            assert "bands" in header, f"line {n}: no bands"
            expected = len(header["bands"].split())
        else:
            assert header["format"] in ("rgb", "xyz")
            expected = 3
        toks = content.split()
        assert len(toks) == 4 + expected, f"line {n}: {len(toks)} fields, expected {4 + expected}"
        nums = [float(t) for t in toks]
        assert all(math.isfinite(v) for v in nums), f"line {n}: not finite"
        assert 0.0 <= nums[0] <= 90.0 and 0.0 <= nums[2] <= 90.0, f"line {n}: theta out of [0, 90]"
        samples.append((tuple(nums[:4]), np.array(nums[4:])))
    assert "format" in header and samples
    bands = [float(b) for b in header.get("bands", "").split()]
    assert all(b2 > b1 for b1, b2 in zip(bands, bands[1:])), "bands not increasing"
    return header, bands, samples


RGBS = [
    (1.0, 0.0, 0.0),
    (0.0, 1.0, 0.0),
    (0.0, 0.0, 1.0),
    (1.0, 1.0, 1.0),
    (0.42, 0.36, 0.26),
    (0.70, 0.46, 0.45),
    (0.0, 0.0, 0.0),
    (3.7, 0.2, 1.9),
    (0.013, 0.9, 0.31),
]


@pytest.mark.parametrize("rgb", RGBS)
def test_spectra_are_exact_metamers_of_the_srgb_colour(rgb):
    xyz = SP.xyz_of_spectrum(SP.spectrum_of_rgb(rgb))
    want = 100.0 * np.array(SP.M) @ np.array(rgb)
    assert np.abs(xyz - want).max() < 1e-9


def test_metamers_on_many_random_colours_and_the_session_conversion():
    rng = np.random.default_rng(5)
    rgb = rng.uniform(0.0, 2.0, (500, 3))
    err = np.abs(SP.xyz_of_spectrum(SP.spectrum_of_rgb(rgb)) - SP.rgb_to_xyz(rgb)).max()
    assert err < 1e-9
    # goniowatch's session conversion: the IEC matrix (0.4124 first, not the seed text's 0.4142)
    assert SP.M[0][0] == 0.4124 and SP.rgb_to_xyz([1, 1, 1])[1] == pytest.approx(100.0, abs=1e-12)


def test_white_is_the_30_band_d65_white():
    # the 30-band D65 white itself: Y = 100, D65's chromaticity
    w30 = SP.D65_WHITE_30
    assert w30[1] == pytest.approx(100.0, abs=1e-12)
    assert w30[0] / w30.sum() == pytest.approx(0.3127, abs=1e-3)
    assert w30[1] / w30.sum() == pytest.approx(0.3290, abs=1e-3)
    # rgb (1, 1, 1) is, spectrally, the perfect reflector within 0.5 % in every band ...
    white = SP.spectrum_of_rgb([1.0, 1.0, 1.0])
    assert white.shape == (30,)
    assert np.abs(white - 1.0).max() < 5e-3
    # ... and its XYZ is that white: Y exactly, X and Z within the 0.16 by which the rounded IEC
    # matrix's white (95.05, 100, 108.9) differs from the 30-band table's
    xyz = SP.xyz_of_spectrum(white)
    assert xyz[1] == pytest.approx(100.0, abs=1e-9)
    assert np.abs(xyz - w30).max() < 0.2
    assert np.abs(xyz - np.array([95.05, 100.0, 108.9])).max() < 1e-9


def test_basis_spectra_are_smooth_and_physically_plausible():
    s = SP.basis_spectra()
    assert s.shape == (30, 3)
    assert s.min() >= 0.0 and s.max() <= 1.0
    # R peaks at the long end, G in the middle, B at the short end
    peaks = SP.BANDS_NM[np.argmax(s, axis=0)]
    assert peaks[0] >= 620 and 520 <= peaks[1] <= 580 and peaks[2] <= 460
    # no band-to-band oscillation: each basis changes sign of its slope at most twice
    for k in range(3):
        d = np.diff(s[:, k])
        d = d[np.abs(d) > 1e-4]
        assert np.count_nonzero(np.diff(np.sign(d))) <= 2


def _table_rows(path, lo=400, hi=690):
    rows = {}
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("#") or line.startswith("wavelength"):
                continue
            fields = line.strip().split(",")
            if len(fields) >= 5 and lo <= float(fields[0]) <= hi:
                rows[float(fields[0])] = tuple(float(v) for v in fields[1:5])
    return rows


def test_embedded_table_is_the_cie_table_goniowatch_uses():
    ours = {float(r[0]): tuple(float(v) for v in r[1:]) for r in SP.CIE1931_D65_10NM}
    assert sorted(ours) == [400.0 + 10 * k for k in range(30)]
    rust = _table_rows(os.path.join(REPO, "src", "measure", "data", "cmf1931_d65_5nm_380_780.csv"))
    assert all(rust[w] == ours[w] for w in ours)
    shared = "/work/shared/reference/cmf1931_d65_10nm.csv"
    if os.path.exists(shared):
        assert _table_rows(shared) == ours


def _write(tmp_path, name="ref.txt", material="walkway", seed=4, **kw):
    path = tmp_path / name
    n = R.write_reference(PRESETS[material] if material in PRESETS else material, str(path), seed, **kw)
    return path, n


def test_file_parses_in_the_documented_format(tmp_path):
    path, n = _write(tmp_path)
    text = path.read_text(encoding="utf-8")
    assert text.splitlines()[0] == VERSION_LINE
    header, bands, samples = parse_reference(text)
    assert header["format"] == "spectral"
    assert bands == [400.0 + 10 * k for k in range(30)]
    assert header["name"] == "walkway (plastic with a glossy varnish) (goniosim reference, Integra-like grid, seed 4)"
    assert len(samples) == n == len(R.reference_grid())
    for angles, values in samples:
        assert len(values) == 30 and np.all(values > 0)
        assert 0.0 <= angles[0] <= 90.0 and 0.0 <= angles[2] <= R.MAX_THETA_O_DEG
    # values carry 6 significant digits
    first = text.splitlines()[len(text.splitlines()) - n].split()
    assert all(len(t.replace(".", "").replace("-", "").lstrip("0")) <= 6 for t in first[4:])


def test_values_convert_to_the_session_xyz_of_the_reflectance(tmp_path):
    """Calibrated and noiseless, goniowatch's XYZ of every line is 100·M·(albedo + π f_s)."""
    m = PRESETS["pinkwall"]
    path, _ = _write(tmp_path, material="pinkwall", calibration=False, noise_pct=0.0)
    _, _, samples = parse_reference(path.read_text(encoding="utf-8"))
    worst = 0.0
    for angles, values in samples:
        want = SP.rgb_to_xyz(R.reflectance_rgb(m, *angles))
        got = SP.xyz_of_spectrum(values)
        worst = max(worst, float(np.abs(got / want - 1.0).max()))
    assert worst < 2e-6  # 6 significant digits


def test_uncalibrated_instrument_and_noise(tmp_path):
    clean, _ = _write(tmp_path, "a.txt", calibration=False, noise_pct=0.0)
    tilted, _ = _write(tmp_path, "b.txt", calibration=True, noise_pct=0.0)
    noisy, _ = _write(tmp_path, "c.txt", calibration=True, noise_pct=0.5)
    a = np.array([v for _, v in parse_reference(clean.read_text())[2]])
    b = np.array([v for _, v in parse_reference(tilted.read_text())[2]])
    c = np.array([v for _, v in parse_reference(noisy.read_text())[2]])
    response = 0.93 * (1.0 + 0.08 * (SP.BANDS_NM - 545.0) / 145.0)
    assert np.abs(b / a / response - 1.0).max() < 1.5e-5  # two values at 6 significant digits
    rel = c / b - 1.0
    assert abs(rel.mean()) < 5e-4 and 0.0045 < rel.std() < 0.0055


def test_grid_has_the_mirror_direction_and_is_dense_around_it():
    grid = R.reference_grid()
    assert sorted({g[0] for g in grid}) == [0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0]
    assert all(g[1] == 0.0 for g in grid)
    for ti in R.INCIDENCE_DEG:
        outs = [(g[2], g[3]) for g in grid if g[0] == ti]
        mirror = (ti, 180.0) if ti > 0 else (0.0, 0.0)
        assert mirror in outs, ti
        vm = R.sph_to_vec(*mirror)
        dist = np.array([math.degrees(math.acos(min(1.0, float(np.dot(vm, R.sph_to_vec(*o)))))) for o in outs])
        # directions per steradian within 10° of the mirror vs beyond 35°
        near = np.count_nonzero(dist <= 10.0 + 1e-6) / (2 * math.pi * (1 - math.cos(math.radians(10))))
        far = np.count_nonzero(dist > 35.0) / (2 * math.pi * math.cos(math.radians(35)))
        assert near > 10 * far, (ti, near, far)
        # every ring distance is present (unless beyond the horizon limit)
        for ring, _ in R.MIRROR_RINGS:
            if ti + ring <= R.MAX_THETA_O_DEG:
                assert np.any(np.abs(dist - ring) < 1e-2), (ti, ring)
        assert max(o[0] for o in outs) <= R.MAX_THETA_O_DEG
        # no near-duplicates
        vs = np.array([R.sph_to_vec(*o) for o in outs])
        cos = vs @ vs.T
        np.fill_diagonal(cos, -1.0)
        assert cos.max() < math.cos(math.radians(R.MIN_SEPARATION_DEG))
        # the coarse hemisphere grid covers the rest
        assert (80.0, 90.0) in outs and (40.0, 270.0) in outs


def test_same_seed_gives_identical_bytes(tmp_path):
    a, _ = _write(tmp_path, "a.txt", seed=11)
    b, _ = _write(tmp_path, "b.txt", seed=11)
    c, _ = _write(tmp_path, "c.txt", seed=12)
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()


def _cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "goniosim", "reference", *args], cwd=SIM, capture_output=True, text=True, timeout=120
    )


def test_cli_writes_a_reference_and_rejects_bad_scenarios(tmp_path):
    out = tmp_path / "walkway.ref"
    p = _cli("scenarios/clean.toml", "--out", str(out), "--seed", "7")
    assert p.returncode == 0, p.stderr
    header, bands, samples = parse_reference(out.read_text(encoding="utf-8"))
    assert header["name"].startswith("walkway") and header["name"].endswith("seed 7)")
    assert len(bands) == 30 and len(samples) == len(R.reference_grid())
    # the same as the library call
    lib = tmp_path / "lib.ref"
    R.write_reference(PRESETS["walkway"], str(lib), 7)
    assert lib.read_bytes() == out.read_bytes()
    # --no-calibration --noise-pct 0
    plain = tmp_path / "plain.ref"
    assert _cli("scenarios/clean.toml", "--out", str(plain), "--no-calibration", "--noise-pct", "0").returncode == 0
    assert "noise 0 %" in plain.read_text(encoding="utf-8")

    p = _cli(str(tmp_path / "missing.toml"), "--out", str(tmp_path / "x.ref"))
    assert p.returncode == 2 and "goniosim:" in p.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text('[material]\npreset = "velvet"\n', encoding="utf-8")
    p = _cli(str(bad), "--out", str(tmp_path / "x.ref"))
    assert p.returncode == 2 and "material.preset" in p.stderr
    assert not (tmp_path / "x.ref").exists()
