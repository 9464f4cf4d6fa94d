"""The held-out nuisance model: rows of the detection matrix run under `realism = "realistic-d"`
(a bowed sample and a gripper jaw's shadow, sim/README.md), which no goniowatch design, tuning
or rule was made with in view. The matrix's third model, `realistic-c`, was meant to be that, but
two rules were found on its runs; this one is only recorded and scored, never looked into to
change a detector. Recordings and scores use the detection lab's machinery (benches/detection.py),
in their own lab folder.

  python3 benches/holdout.py record [--jobs 2] [--lab target/lab-holdout] [--bin BIN]
  python3 benches/holdout.py score  [--jobs 2] [--lab target/lab-holdout] [--bin BIN]
                                    [--out benches/holdout-records.json]
  python3 benches/holdout.py tables [--write] [RECORDS]

`tables` prints the blocks generated from the records (`--write`: fills the `<!-- holdout:NAME -->`
blocks of BENCHMARKS.md)."""

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

MODEL = "realistic-d"
RECORDS = os.path.join(M.REPO, "benches", "holdout-records.json")
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


def runs() -> list[M.Run]:
    return [M.Run(M.ROWS[row], material, MODEL, seed, every)
            for row, every, seeds in PLAN for material in M.ISOTROPIC for seed in seeds]


def cmd_record(a) -> int:
    todo = [r for r in runs() if not os.path.exists(os.path.join(a.lab, "runs", r.id, "record.json"))]
    print(f"holdout record: {len(todo)} of {len(runs())} runs to record, {a.jobs} at once, into {a.lab}/runs", flush=True)
    if todo:
        D.pool_map(lambda r: D.record_one(r, a.lab, a.bin), todo, a.jobs, D.Progress("recorded", len(todo), a.jobs))
    return 0


def cmd_score(a) -> int:
    bid, records, recorded, elsewhere = D.score_runs(runs(), a.lab, a.bin, a.jobs, "holdout score")
    if elsewhere:
        return 1
    with open(a.out, "w", encoding="utf-8") as f:
        json.dump({"binary": bid, "model": MODEL, "runs_in_plan": len(runs()), "records": records}, f, indent=0, sort_keys=True)
        f.write("\n")
    print(f"holdout score: {len(records)} records to {a.out}")
    return 0 if recorded == len(runs()) else 1


def blocks(records: list[dict]) -> dict[str, str]:
    """The generated blocks: what each fault class got right, and the fault-free runs' alarms."""
    lines = [line for line in T._catches_lines(records) if line[2] != "–"]
    return {
        "count": f"{len(records)} runs scored ({MODEL}, 16 × 16).",
        "catches": T.table(["fault (simulated rig: 4 isotropic materials)", "probes", f"runs right, held out ({MODEL})"], lines),
        "false-alarms": T.false_alarm_table(records),
    }


def fill(text: str, generated: dict[str, str]) -> str:
    def sub(m):
        return f"<!-- holdout:{m.group(1)} -->\n{generated[m.group(1)]}\n<!-- /holdout:{m.group(1)} -->"

    return re.sub(r"<!-- holdout:([a-z-]+) -->.*?<!-- /holdout:\1 -->", sub, text, flags=re.S)


def cmd_tables(a) -> int:
    with open(a.records, encoding="utf-8") as f:
        records = json.load(f)["records"]
    generated = blocks(records)
    if not a.write:
        for name, text in generated.items():
            print(f"<!-- holdout:{name} -->\n{text}\n<!-- /holdout:{name} -->\n")
        return 0
    path = os.path.join(M.REPO, "BENCHMARKS.md")
    with open(path, encoding="utf-8") as f:
        text = f.read()
    with open(path, "w", encoding="utf-8") as f:
        f.write(fill(text, generated))
    print("BENCHMARKS.md: holdout tables written")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("record", "score"):
        p = sub.add_parser(name)
        p.add_argument("--lab", default=os.path.join(M.REPO, "target", "lab-holdout"))
        p.add_argument("--bin", default=D.DEFAULT_BIN)
        p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
        if name == "score":
            p.add_argument("--out", default=RECORDS)
    p = sub.add_parser("tables")
    p.add_argument("records", nargs="?", default=RECORDS)
    p.add_argument("--write", action="store_true")
    a = ap.parse_args()
    if a.cmd == "tables":
        return cmd_tables(a)
    if not os.access(a.bin, os.X_OK):
        sys.exit(f"no goniowatch binary at {a.bin}: run `cargo build --release` or set GONIOWATCH_BIN")
    a.bin, a.lab = os.path.abspath(a.bin), os.path.abspath(a.lab)
    os.makedirs(a.lab, exist_ok=True)
    return {"record": cmd_record, "score": cmd_score}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
