"""Every fault kind shows up where it was scheduled, in the truth file and in the data."""

import json
import os

import numpy as np
import pytest

from goniosim.controller import Controller
from goniosim.render import decode_hdr

FAULTS = [
    {"kind": "lamp-colour-drift", "at_capture": 1, "until_capture": 4, "cct_k_per_h": -36000.0},
    {"kind": "lamp-decay", "at_capture": 5, "until_capture": 10, "rate_pct_per_h": 360.0},
    {"kind": "lamp-decay", "at_capture": 10, "until_capture": 12, "rate_pct_per_h": 360.0, "model": "exponential"},
    {"kind": "lamp-step", "at_capture": 12, "until_capture": 14, "step_pct": -3.0},
    {"kind": "lamp-flicker", "at_capture": 14, "until_capture": 16, "amplitude_pct": 2.0},
    {"kind": "joint-offset", "at_capture": 16, "until_capture": 18, "joint": 2, "offset_deg": 1.0},
    {"kind": "encoder-mismatch", "at_capture": 18, "until_capture": 20, "joint": 4, "offset_deg": 0.5},
    {"kind": "wagon-offset", "at_capture": 20, "until_capture": 22, "offset_deg": -1.0},
    {"kind": "wagon-backlash", "at_capture": 36, "until_capture": 38, "backlash_deg": 0.5},
    {"kind": "nan-pixels", "at_capture": 22, "count": 5},
    {"kind": "inf-pixels", "at_capture": 23, "count": 5},
    {"kind": "saturated-block", "at_capture": 24, "size_px": 4},
    {"kind": "dark-frame", "at_capture": 25},
    {"kind": "truncated-file", "at_capture": 26, "keep_fraction": 0.3},
    {"kind": "missing-file", "at_capture": 27},
    {"kind": "slow-write", "at_capture": 28, "duration_s": 0.4},
    {"kind": "duplicate-index", "at_capture": 29},
    {"kind": "corrupt-bytes", "at_capture": 30, "until_capture": 32, "rate": 0.05},
    {"kind": "drop-lines", "at_capture": 32, "until_capture": 34, "rate": 0.5},
    {"kind": "reboot", "at_capture": 34},
    {"kind": "unplug", "at_capture": 38, "duration_s": 0.2},
    {"kind": "slow-link", "at_capture": 39, "baud": 2400},
]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from goniosim import scenario as S

    tmp = tmp_path_factory.mktemp("faults")
    sc = S.from_dict(
        {
            "session": {
                "id": "f",
                "capture_root": str(tmp / "cap"),
                "port": str(tmp / "port"),
                "image_size": [16, 16],
                "captures": 40,
                "speed": 0.0,
                "seed": 4,
                "noise": False,
            },
            "faults": FAULTS,
        }
    )
    import threading

    from simtest import Client

    sc.speed = 7.0 / 0.03  # 30 ms per capture
    ctl = Controller(sc, log=None, linger_s=0.5)
    th = threading.Thread(target=ctl.run, daemon=True)
    th.start()
    # a subscribed reader on the daemon side, so the link faults act on real traffic
    c = Client(sc.port)
    c.send("HELLO", {"proto": "1"})
    c.send("SUBSCRIBE")
    try:
        while th.is_alive():
            c.pump()
    except Exception:
        pass  # the unplug fault ends the reader
    th.join()
    c.close()
    stats = dict(ctl.cable.stats)
    ctl.close()
    truth = {t["idx"]: t for t in map(json.loads, open(sc.truth_path()))}
    return sc, truth, stats


def path(sc, t):
    return os.path.join(sc.capture_root, t["file"])


def test_lamp_faults(session):
    sc, truth, _ = session
    assert truth[4]["lamp_gain"] == 1.0 and truth[4]["faults"] == []
    # linear 360 %/h: 7 s per capture = 7 % per capture after onset
    for k in range(5, 10):
        assert truth[k]["lamp_gain"] == pytest.approx(1 - 3.6 * (k - 5) * 7 / 3600)
        assert "lamp-decay" in truth[k]["faults"]
    assert truth[11]["lamp_gain"] == pytest.approx(np.exp(-3.6 * 7 / 3600))
    assert truth[12]["lamp_gain"] == pytest.approx(0.97) and "lamp-step" in truth[12]["faults"]
    assert truth[14]["lamp_gain"] != 1.0 and truth[15]["lamp_gain"] != truth[14]["lamp_gain"]
    assert truth[16]["lamp_gain"] == 1.0
    # the data shows it: same geometry scaled by the gain
    a = decode_hdr(open(path(sc, truth[12]), "rb").read()).mean()
    assert a > 0


def test_lamp_colour_drift_follows_planck_through_the_reference_spectral_path(session):
    from goniosim.spectral import M, lamp_colour_matrix

    _, truth, _ = session
    assert truth[0]["lamp_cct_k"] is None and truth[4]["lamp_cct_k"] is None
    # −36,000 K/h at 7 s per capture: −70 K per capture from 3000 K at the onset
    for k in range(1, 4):
        assert truth[k]["lamp_cct_k"] == pytest.approx(3000.0 - 70.0 * (k - 1))
        assert "lamp-colour-drift" in truth[k]["faults"]
    # captures 1–4 see the same BRDF (light at the pole, camera at θo = 15° on four azimuths of an
    # isotropic sample): only the lamp's colour differs
    ref = np.array(truth[1]["mean_rgb_noiseless_roi"])
    for k in (2, 3):
        got = np.array(truth[k]["mean_rgb_noiseless_roi"])
        assert got == pytest.approx(lamp_colour_matrix(truth[k]["lamp_cct_k"]) @ ref, rel=1e-9)
        # redder, and the luminance nearly kept
        assert got[0] / got[2] > ref[0] / ref[2]
        assert (M @ got)[1] == pytest.approx((M @ ref)[1], rel=5e-3)


def test_lamp_colour_matrix():
    from goniosim.spectral import M, lamp_colour_matrix

    assert lamp_colour_matrix(3000.0) == pytest.approx(np.eye(3), abs=1e-12)
    assert lamp_colour_matrix(5000.0, 5000.0) == pytest.approx(np.eye(3), abs=1e-12)
    white = np.ones(3)
    prev = None
    for cct in (2600.0, 2800.0, 3000.0, 3200.0, 3400.0):
        c = lamp_colour_matrix(cct)
        # a white keeps its luminance (the metamer white is flat within 0.4 %)
        assert (M @ c @ white)[1] == pytest.approx(1.0, abs=1e-3)
        # cooler is redder and less blue, monotonically
        if prev is not None:
            assert c[0, 0] < prev[0, 0] and c[2, 2] > prev[2, 2]
        prev = c
    with pytest.raises(ValueError):
        lamp_colour_matrix(0.0)
    with pytest.raises(ValueError):
        lamp_colour_matrix(float("nan"))


def test_positioning_faults(session):
    _, truth, _ = session
    t = truth[16]
    assert t["true_pose"][1] == pytest.approx(t["cmd"][1] + 1.0) and t["enc"] == t["cmd"]
    t = truth[18]
    assert t["enc"][3] == pytest.approx(t["cmd"][3] + 0.5) and t["true_pose"] == t["cmd"]
    t = truth[20]
    assert t["true_pose"][3] == pytest.approx(t["cmd"][3] - 1.0) and t["enc"] == t["cmd"]
    moved = [truth[k] for k in (36, 37) if truth[k]["cmd"][3] != truth[k - 1]["cmd"][3]]
    assert moved and all(abs(t["true_pose"][3] - t["cmd"][3]) == pytest.approx(0.5) for t in moved)
    assert truth[22]["true_pose"] == truth[22]["cmd"]


def test_pixel_faults(session):
    import OpenEXR

    sc, truth, _ = session
    for k, bad in ((22, np.isnan), (23, np.isinf)):
        assert truth[k]["format"] == "exr"
        with OpenEXR.File(path(sc, truth[k])) as f:
            rgb = f.channels()["RGB"].pixels
        assert bad(rgb).sum() >= 1
    sat = decode_hdr(open(path(sc, truth[24]), "rb").read())
    assert sat.max() > 60000
    dark = decode_hdr(open(path(sc, truth[25]), "rb").read())
    assert truth[25]["lamp_gain"] == 0.0 and dark.max() == 0.0


def test_file_faults(session):
    sc, truth, _ = session
    full = os.path.getsize(path(sc, truth[25]))
    assert os.path.getsize(path(sc, truth[26])) < 0.5 * full
    assert not truth[27]["written"] and not os.path.exists(path(sc, truth[27]))
    assert os.path.getsize(path(sc, truth[28])) == full, "the slow write finishes"
    assert not [n for n in os.listdir(os.path.dirname(path(sc, truth[0]))) if n.endswith(".tmp")]
    assert truth[29]["announced_idx"] == 28 and truth[29]["idx"] == 29


def test_link_faults(session):
    _, truth, stats = session
    assert stats.get("corrupted_bytes", 0) > 0
    assert stats.get("dropped_lines", 0) > 0
    assert truth[33]["boot"] == 1 and truth[34]["boot"] == 2
    assert stats["unplugs"] >= 1 and stats["plugs"] == 2
    assert truth[39]["faults"] == ["slow-link"]


def test_slow_link_paces_bytes():
    from goniosim.link import Cable
    import tempfile, time as _t

    with tempfile.TemporaryDirectory() as d:
        cable = Cable(os.path.join(d, "port"), baud=9600)
        try:
            import serial

            rig = serial.Serial(cable.rig_path, timeout=0)
            dmn = serial.Serial(os.path.join(d, "port"), timeout=0.05)
            payload = b"x" * 479 + b"\n"  # 480 bytes at 960 bytes/s: about 0.5 s
            t0 = _t.monotonic()
            rig.write(payload)
            got = b""
            while len(got) < len(payload) and _t.monotonic() - t0 < 5:
                got += dmn.read(4096)
            elapsed = _t.monotonic() - t0
            assert got == payload
            assert elapsed > 0.35, f"not paced: {elapsed:.3f} s"
            rig.close()
            dmn.close()
        finally:
            cable.close()
