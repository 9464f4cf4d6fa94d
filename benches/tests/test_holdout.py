"""The held-out models' blocks in BENCHMARKS.md are what benches/holdout.py makes of the committed
records (benches/holdout-records-MODEL.json), and each plan holds only runs of the matrix's rows
under its held-out model."""

import json
import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
import holdout as H  # noqa: E402
import matrix as M  # noqa: E402


def test_benchmarks_holds_the_generated_holdout_blocks_of_every_held_out_model():
    with open(os.path.join(M.REPO, "BENCHMARKS.md"), encoding="utf-8") as f:
        text = f.read()
    found = sorted((m.group(1), m.group(2)) for m in H.BLOCK.finditer(text))
    generated = {model: H.blocks(model, H.load(model)) for model in H.MODELS}
    assert found == sorted((model, name) for model, named in generated.items() for name in named), found
    assert H.fill(text, generated) == text, "run `python3 benches/holdout.py tables --write`"


@pytest.mark.parametrize("model", H.MODELS)
def test_the_plan_is_the_matrix_rows_under_the_held_out_model_and_every_run_is_recorded(model):
    runs = H.runs(model)
    assert len({r.id for r in runs}) == len(runs)
    assert all(r.model == model and r.row.name in M.ROWS for r in runs)
    assert model not in M.MODELS
    with open(H.records_path(model), encoding="utf-8") as f:
        data = json.load(f)
    assert data["model"] == model
    assert {r["id"] for r in data["records"]} == {r.id for r in runs}
