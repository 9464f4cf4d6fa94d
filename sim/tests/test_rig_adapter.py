"""The adapter's lab-facing side (sim/adapter/rig_adapter.py) on bad input: a log line or a call
it cannot announce is refused at once with a ValueError that says why (the follower skips the
line with that message and goes on), and nothing is queued for goniowatch. Also the dry run's
own names (`goniosim archive --name-format`): a format it cannot fill is refused before anything
is written."""

import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "adapter"))
from rig_adapter import RigAdapter, parse_log_line  # noqa: E402

POSE = (0.0, 90.0, -30.0, 15.0)


def test_a_good_line_and_run_done_parse():
    kind, kw = parse_log_line("2026-12-06 10:00:01 INFO CAPTURE 7 run/img%2007.hdr 0 90 -30 15 entry=3 t=21.5\n")
    assert kind == "capture" and kw["index"] == 7 and kw["relative_path"] == "run/img 07.hdr"
    assert kw["pose"] == ["0", "90", "-30", "15"] and kw["entry"] == "3" and kw["t"] == "21.5"
    assert parse_log_line("... RUN-DONE") == ("done", None)
    assert parse_log_line("the lamp was switched on") is None
    assert parse_log_line("") is None


@pytest.mark.parametrize("line", [
    "CAPTURE",                                     # nothing after the keyword
    "CAPTURE 7 img.hdr 0 90 -30",                  # three angles
    "CAPTURE 7 img.hdr 0 90 -30 15 16",            # five angles
    "CAPTURE seven img.hdr 0 90 -30 15",           # an index that is not a number
    "CAPTURE 7 img.hdr 0 90 -30 15 colour=red",    # an unknown option
    "CAPTURE 7 img%zz.hdr 0 90 -30 15",            # a bad percent escape
    "CAPTURE 7 img.hdr 0 90 -3\x00 15",           # garbled bytes in an angle
])
def test_a_malformed_capture_line_is_refused_with_the_format(line):
    with pytest.raises(ValueError):
        item = parse_log_line(line)
        RigAdapter().announce_capture(**item[1])


@pytest.mark.parametrize("kw", [
    {"pose": (0.0, float("nan"), -30.0, 15.0)},    # a NaN angle
    {"pose": (0.0, 90.0, float("inf"), 15.0)},     # an infinite angle
    {"enc": (0.0, 90.0, -30.0, float("nan"))},     # a NaN encoder reading
    {"t": float("nan")},                           # a NaN time
    {"sub": float("inf")},                         # an infinite substitute θi
    {"exposure": 0.0},                             # an exposure that divides by zero
    {"exposure": float("nan")},
    {"index": -1},                                 # a negative index
    {"relative_path": "/abs/img.hdr"},             # an absolute path
    {"relative_path": "x" * 600},                  # too long for a protocol line
])
def test_an_announcement_that_cannot_be_sent_is_refused_and_nothing_is_queued(kw):
    a = RigAdapter()
    args = {"index": 1, "relative_path": "img.hdr", "pose": POSE, "t": 7.0, **kw}
    with pytest.raises(ValueError):
        a.announce_capture(**args)
    assert a.inbox.empty()
    # the same call with good values goes through
    a.announce_capture(1, "img.hdr", POSE, t=7.0)
    assert not a.inbox.empty()


@pytest.mark.parametrize("fmt", ["{bogus}.hdr", "{idx:q}.hdr", "{0}.hdr", "{idx"])
def test_archive_refuses_a_name_format_it_cannot_fill_before_writing_anything(tmp_path, fmt):
    import subprocess

    sim = os.path.join(os.path.dirname(__file__), "..")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "goniosim", "archive", "scenarios/archive.toml", "--out", str(out),
                        "--captures", "2", "--name-format", fmt], cwd=sim, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    assert "--name-format" in r.stderr and "fields: idx, entry, tl, pl, tv, pv, ext" in r.stderr, r.stderr
    assert not out.exists()


def test_archive_names_the_files_by_the_format(tmp_path):
    import subprocess

    sim = os.path.join(os.path.dirname(__file__), "..")
    r = subprocess.run([sys.executable, "-m", "goniosim", "archive", "scenarios/archive.toml", "--out", str(tmp_path),
                        "--captures", "3", "--name-format", "{idx:05d}_L{tl:02.0f}-{pl:03.0f}_C{tv:02.0f}-{pv:03.0f}.{ext}"],
                       cwd=sim, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    names = sorted(n for n in os.listdir(tmp_path / "archive") if n.endswith(".hdr"))
    assert names[0].startswith("00000_L00-000_C") and len(names) == 3, names
