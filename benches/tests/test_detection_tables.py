"""The detection tables are made by benches/detection_tables.py, never typed: its output for a
small committed fixture of records is pinned, and the blocks in BENCHMARKS.md and README.md
must be what it makes of the committed records (benches/detection-records.json).

To bless the fixture's tables after a deliberate change to the tables:
  python3 benches/tests/test_detection_tables.py --bless
"""

import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
BENCHES = os.path.dirname(HERE)
REPO = os.path.dirname(BENCHES)
sys.path.insert(0, BENCHES)
import detection_tables as T  # noqa: E402

FIXTURE = os.path.join(HERE, "fixture-records.json")
EXPECTED = os.path.join(HERE, "fixture-tables.md")


def render(blocks):
    return "".join(f"<!-- detection:{k} -->\n{v}\n<!-- /detection:{k} -->\n\n" for k, v in blocks.items())


def test_the_fixtures_tables_are_the_pinned_ones():
    got = render(T.tables(T.load(FIXTURE)))
    with open(EXPECTED, encoding="utf-8") as f:
        assert got == f.read(), "the tables of the fixture changed: bless them if that was meant (see the module doc)"


@pytest.mark.parametrize("doc", ["BENCHMARKS.md", "README.md"])
def test_the_documents_hold_the_generated_tables(doc):
    records = os.path.join(BENCHES, "detection-records.json")
    with open(os.path.join(REPO, doc), encoding="utf-8") as f:
        text = f.read()
    assert "<!-- detection:" in text, f"{doc} has no generated detection block"
    assert T.fill(text, T.tables(T.load(records))) == text, (
        f"{doc}'s detection tables are not what benches/detection_tables.py makes of {records}: "
        "run `python3 benches/detection_tables.py --write`")


def test_a_block_with_no_generator_is_refused():
    with pytest.raises(KeyError):
        T.fill("<!-- detection:nothing -->\nx\n<!-- /detection:nothing -->", {"count": "1"})


def rec(**kw):
    base = {"row": "r", "material": "walkway", "model": "realistic", "every": 0, "fault": None, "steps": [],
            "drift_before": None, "positioning_before": None, "drift_after": None, "positioning_after": None,
            "joint_after": None, "unstable_after": None, "codes_after": [], "final_rate_pct_per_h": None}
    base.update(kw)
    return base


def alarm(idx, code="gain-step", joint=None, offset=None, level=None):
    return {"idx": idx, "code": code, "joint": joint, "offset_deg": offset, "level_pct": level, "rate_pct_per_h": None}


def test_a_slip_is_named_right_only_with_its_axis_and_sign():
    f = {"kind": "joint", "onset": 100, "size": 1.0, "axis": 2}
    assert T.named(rec(fault=f, joint_after=alarm(300, "joint-offset-suspected", 2, 0.8)))
    assert not T.named(rec(fault=f, joint_after=alarm(300, "joint-offset-suspected", 1, 0.8)))
    assert not T.named(rec(fault=f, joint_after=alarm(300, "joint-offset-suspected", 2, -0.8)))
    assert not T.named(rec(fault=f))


def test_the_wagons_lag_must_be_named_as_a_lag_and_its_offset_as_an_offset():
    lag = {"kind": "joint", "onset": 100, "size": 1.0, "axis": 4}
    as_lag = alarm(300, "wagon-backlash-suspected", 4, 0.9)
    as_offset = alarm(300, "wagon-offset-suspected", 4, 0.9)
    assert T.named(rec(row="wagon backlash 1° at mid-run", fault=lag, joint_after=as_lag))
    wrong = rec(row="wagon backlash 1° at mid-run", fault=lag, joint_after=as_offset)
    assert not T.named(wrong) and T.wrong_kind(wrong)
    assert T.named(rec(row="wagon +1° at mid-run", fault=lag, joint_after=as_offset))
    wrong = rec(row="wagon +1° at mid-run", fault=lag, joint_after=as_lag)
    assert not T.named(wrong) and T.wrong_kind(wrong)
    assert not T.wrong_kind(rec(row="wagon +1° at mid-run", fault=lag, joint_after=alarm(300, "joint-offset-suspected", 1, 0.9)))


def test_a_camera_pose_moved_is_counted_on_its_own_neither_named_nor_silent():
    f = {"kind": "joint", "onset": 100, "size": 1.0, "axis": 4}
    moved = alarm(300, "camera-pose-moved", None, 0.9)
    rs = [rec(row="wagon +1° at mid-run", fault=f, positioning_after=moved, codes_after=["camera-pose-moved"]),
          rec(row="wagon +1° at mid-run", fault=f, joint_after=alarm(300, "wagon-offset-suspected", 4, 0.9),
              positioning_after=alarm(300, "wagon-offset-suspected", 4, 0.9), codes_after=["wagon-offset-suspected"]),
          rec(row="wagon +1° at mid-run", fault=f)]
    assert not T.named(rs[0]) and not T.false_alarm(rs[0])
    line = T.positioning_table(rs).splitlines()[2]
    cells = [c.strip() for c in line.strip("|").split("|")]
    # named right, named as another axis, camera-pose-moved, no positioning alarm
    assert cells[-5:-1] == ["1 of 3", "0", "1", "1"], cells


def test_a_false_alarm_is_one_in_a_fault_free_run_or_before_the_onset():
    assert T.false_alarm(rec(drift_after=alarm(10)))
    assert not T.false_alarm(rec())
    f = {"kind": "step", "onset": 100, "size": -3.0, "axis": None}
    assert not T.false_alarm(rec(fault=f, drift_after=alarm(200)))
    assert T.false_alarm(rec(fault=f, positioning_before=alarm(50, "joint-offset-suspected", 1, 0.5)))


def test_a_step_caught_late_or_with_the_wrong_sign_is_counted_so():
    f = {"kind": "step", "onset": 100, "size": -3.0, "axis": None}
    rs = [rec(row="s", fault=f, drift_after=alarm(250, level=-2.9)), rec(row="s", fault=f, drift_after=alarm(500, level=-2.9)),
          rec(row="s", fault=f, drift_after=alarm(150, level=2.0)), rec(row="s", fault=f)]
    line = T.step_table(rs).splitlines()[2]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[3] == "2 of 4" and cells[4] == "3 of 4" and cells[5] == "1", cells


if __name__ == "__main__" and "--bless" in sys.argv:
    with open(EXPECTED, "w", encoding="utf-8") as f:
        f.write(render(T.tables(T.load(FIXTURE))))
    print(f"blessed {EXPECTED}")
