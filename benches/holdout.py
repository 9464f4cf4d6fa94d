"""The held-out nuisance models: rows of the detection matrix run under `realism = "realistic-d"`
(a bowed sample and a gripper jaw's shadow) and `"realistic-e"` (a sample on a wedge, a bracket
relighting it, a trace of anisotropy; sim/README.md), written to be kept out of every goniowatch
design, tuning or rule. They are only recorded and scored, never looked into to change a
detector; a model a decision has answered says so in BENCHMARKS.md, and the next one takes its
place. Recordings and scores use the detection lab's machinery (benches/detection.py), in their
own lab folder.

  python3 benches/holdout.py record [--model M] [--jobs 2] [--lab target/lab-holdout] [--bin BIN]
  python3 benches/holdout.py score  [--model M] [--jobs 2] [--lab target/lab-holdout] [--bin BIN]
  python3 benches/holdout.py tables [--model M] [--write]

Without `--model`, every held-out model. `score` writes benches/holdout-records-MODEL.json;
`tables` prints the blocks generated from those records (`--write`: fills the
`<!-- holdout:MODEL:NAME -->` blocks of BENCHMARKS.md)."""

from __future__ import annotations

import argparse
import json
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import detection as D  # noqa: E402
import detection_tables as T  # noqa: E402
import matrix as M  # noqa: E402

MODELS = ("realistic-d", "realistic-e")
# (row, probe cadence, seeds): fault-free runs with and without probes, and one run of each of
# the faults the product's alarms are for on every material
PLAN = (
    ("no fault", 0, range(1, 6)),
    ("no fault", 75, range(1, 4)),
    ("step −1.5 % at mid-run", 0, (1,)),
    ("step −1.5 % at mid-run", 75, (1,)),
    ("joint 2 +1° at mid-run", 0, (1,)),
    ("joint 1 +1° at mid-run", 75, (1,)),
    ("wagon +1° at mid-run", 75, (1,)),
)


def records_path(model: str) -> str:
    """The committed records of `model`'s plan."""
    return os.path.join(M.REPO, "benches", f"holdout-records-{model}.json")


def runs(model: str) -> list[M.Run]:
    return [M.Run(M.ROWS[row], material, model, seed, every)
            for row, every, seeds in PLAN for material in M.ISOTROPIC for seed in seeds]


def cmd_record(a) -> int:
    for model in a.models:
        plan = runs(model)
        todo = [r for r in plan if not os.path.exists(os.path.join(a.lab, "runs", r.id, "record.json"))]
        print(f"holdout record ({model}): {len(todo)} of {len(plan)} runs to record, {a.jobs} at once, into {a.lab}/runs", flush=True)
        if todo:
            D.pool_map(lambda r: D.record_one(r, a.lab, a.bin), todo, a.jobs, D.Progress("recorded", len(todo), a.jobs))
    return 0


def cmd_score(a) -> int:
    status = 0
    for model in a.models:
        plan = runs(model)
        bid, records, recorded, elsewhere = D.score_runs(plan, a.lab, a.bin, a.jobs, f"holdout score ({model})")
        if elsewhere:
            return 1
        out = records_path(model)
        with open(out, "w", encoding="utf-8") as f:
            json.dump({"binary": bid, "model": model, "runs_in_plan": len(plan), "records": records}, f, indent=0, sort_keys=True)
            f.write("\n")
        print(f"holdout score ({model}): {len(records)} records to {out}")
        if recorded != len(plan):
            status = 1
    return status


def blocks(model: str, records: list[dict]) -> dict[str, str]:
    """The generated blocks of `model`: what each fault class got right, and the fault-free
    runs' alarms."""
    lines = [line for line in T._catches_lines(records) if line[2] != "–"]
    return {
        "count": f"{len(records)} runs scored ({model}, 16 × 16).",
        "catches": T.table(["fault (simulated rig: 4 isotropic materials)", "probes", f"runs right, held out ({model})"], lines),
        "false-alarms": T.false_alarm_table(records),
    }


def load(model: str) -> list[dict]:
    with open(records_path(model), encoding="utf-8") as f:
        return json.load(f)["records"]


BLOCK = re.compile(r"<!-- holdout:(realistic-[a-z]+):([a-z-]+) -->.*?<!-- /holdout:\1:\2 -->", re.S)


def fill(text: str, generated: dict[str, dict[str, str]]) -> str:
    """`text` with every `<!-- holdout:MODEL:NAME -->` block of a model in `generated` filled."""
    def sub(m):
        model, name = m.group(1), m.group(2)
        if model not in generated:
            return m.group(0)
        return f"<!-- holdout:{model}:{name} -->\n{generated[model][name]}\n<!-- /holdout:{model}:{name} -->"

    return BLOCK.sub(sub, text)


def cmd_tables(a) -> int:
    generated = {model: blocks(model, load(model)) for model in a.models}
    if not a.write:
        for model, named in generated.items():
            for name, text in named.items():
                print(f"<!-- holdout:{model}:{name} -->\n{text}\n<!-- /holdout:{model}:{name} -->\n")
        return 0
    path = os.path.join(M.REPO, "BENCHMARKS.md")
    with open(path, encoding="utf-8") as f:
        text = f.read()
    with open(path, "w", encoding="utf-8") as f:
        f.write(fill(text, generated))
    print(f"BENCHMARKS.md: holdout tables written ({', '.join(generated)})")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("record", "score"):
        p = sub.add_parser(name)
        p.add_argument("--lab", default=os.path.join(M.REPO, "target", "lab-holdout"))
        p.add_argument("--bin", default=D.DEFAULT_BIN)
        p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
        p.add_argument("--model", choices=MODELS)
    p = sub.add_parser("tables")
    p.add_argument("--model", choices=MODELS)
    p.add_argument("--write", action="store_true")
    a = ap.parse_args()
    a.models = (a.model,) if a.model else MODELS
    if a.cmd == "tables":
        return cmd_tables(a)
    if not os.access(a.bin, os.X_OK):
        sys.exit(f"no goniowatch binary at {a.bin}: run `cargo build --release` or set GONIOWATCH_BIN")
    a.bin, a.lab = os.path.abspath(a.bin), os.path.abspath(a.lab)
    os.makedirs(a.lab, exist_ok=True)
    return {"record": cmd_record, "score": cmd_score}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
