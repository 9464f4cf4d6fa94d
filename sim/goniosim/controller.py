"""The simulated arm/wagon controller: runs the plan, renders and writes the captures, speaks
docs/protocol.md on its serial port, injects the scenario's faults, and writes the truth file."""

from __future__ import annotations

import json
import math
import os
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import serial

from . import protocol as P
from .geometry import vec_to_sph
from .link import Cable
from .material import PRESETS, REALISM, albedo_texture
from .render import add_noise, exr_bytes_to_file, hdr_bytes, png_bytes, render, write_atomic
from .scenario import ONE_SHOT, Scenario
from .spectral import lamp_colour_matrix

PROTO_VERSION = 1
TRUTH_ROI_FRACTION = 0.1


@dataclass
class CaptureRecord:
    idx: int
    entry: int
    fields: dict


class NoCable:
    """The cable of a rig without a serial link (`archive`): its faults have nothing to act on."""

    rig_path = None
    corrupt_rate = 0.0
    drop_rate = 0.0
    baud = 0

    def unplug(self, duration_s: float) -> None:
        pass

    def close(self) -> None:
        pass


# File names of a capture set written without a controller (`archive --naming`): the Bonn
# convention with the plan's nominal angles, optionally after the capture index.
NAMINGS = ("bonn", "bonn-indexed", "sidecar")
# The exposure of LDR captures written without a sidecar to record a per-capture one.
LDR_EXPOSURE = 0.25


class Controller:
    def __init__(
        self,
        sc: Scenario,
        cable: Cable | None = None,
        log=sys.stderr,
        linger_s: float = 5.0,
        naming: str | None = None,
        ldr: str | None = None,
        link=None,
        name_format: str | None = None,
    ) -> None:
        """`naming` set: no serial link; the captures are named by `naming` (NAMINGS), and with
        "sidecar" a captures.csv beside them maps each file to its angles and time. `link` set
        (a `lockstep.DaemonLink`): the controller talks to the daemon in lockstep instead of
        over a serial port, and writes its captures without fsync."""
        self.sc = sc
        self.naming = naming
        # archive only: a rig's own file names, a Python format string over idx, entry, tl, pl,
        # tv, pv (the plan's nominal angles in degrees) and ext, under the session's folder
        self.name_format = name_format
        # archive only: captures as sRGB PNG ("png8", "png16"), auto-exposed per capture when a
        # sidecar records the exposure, else at the fixed LDR_EXPOSURE
        self.ldr = ldr
        self.lockstep = link is not None
        if naming is not None or link is not None:
            cable = NoCable()
        self.cable = cable if cable is not None else Cable(sc.port, sc.baud, sc.seed)
        self.own_cable = cable is None
        self.log = log
        self.linger_s = linger_s
        if link is not None:
            self.ser = link
        else:
            self.ser = serial.Serial(self.cable.rig_path, baudrate=115200, timeout=0) if naming is None else None
        self.sidecar = None
        if naming == "sidecar":
            os.makedirs(os.path.join(sc.capture_root, sc.session_id), exist_ok=True)
            self.sidecar = open(os.path.join(sc.capture_root, sc.session_id, "captures.csv"), "w", encoding="utf-8")
            self.sidecar.write("file,theta_i,phi_i,theta_o,phi_o,t" + (",exposure" if ldr else "") + "\n")
        self.rx = P.LineBuffer()
        self.seq = 0
        self.boot = 0
        self.subscribed = False
        self.state = "running"
        self.t = 0.0  # controller time, seconds since session start
        self.next_idx = 0
        self.captures: list[CaptureRecord] = []
        self.probes: list[int] = []
        self.prev_cmd: list[float] | None = None
        self.poses: dict[int, tuple] = {}
        # the wagon's last direction of motion (+1, -1; 0 before it first moved): the backlash
        # lag persists while the wagon stands still
        self.wagon_move = 0.0
        self.material = PRESETS[sc.material]
        self.realism = REALISM[sc.realism]
        w, h = sc.image_size
        self.albedo = albedo_texture(self.material, h, w, sc.seed)
        self.holder_px = max(1, int(round(sc.holder_fraction * min(w, h))))
        self.rng = np.random.default_rng(sc.seed + 1)
        self.flicker_rng = np.random.default_rng(sc.seed + 2)
        os.makedirs(os.path.join(sc.capture_root, sc.session_id), exist_ok=True)
        os.makedirs(os.path.dirname(os.path.abspath(sc.truth_path())), exist_ok=True)
        self.truth = open(sc.truth_path(), "w", encoding="utf-8")
        self.stats = {"bad_lines": 0, "commands": 0}
        self.fired: set[int] = set()  # one-shot faults already fired (by index in sc.faults)
        self._writers: list[threading.Thread] = []
        self.stop = threading.Event()  # ends the linger after the session

    # -- serial ----------------------------------------------------------------------------------
    def send(self, verb: str, fields: dict | None = None, event: bool = False) -> None:
        if self.ser is None or (event and not self.subscribed):
            return
        line = P.frame(self.seq, verb, fields)
        self.seq = (self.seq + 1) % P.SEQ_MOD
        self.ser.write(line)

    def poll(self) -> None:
        if self.ser is None:
            return
        if self.lockstep:
            # everything the daemon answered, and what it answers to the replies
            while self.ser.pending:
                self._poll_once()
            return
        self._poll_once()

    def _poll_once(self) -> None:
        data = self.ser.read(65536)
        if not data:
            return
        for line in self.rx.feed(data):
            try:
                msg = P.parse(line)
            except P.ProtocolError:
                self.stats["bad_lines"] += 1
                self.send("NAK", {"ref": -1, "reason": "bad-crc"})
                continue
            self.handle(msg)

    def handle(self, m: P.Message) -> None:
        self.stats["commands"] += 1
        ref = m.seq
        if m.verb == "HELLO":
            versions = [v for v in (m.get("proto") or "").split(",") if v]
            if str(PROTO_VERSION) not in versions:
                self.send("NAK", {"ref": ref, "reason": "unsupported-version", "supported": PROTO_VERSION})
            else:
                self.send_ident()
        elif m.verb == "SUBSCRIBE":
            self.subscribed = True
            self.send("ACK", {"ref": ref})
            self.send("STATUS", {"state": self.state, "t": f"{self.t:.3f}", "next": self.next_idx})
        elif m.verb == "RESYNC":
            try:
                start = int(m.get("from", "0") or 0)
            except ValueError:
                self.send("NAK", {"ref": ref, "reason": "bad-args"})
                return
            n = 0
            for rec in self.captures:
                if rec.idx >= start:
                    f = dict(rec.fields)
                    f["replay"] = 1
                    self.send("CAPTURE", f)
                    n += 1
            self.send("ACK", {"ref": ref, "count": n, "next": self.next_idx, "state": self.state})
        elif m.verb == "POSE?":
            cmd = self.prev_cmd or [0.0, 0.0, 0.0, 0.0]
            self.send("POSE", {"t": f"{self.t:.3f}", "cmd": P.fmt_pose(cmd), "enc": P.fmt_pose(cmd), "ref": ref})
        elif m.verb in ("PAUSE", "RESUME"):
            if not self.sc.allow_actions:
                self.send("NAK", {"ref": ref, "reason": "refused"})
                return
            self.state = "paused" if m.verb == "PAUSE" else "running"
            self.send("ACK", {"ref": ref})
            self.send("STATUS", {"state": self.state, "t": f"{self.t:.3f}", "next": self.next_idx}, event=True)
        elif m.verb == "PROBE":
            if not self.sc.allow_actions:
                self.send("NAK", {"ref": ref, "reason": "refused"})
                return
            try:
                entry = int(m.get("entry", ""))
                if not 0 <= entry < self.sc.plan.captures:
                    raise ValueError
            except ValueError:
                self.send("NAK", {"ref": ref, "reason": "bad-args"})
                return
            self.probes.append(entry)
            self.send("ACK", {"ref": ref, "queued": len(self.probes)})
        else:
            self.send("NAK", {"ref": ref, "reason": "unknown-verb"})

    def send_ident(self) -> None:
        self.send(
            "IDENT",
            {
                "rig": self.sc.rig_id,
                "fw": self.sc.firmware,
                "proto": PROTO_VERSION,
                "session": self.sc.session_id,
                "captures": self.sc.capture_count,
                "boot": self.boot,
            },
        )

    def reboot(self) -> None:
        """Controller restart: sequence restarts, subscription is lost, the capture log is kept."""
        self.boot += 1
        self.seq = 0
        self.subscribed = False
        self.rx = P.LineBuffer()
        self.send_ident()

    # -- faults ------------------------------------------------------------------------------------
    def active_faults(self, idx: int) -> list[tuple[int, object]]:
        t_h = self.t / 3600.0
        out = []
        for i, f in enumerate(self.sc.faults):
            if f.kind in ONE_SHOT:
                if i not in self.fired and f.onset_reached(idx, t_h):
                    out.append((i, f))
            elif f.active(idx, t_h):
                out.append((i, f))
        return out

    def onset_hours(self, f) -> float:
        if f.at_hours is not None:
            return float(f.at_hours)
        return (f.at_capture or 0) * self.sc.time_per_capture_s / 3600.0

    def lamp_gain(self, faults) -> float:
        g = self.sc.lamp_gain
        t_h = self.t / 3600.0
        for _, f in faults:
            if f.kind == "lamp-decay":
                dt = max(0.0, t_h - self.onset_hours(f))
                r = float(f.p("rate_pct_per_h", 1.0)) / 100.0
                g *= math.exp(-r * dt) if f.p("model", "linear") == "exponential" else max(0.0, 1.0 - r * dt)
            elif f.kind == "lamp-step":
                g *= 1.0 + float(f.p("step_pct", -3.0)) / 100.0
            elif f.kind == "lamp-flicker":
                g *= 1.0 + float(f.p("amplitude_pct", 1.0)) / 100.0 * float(self.flicker_rng.normal())
            elif f.kind == "dark-frame":
                g = 0.0
        return g

    def lamp_cct(self, faults) -> float | None:
        """The lamp's colour temperature (K) under a `lamp-colour-drift` fault, else None (the
        lamp the camera was white-balanced on). Linear in time from the onset, not below 1000 K."""
        t_h = self.t / 3600.0
        for _, f in faults:
            if f.kind == "lamp-colour-drift":
                dt = max(0.0, t_h - self.onset_hours(f))
                start = float(f.p("cct_start_k", 3000.0))
                return max(1000.0, start + float(f.p("cct_k_per_h", -20.0)) * dt)
        return None

    # -- one capture ---------------------------------------------------------------------------
    def take(self, entry: int, probe: bool = False) -> None:
        sc = self.sc
        idx = self.next_idx
        faults = self.active_faults(idx)
        kinds = {f.kind for _, f in faults}
        for i, f in faults:
            if f.kind in ONE_SHOT:
                self.fired.add(i)
        if "reboot" in kinds:
            self.reboot()
        if "unplug" in kinds:
            f = next(f for _, f in faults if f.kind == "unplug")
            self.cable.unplug(float(f.p("duration_s", 2.0)))
        self.cable.corrupt_rate = max([float(f.p("rate", 0.0)) for _, f in faults if f.kind == "corrupt-bytes"] or [0.0])
        self.cable.drop_rate = max([float(f.p("rate", 0.0)) for _, f in faults if f.kind == "drop-lines"] or [0.0])
        slow = [int(f.p("baud", 9600)) for _, f in faults if f.kind == "slow-link"]
        self.cable.baud = min(slow) if slow else sc.baud

        light, camera = sc.plan.entry(entry)
        ld, cd = sc.plan.directions[light], sc.plan.directions[camera]
        if entry not in self.poses:
            # the commanded pose of a plan entry is a function of the rig and the plan alone
            self.poses[entry] = sc.rig.plan_pose(ld, cd)
        cmd, _, _, sub = self.poses[entry]
        true_pose = list(cmd)
        enc = list(cmd)
        if self.prev_cmd is not None and cmd[3] != self.prev_cmd[3]:
            self.wagon_move = math.copysign(1.0, cmd[3] - self.prev_cmd[3])
        for _, f in faults:
            if f.kind == "joint-offset":
                j = int(f.p("joint", 1)) - 1
                true_pose[j] += float(f.p("offset_deg", 1.0))
            elif f.kind == "wagon-offset":
                true_pose[3] += float(f.p("offset_deg", 1.0))
            elif f.kind == "encoder-mismatch":
                j = int(f.p("joint", 1)) - 1
                enc[j] += float(f.p("offset_deg", 0.5))
            elif f.kind == "wagon-backlash" and self.wagon_move != 0.0:
                true_pose[3] -= math.copysign(float(f.p("backlash_deg", 0.5)), self.wagon_move)
        self.prev_cmd = list(cmd)
        self.send("POSE", {"t": f"{self.t:.3f}", "cmd": P.fmt_pose(cmd), "enc": P.fmt_pose(enc)}, event=True)

        wi, wo = sc.rig.forward(true_pose)
        gain = self.lamp_gain(faults)
        clean = render(self.albedo, wi, wo, self.material, self.realism, gain, self.holder_px)
        cct = self.lamp_cct(faults)
        if cct is not None:
            f = next(f for _, f in faults if f.kind == "lamp-colour-drift")
            clean = clean @ lamp_colour_matrix(cct, float(f.p("cct_start_k", 3000.0))).T
        img = add_noise(clean, self.rng, sc.photons_per_unit, sc.read_noise) if sc.noise else clean.copy()
        if "nan-pixels" in kinds or "inf-pixels" in kinds:
            for _, f in faults:
                if f.kind in ("nan-pixels", "inf-pixels"):
                    n = int(f.p("count", 10))
                    ys = self.rng.integers(0, img.shape[0], n)
                    xs = self.rng.integers(0, img.shape[1], n)
                    img[ys, xs, self.rng.integers(0, 3, n)] = np.nan if f.kind == "nan-pixels" else np.inf
        if "saturated-block" in kinds:
            f = next(f for _, f in faults if f.kind == "saturated-block")
            s = int(f.p("size_px", 8))
            h, w, _ = img.shape
            y0, x0 = (h - s) // 2, (w - s) // 2
            img[y0 : y0 + s, x0 : x0 + s, :] = float(f.p("value", 65504.0))

        # NaN/Inf cannot be stored in Radiance RGBE: such captures are written as OpenEXR
        fmt = "exr" if ("nan-pixels" in kinds or "inf-pixels" in kinds or sc.format == "exr") else "hdr"
        exposure = None
        if self.ldr is not None:
            fmt = "png"
            exposure = self.exposure_for(img)
        nominal = (ld[0], ld[1], cd[0], cd[1])
        rel = self.file_name(idx, entry, fmt, nominal)
        path = os.path.join(sc.capture_root, rel)
        written = self.write_capture(path, img, fmt, kinds, exposure)
        if self.sidecar is not None:
            name = rel.split("/", 1)[1]
            extra = f",{exposure!r}" if exposure is not None else ""
            self.sidecar.write(f"{name},{nominal[0]:g},{nominal[1]:g},{nominal[2]:g},{nominal[3]:g},{self.t:.3f}{extra}\n")
            self.sidecar.flush()

        fields = {
            "idx": idx,
            "entry": entry,
            "file": rel,
            "t": f"{self.t:.3f}",
            "cmd": P.fmt_pose(cmd),
            "enc": P.fmt_pose(enc),
            "exp": "hdr5",
        }
        if sub is not None:
            fields["sub"] = f"{sub:.4f}"
        if probe:
            fields["probe"] = 1
        if "malformed-announcement" in kinds:
            # an intact line (valid CRC) with a bad percent escape, live and in every resend
            fields["file"] = P.Raw(P.encode_value(rel) + "%ZZ")
        self.captures.append(CaptureRecord(idx, entry, fields))
        announced = dict(fields)
        if "duplicate-index" in kinds and idx > 0:
            announced["idx"] = idx - 1
        self.send("CAPTURE", announced, event=True)

        ti, pi = vec_to_sph(wi)
        to, po = vec_to_sph(wo)
        # the same region as goniowatch's default for the simulator, margin-fraction 0.1
        my, mx = int(clean.shape[0] * TRUTH_ROI_FRACTION), int(clean.shape[1] * TRUTH_ROI_FRACTION)
        roi = clean[my : clean.shape[0] - my, mx : clean.shape[1] - mx].reshape(-1, 3)
        truth = {
            "idx": idx,
            "entry": entry,
            "light": light,
            "camera": camera,
            "probe": probe,
            "file": rel,
            "format": fmt,
            "written": written,
            "t": round(self.t, 6),
            "cmd": cmd,
            "enc": enc,
            "true_pose": true_pose,
            "substitute_theta_i": sub,
            "true_angles": [ti, pi, to, po],
            "lamp_gain": gain,
            "lamp_cct_k": cct,
            "faults": sorted(kinds),
            "announced_idx": announced["idx"],
            "boot": self.boot,
            "mean_rgb_noiseless_roi": roi.mean(axis=0).tolist(),
        }
        self.truth.write(json.dumps(truth) + "\n")
        self.truth.flush()
        self.next_idx += 1
        self.t += sc.time_per_capture_s

    def file_name(self, idx: int, entry: int, fmt: str, nominal: tuple) -> str:
        """The capture's path under the capture root."""
        ti, pi, to, po = nominal
        if self.name_format is not None:
            name = self.name_format.format(idx=idx, entry=entry, tl=ti, pl=pi, tv=to, pv=po, ext=fmt)
            return f"{self.sc.session_id}/{name}"
        bonn = f"tl{ti:03.0f}_pl{pi:03.0f}_tv{to:03.0f}_pv{po:03.0f}.{fmt}"
        if self.naming == "bonn":
            return f"{self.sc.session_id}/{bonn}"
        if self.naming == "bonn-indexed":
            return f"{self.sc.session_id}/{idx:05d}_{bonn}"
        return f"{self.sc.session_id}/cap_{idx:05d}_e{entry:04d}.{fmt}"

    def exposure_for(self, img: np.ndarray) -> float:
        """The LDR exposure: with a sidecar, the largest power of two (as a camera's shutter
        steps) that keeps the brightest pixel below 0.9, so nothing clips; without, the fixed
        LDR_EXPOSURE."""
        if self.sidecar is None:
            return LDR_EXPOSURE
        top = float(np.max(np.nan_to_num(img, nan=0.0, posinf=0.0)))
        return float(2.0 ** math.floor(math.log2(0.9 / top))) if top > 0 else 1.0

    def write_capture(self, path: str, img: np.ndarray, fmt: str, kinds: set[str], exposure: float | None = None) -> bool:
        if "missing-file" in kinds:
            return False
        if fmt == "png":
            data = png_bytes(img, exposure or 1.0, 16 if self.ldr == "png16" else 8)
        elif fmt == "exr":
            tmp = os.path.join(os.path.dirname(path), "." + os.path.basename(path) + ".tmp.exr")
            exr_bytes_to_file(img, tmp, half=True)
            with open(tmp, "rb") as f:
                data = f.read()
            os.unlink(tmp)
        else:
            data = hdr_bytes(img)
        if "truncated-file" in kinds:
            f = next(f for f in self.sc.faults if f.kind == "truncated-file" and self.sc.faults.index(f) in self.fired)
            data = data[: max(1, int(len(data) * float(f.p("keep_fraction", 0.5))))]
        if "slow-write" in kinds:
            f = next(f for f in self.sc.faults if f.kind == "slow-write" and self.sc.faults.index(f) in self.fired)
            th = threading.Thread(target=slow_write, args=(path, data, float(f.p("duration_s", 2.0))), daemon=True)
            th.start()
            self._writers.append(th)
            return True
        write_atomic(path, data, durable=not self.lockstep)
        return True

    # -- the session -----------------------------------------------------------------------------
    def sleep(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while True:
            self.poll()
            left = end - time.monotonic()
            if left <= 0:
                return
            time.sleep(min(left, 0.005))

    def run(self) -> None:
        sc = self.sc
        self.reboot()  # first boot: IDENT, boot = 1
        if self.lockstep:
            self.poll()
        elif self.ser is not None:
            self.sleep(0.05)
        period = sc.time_per_capture_s / sc.speed if sc.speed > 0 else 0.0
        count = sc.capture_count
        started = time.monotonic()
        for k in range(count):
            self.poll()
            if self.lockstep and self.state == "paused":
                # nothing is left to resume it: the run ends here, as an operator would end it
                print(f"goniosim: paused by the daemon at capture {self.next_idx}; the lockstep run ends", file=self.log, flush=True)
                break
            while self.state == "paused":
                self.sleep(0.01)
            while self.probes:
                self.take(self.probes.pop(0), probe=True)
            self.take(sc.start_capture + k)
            if period:
                self.sleep(max(0.0, started + (k + 1) * period - time.monotonic()))
            if self.log and (k % 500 == 0 or k == count - 1):
                print(f"goniosim: capture {k + 1}/{count}", file=self.log, flush=True)
        self.state = "done"
        self.send("STATUS", {"state": "done", "t": f"{self.t:.3f}", "next": self.next_idx}, event=True)
        for th in self._writers:
            th.join()
        if self.ser is None:
            return
        if self.lockstep:
            self.poll()
            return
        end = time.monotonic() + self.linger_s
        while time.monotonic() < end and not self.stop.is_set():
            self.sleep(0.02)

    def close(self) -> None:
        self.truth.close()
        if self.sidecar is not None:
            self.sidecar.close()
        if self.ser is not None:
            self.ser.close()
        if self.own_cable:
            self.cable.close()


def slow_write(path: str, data: bytes, duration_s: float) -> None:
    """Write in place, without a rename, in pieces spread over `duration_s`."""
    pieces = 8
    step = max(1, len(data) // pieces)
    with open(path, "wb") as f:
        for i in range(0, len(data), step):
            f.write(data[i : i + step])
            f.flush()
            time.sleep(duration_s / pieces)
