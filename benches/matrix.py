"""The detection matrix: the one definition of every run the detection lab records and scores.

A run is one simulated full acquisition (6,561 captures of 16 × 16 pixels, 7 s of rig time a
capture, about 12.8 h) of one material under one nuisance model, with one seed, with or without
drift probes, and with at most a few injected faults. `RUNS` lists them all; a run's `id` names
its folder and its record, so a matrix that grows keeps the runs it had.

Rows (a scenario: the faults and the truth they are scored against) are crossed with groups (a
material, a nuisance model and a probe cadence) and seeds. The nuisance models are the
simulator's `realistic` and `realistic-b` (sim/README.md), which detectors are designed on, and
`realistic-c`, which nothing was designed or tuned on: its rows are out of sample, as are the
fault-free runs at 64 × 64 pixels.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CAPTURES = 6561
T_CAPTURE_S = 7.0

ISOTROPIC = ("walkway", "ceiling", "floortile", "pinkwall")
MODELS = ("realistic", "realistic-b", "realistic-c")
# the models detectors were designed and tuned on; the others are out of sample
DESIGN_MODELS = ("realistic", "realistic-b")
# Light sweep 40 starts at capture 3,240; light sweep 20 (θi = 45°, its second sweep) at 1,700;
# the θi = 75° layer holds lights 57–80 (captures 4,617 on).
EARLY, MID, BOUNDARY, LATE75, END75 = 1700, 3280, 3240, 5200, 5900


@dataclass(frozen=True)
class Truth:
    """What a row's runs are scored against. `kind`: rate (a linear decay), rate-exp, step,
    joint (a positioning fault: arm joints 1–3, axis 4 = the wagon), encoder (a reading off
    while the pose is right), unstable (a flickering lamp); `size`: %/h, %, degrees or the
    flicker's SD in %."""

    kind: str
    onset: int
    size: float
    axis: int | None = None


@dataclass(frozen=True)
class Row:
    name: str
    faults: tuple = ()
    truth: Truth | None = None


def _sign(x: float) -> str:
    return ("+" if x > 0 else "−") + f"{abs(x):g}"


def _rows() -> list[Row]:
    rows = [Row("no fault")]
    for rate, model in ((0.5, "linear"), (1.0, "linear"), (0.5, "exponential")):
        name = f"{'exponential ' if model == 'exponential' else ''}decay {rate:g} %/h"
        rows.append(Row(name, ({"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": rate, "model": model},),
                        Truth("rate-exp" if model == "exponential" else "rate", 0, rate)))
    for size, where, at in ((-1.5, "at mid-run", MID), (-2.0, "at mid-run", MID), (-3.0, "at mid-run", MID),
                            (1.5, "at mid-run", MID), (-1.5, "at a sweep boundary", BOUNDARY),
                            (-1.5, "early", EARLY), (1.5, "early", EARLY), (-3.0, "early", EARLY),
                            (-1.5, "early in the 75° layer", LATE75), (-3.0, "early in the 75° layer", LATE75),
                            (-1.5, "late in the 75° layer", END75)):
        rows.append(Row(f"step {_sign(size)} % {where}", ({"kind": "lamp-step", "at_capture": at, "step_pct": size},),
                        Truth("step", at, size)))
    for j in (1, 2):
        for o, where, at in ((1.0, "early", EARLY), (-1.0, "early", EARLY), (1.0, "at mid-run", MID),
                             (-1.0, "at mid-run", MID), (2.0, "at mid-run", MID), (1.0, "in the 75° layer", LATE75),
                             (-1.0, "in the 75° layer", LATE75)):
            rows.append(Row(f"joint {j} {_sign(o)}° {where}",
                            ({"kind": "joint-offset", "at_capture": at, "joint": j, "offset_deg": o},), Truth("joint", at, o, j)))
    # joint 3 turns an isotropic sample about its normal: nothing to see (the identifiability row)
    rows.append(Row("joint 3 +1° at mid-run", ({"kind": "joint-offset", "at_capture": MID, "joint": 3, "offset_deg": 1.0},),
                    Truth("joint", MID, 1.0, 3)))
    for label, fault, size in (("+1°", {"kind": "wagon-offset", "offset_deg": 1.0}, 1.0),
                               ("−1°", {"kind": "wagon-offset", "offset_deg": -1.0}, -1.0),
                               ("backlash 1°", {"kind": "wagon-backlash", "backlash_deg": 1.0}, 1.0)):
        for where, at in (("early", EARLY), ("at mid-run", MID)):
            rows.append(Row(f"wagon {label} {where}", (dict(fault, at_capture=at),), Truth("joint", at, size, 4)))
    for label, j, o in (("joint 1", 1, 0.3), ("joint 2", 2, 0.3), ("wagon", 4, 0.5)):
        rows.append(Row(f"encoder {label} +{o:g}° at mid-run",
                        ({"kind": "encoder-mismatch", "at_capture": MID, "joint": j, "offset_deg": o},), Truth("encoder", MID, o, j)))
    rows.append(Row("decay 0.5 %/h with joint 2 +1° at mid-run",
                    ({"kind": "lamp-decay", "at_capture": 0, "rate_pct_per_h": 0.5, "model": "linear"},
                     {"kind": "joint-offset", "at_capture": MID, "joint": 2, "offset_deg": 1.0}), Truth("rate", 0, 0.5)))
    rows.append(Row("flicker 3 % per capture", ({"kind": "lamp-flicker", "at_capture": 0, "amplitude_pct": 3.0},),
                    Truth("unstable", 0, 3.0)))
    return rows


ROWS = {r.name: r for r in _rows()}

# with probes every 75 captures (the cadence `goniowatch plan` designs for the anisotropic
# configuration, 2.6 % of the run time), on every isotropic material and model
PROBE_ROWS = ("no fault", "step −1.5 % at mid-run", "step −3 % early", "decay 0.5 %/h", "flicker 3 % per capture",
              "joint 1 +1° at mid-run", "joint 2 +1° at mid-run", "wagon +1° at mid-run", "wagon −1° at mid-run",
              "wagon +1° early", "wagon backlash 1° at mid-run")
# anisotropic samples need probes for their lamp, and get the joint-3 sentinel with them
ANISO_ROWS = ("no fault", "step −3 % at mid-run", "joint 3 +1° at mid-run")


@dataclass(frozen=True)
class Run:
    row: Row
    material: str
    model: str
    seed: int
    every: int = 0
    config: str = "sim.toml"
    # the images' side in pixels: the realistic preset's holder bleed is set in pixels, so its
    # nuisance (and the light sweeps' patterns) change with it; 16 is the lab's size
    image: int = 16

    @property
    def label(self) -> str:
        """The nuisance model as the tables name it, with the image size when not the lab's."""
        return self.model if self.image == 16 else f"{self.model}, {self.image} px"

    @property
    def id(self) -> str:
        name = re.sub(r"−(?=[0-9.]+)", "minus ", self.row.name)
        name = re.sub(r"\+(?=[0-9.]+)", "plus ", name)
        slug = re.sub(r"[^a-z0-9.]+", "-", name.lower()).strip("-")
        probes = f"-p{self.every}" if self.every else ""
        image = f"-i{self.image}" if self.image != 16 else ""
        return f"{slug}--{self.material}-{self.model}{probes}{image}-s{self.seed}"

    def scenario_toml(self, capture_root: str, session_id: str = "r") -> str:
        lines = [f'rig_config = {json.dumps(os.path.join(REPO, "config", self.config))}', "[session]",
                 f"id = {json.dumps(session_id)}", f"capture_root = {json.dumps(capture_root)}",
                 f"image_size = [{self.image}, {self.image}]", "speed = 0", f"seed = {self.seed}",
                 "[material]", f"preset = {json.dumps(self.material)}", f"realism = {json.dumps(self.model)}"]
        for f in self.row.faults:
            lines.append("[[faults]]")
            lines += [f"{k} = {json.dumps(v)}" for k, v in f.items()]
        return "\n".join(lines) + "\n"

    def config_toml(self) -> str:
        text = open(os.path.join(REPO, "config", self.config), encoding="utf-8").read()
        out, n = re.subn(r"(?m)^every = 0$", f"every = {self.every}", text)
        if n != 1:
            raise ValueError(f"config/{self.config}: no single `every = 0` line under [probes] to set the cadence in")
        return out


def _runs() -> list[Run]:
    runs = []
    for material in ISOTROPIC:
        for model in MODELS:
            # fault-free: 20 seeds of each material and model, with and without probes (a false
            # alarm rate of 1 in 20 needs that many to be seen at all)
            runs += [Run(ROWS["no fault"], material, model, s) for s in range(1, 21)]
            runs += [Run(r, material, model, s) for r in ROWS.values() if r.truth for s in (1, 2)]
            runs += [Run(ROWS[n], material, model, s, every=75) for n in PROBE_ROWS
                     for s in (range(1, 21) if n == "no fault" else (1, 2))]
            # out of sample: fault-free at 64 × 64 pixels (the archive demo's size), where nothing
            # was tuned
            runs += [Run(ROWS["no fault"], material, model, s, image=64) for s in (1, 2, 3)]
    for material in ("brushed", "fabric"):
        runs += [Run(ROWS[n], material, "realistic", s, every=75, config="sim-anisotropic.toml")
                 for n in ANISO_ROWS for s in (1, 2)]
    return runs


RUNS = _runs()


def select(pattern: str | None = None) -> list[Run]:
    """The runs whose id matches the regular expression (all without one)."""
    if not pattern:
        return list(RUNS)
    rx = re.compile(pattern)
    return [r for r in RUNS if rx.search(r.id)]


if __name__ == "__main__":
    ids = [r.id for r in RUNS]
    assert len(ids) == len(set(ids)), "run ids must be unique"
    print(f"{len(RUNS)} runs, {len(ROWS)} rows")
