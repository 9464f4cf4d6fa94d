"""Scenario files (TOML): the session, the rig and plan (same format as goniowatch's config, or
taken from it with `rig_config`), the material, and the faults. Unknown keys are errors that name
the key."""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field

from .geometry import Plan, Rig
from .material import PRESETS, REALISM

FAULT_KINDS = {
    # kind: allowed keys besides kind/at_capture/at_hours/until_capture
    "lamp-decay": {"rate_pct_per_h", "model"},
    "lamp-step": {"step_pct"},
    "lamp-flicker": {"amplitude_pct"},
    "lamp-colour-drift": {"cct_k_per_h", "cct_start_k"},
    "joint-offset": {"joint", "offset_deg"},
    "wagon-offset": {"offset_deg"},
    "encoder-mismatch": {"joint", "offset_deg"},
    "wagon-backlash": {"backlash_deg"},
    "nan-pixels": {"count"},
    "inf-pixels": {"count"},
    "saturated-block": {"size_px", "value"},
    "dark-frame": set(),
    "truncated-file": {"keep_fraction"},
    "missing-file": set(),
    "slow-write": {"duration_s"},
    "duplicate-index": set(),
    "malformed-announcement": set(),
    "corrupt-bytes": {"rate"},
    "drop-lines": {"rate"},
    "reboot": set(),
    "unplug": {"duration_s"},
    "slow-link": {"baud"},
}
COMMON = {"kind", "at_capture", "at_hours", "until_capture"}
# faults that happen once, at their onset capture
ONE_SHOT = {
    "dark-frame",
    "truncated-file",
    "missing-file",
    "slow-write",
    "duplicate-index",
    "malformed-announcement",
    "reboot",
    "unplug",
    "nan-pixels",
    "inf-pixels",
    "saturated-block",
}


class ScenarioError(ValueError):
    pass


@dataclass
class Fault:
    kind: str
    at_capture: int | None = None
    at_hours: float | None = None
    until_capture: int | None = None
    params: dict = field(default_factory=dict)

    def onset_reached(self, idx: int, t_hours: float) -> bool:
        if self.at_capture is not None and idx < self.at_capture:
            return False
        if self.at_hours is not None and t_hours < self.at_hours:
            return False
        return True

    def active(self, idx: int, t_hours: float) -> bool:
        if not self.onset_reached(idx, t_hours):
            return False
        if self.until_capture is not None and idx >= self.until_capture:
            return False
        return True

    def p(self, key: str, default=None):
        return self.params.get(key, default)


@dataclass
class Scenario:
    # the goniowatch config the rig and plan came from (`rig_config`), absolute; None without
    rig_config: str | None = None
    session_id: str = "demo"
    capture_root: str = "captures"
    port: str = "/tmp/goniowatch-rig"
    truth: str = ""  # default: <capture_root>/<session_id>.truth.jsonl
    format: str = "hdr"  # "hdr" or "exr" (half float, ZIP)
    image_size: tuple[int, int] = (64, 64)  # width, height
    holder_fraction: float = 0.08
    seed: int = 1
    captures: int = 0  # 0 = the whole plan
    start_capture: int = 0
    time_per_capture_s: float = 7.0
    speed: float = 0.0  # 0 = as fast as possible; 1 = real time; k = k times real time
    baud: int = 0  # 0 = unpaced; otherwise bytes are paced at baud/10 per second
    rig_id: str = "ubo-sim"
    firmware: str = "sim-1.0"
    allow_actions: bool = True
    photons_per_unit: float = 4000.0
    read_noise: float = 0.002
    lamp_gain: float = 1.0
    material: str = "walkway"
    realism: str = "clean"
    noise: bool = True
    plan: Plan = field(default_factory=Plan)
    rig: Rig = field(default_factory=Rig)
    faults: list[Fault] = field(default_factory=list)
    base_dir: str = "."

    @property
    def capture_count(self) -> int:
        total = self.plan.captures - self.start_capture
        return total if self.captures <= 0 else min(self.captures, total)

    def truth_path(self) -> str:
        if self.truth:
            return self.truth
        return os.path.join(self.capture_root, f"{self.session_id}.truth.jsonl")


SESSION_KEYS = {
    "id": "session_id",
    "capture_root": "capture_root",
    "port": "port",
    "truth": "truth",
    "format": "format",
    "image_size": "image_size",
    "holder_fraction": "holder_fraction",
    "seed": "seed",
    "captures": "captures",
    "start_capture": "start_capture",
    "time_per_capture_s": "time_per_capture_s",
    "speed": "speed",
    "baud": "baud",
    "rig_id": "rig_id",
    "firmware": "firmware",
    "allow_actions": "allow_actions",
    "photons_per_unit": "photons_per_unit",
    "read_noise": "read_noise",
    "lamp_gain": "lamp_gain",
    "noise": "noise",
}


def _check_keys(section: str, d: dict, allowed: set[str]) -> None:
    for k in d:
        if k not in allowed:
            raise ScenarioError(f"{section}.{k}: unknown key (allowed: {', '.join(sorted(allowed))})")


def load(path: str, overrides: dict | None = None) -> Scenario:
    with open(path, "rb") as f:
        data = tomllib.load(f)
    return from_dict(data, base_dir=os.path.dirname(os.path.abspath(path)), overrides=overrides)


def from_dict(data: dict, base_dir: str = ".", overrides: dict | None = None) -> Scenario:
    _check_keys("scenario", data, {"session", "material", "rig", "plan", "faults", "rig_config"})
    sc = Scenario(base_dir=base_dir)
    rig_section: dict = {}
    plan_section: dict = {}
    if "rig_config" in data:
        cfg_path = data["rig_config"]
        if not os.path.isabs(cfg_path):
            cfg_path = os.path.join(base_dir, cfg_path)
        with open(cfg_path, "rb") as f:
            cfg = tomllib.load(f)
        sc.rig_config = os.path.abspath(cfg_path)
        rig_section = dict(cfg.get("rig", {}))
        plan_section = dict(cfg.get("plan", {}))
    rig_section.update(data.get("rig", {}))
    plan_section.update(data.get("plan", {}))
    session = dict(data.get("session", {}))
    session.update(overrides or {})
    _check_keys("session", session, set(SESSION_KEYS))
    for k, v in session.items():
        setattr(sc, SESSION_KEYS[k], v)
    sc.image_size = tuple(int(v) for v in sc.image_size)  # type: ignore[assignment]
    if len(sc.image_size) != 2 or min(sc.image_size) < 8:
        raise ScenarioError("session.image_size: needs [width, height], each at least 8")
    if sc.format not in ("hdr", "exr"):
        raise ScenarioError(f"session.format: {sc.format!r} is not 'hdr' or 'exr'")
    if not (sc.speed >= 0 and math.isfinite(sc.speed)):
        raise ScenarioError("session.speed: must be 0 (max) or a positive factor")
    for k in ("capture_root", "truth"):
        v = getattr(sc, k)
        if v and not os.path.isabs(v):
            setattr(sc, k, os.path.join(base_dir, v))
    mat = data.get("material", {})
    _check_keys("material", mat, {"preset", "realism"})
    sc.material = mat.get("preset", sc.material)
    sc.realism = mat.get("realism", sc.realism)
    if sc.material not in PRESETS:
        raise ScenarioError(f"material.preset: {sc.material!r} is not one of {sorted(PRESETS)}")
    if sc.realism not in REALISM:
        raise ScenarioError(f"material.realism: {sc.realism!r} is not one of {sorted(REALISM)}")
    _check_keys("plan", plan_section, {"thetas_deg", "delta_phi_deg", "order"})
    try:
        sc.plan = Plan(**plan_section)
        sc.rig = Rig.from_dict(rig_section)
    except (TypeError, ValueError) as e:
        raise ScenarioError(str(e)) from e
    for i, f in enumerate(data.get("faults", [])):
        kind = f.get("kind")
        if kind not in FAULT_KINDS:
            raise ScenarioError(f"faults[{i}].kind: {kind!r} is not one of {sorted(FAULT_KINDS)}")
        _check_keys(f"faults[{i}]", f, COMMON | FAULT_KINDS[kind])
        if "at_capture" not in f and "at_hours" not in f:
            raise ScenarioError(f"faults[{i}]: needs at_capture or at_hours")
        params = {k: v for k, v in f.items() if k not in COMMON}
        sc.faults.append(Fault(kind, f.get("at_capture"), f.get("at_hours"), f.get("until_capture"), params))
    return sc
