"""The held-out model's blocks in BENCHMARKS.md are what benches/holdout.py makes of the committed
records (benches/holdout-records.json), and its plan holds only runs of the matrix's rows under
the held-out model."""

import json
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import holdout as H  # noqa: E402
import matrix as M  # noqa: E402


def test_benchmarks_holds_the_generated_holdout_blocks():
    with open(H.RECORDS, encoding="utf-8") as f:
        records = json.load(f)["records"]
    with open(os.path.join(M.REPO, "BENCHMARKS.md"), encoding="utf-8") as f:
        text = f.read()
    names = re.findall(r"<!-- holdout:([a-z-]+) -->", text)
    assert sorted(names) == sorted(H.blocks(records)), names
    assert H.fill(text, H.blocks(records)) == text, "run `python3 benches/holdout.py tables --write`"


def test_the_plan_is_the_matrix_rows_under_the_held_out_model_and_every_run_is_recorded():
    runs = H.runs()
    assert len({r.id for r in runs}) == len(runs)
    assert all(r.model == H.MODEL and r.row.name in M.ROWS for r in runs)
    assert H.MODEL not in M.MODELS
    with open(H.RECORDS, encoding="utf-8") as f:
        ids = {r["id"] for r in json.load(f)["records"]}
    assert ids == {r.id for r in runs}
