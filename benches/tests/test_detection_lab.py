"""The detection lab's run locks: recorders and scorers side by side on one lab leave a run another
process holds to it."""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import detection as D  # noqa: E402
import matrix as M  # noqa: E402


def test_a_run_lock_is_held_once_and_released(tmp_path):
    lab = str(tmp_path)
    with D.run_lock(lab, "record-x") as first:
        assert first
        # another open of the same lock (as another process would) does not get it
        with D.run_lock(lab, "record-x") as second:
            assert not second
        # another run's lock is free
        with D.run_lock(lab, "record-y") as other:
            assert other
    with D.run_lock(lab, "record-x") as again:
        assert again


def test_a_run_another_process_holds_or_finished_is_left_to_it(tmp_path):
    lab, run = str(tmp_path), M.RUNS[0]
    missing = str(tmp_path / "no-such-binary")
    scores = os.path.join(lab, "scores", "b")
    os.makedirs(scores)
    # held: nothing is run (the binary does not exist, so running it would fail)
    with D.run_lock(lab, f"record-{run.id}"):
        assert D.record_one(run, lab, missing) == 0.0
    with D.run_lock(lab, f"score-b-{run.id}"):
        assert D.score_one(run, lab, missing, scores) == 0.0
    # finished by another: left as it is
    os.makedirs(os.path.join(lab, "runs", run.id))
    with open(os.path.join(lab, "runs", run.id, "record.json"), "w", encoding="utf-8") as f:
        f.write("{}")
    with open(os.path.join(scores, f"{run.id}.json"), "w", encoding="utf-8") as f:
        f.write("{}")
    assert D.record_one(run, lab, missing) == 0.0
    assert D.score_one(run, lab, missing, scores) == 0.0
