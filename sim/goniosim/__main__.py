"""Command line:

- `python -m goniosim run SCENARIO ...`: run a simulated session;
- `python -m goniosim archive SCENARIO --out DIR --naming bonn|bonn-indexed|sidecar [--name-format F] ...`: write the
  scenario's capture set, faults included, without a serial link, into DIR/<session id>/ with
  Bonn-style names (`tl015_pl060_tv030_pv000.hdr`, optionally after the capture index) or with a
  captures.csv sidecar (file, angles, time) beside `cap_…` names: what `goniowatch check` and the
  watch mode read;
- `python -m goniosim lockstep SCENARIO --session DIR [--config FILE] [--goniowatch BIN] ...`: run
  the scenario with `goniowatch lockstep` as the daemon, in lockstep over its standard input and
  output instead of a pty (goniosim/lockstep.py): the session folder a live run would write, in
  the CPU time of the checks. Exits with the daemon's exit code;
- `python -m goniosim stats TRUTH`: the paper's Table 2 from a truth file;
- `python -m goniosim reference SCENARIO --out FILE [--seed N] [--no-calibration] [--noise-pct X]`:
  write an independent reference BRDF measurement of the scenario's material (spectral, 30 bands,
  Integra-like grid) in goniowatch's reference format (docs/reference-format.md). The seed defaults
  to the scenario's `session.seed`; exit code 2 on a bad scenario or argument.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys

from . import scenario as S


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="goniosim", description="Simulated UBO-type gonioreflectometer")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run a session from a scenario file")
    r.add_argument("scenario")
    r.add_argument("--port", help="stable path of the daemon's serial port (a symlink)")
    r.add_argument("--capture-root", help="directory the captures are written under")
    r.add_argument("--truth", help="ground-truth JSON lines file")
    r.add_argument("--captures", type=int, help="stop after this many captures")
    r.add_argument("--speed", type=float, help="0 = as fast as possible, 1 = real time (7 s per capture), k = k times")
    r.add_argument("--seed", type=int)
    r.add_argument("--linger", type=float, default=5.0, help="seconds to keep answering after the last capture")
    ar = sub.add_parser("archive", help="write a scenario's capture set without a serial link (Bonn-style names or a sidecar)")
    ar.add_argument("scenario")
    ar.add_argument("--out", required=True, help="capture root; the set goes to OUT/<session id>/")
    ar.add_argument("--naming", choices=["bonn", "bonn-indexed", "sidecar"], default="bonn")
    ar.add_argument("--name-format", help="the rig's own file names instead: a Python format string over idx, entry, tl, pl, tv, pv (nominal angles, degrees) and ext, e.g. '{idx:05d}_L{tl:02.0f}-{pl:03.0f}_C{tv:02.0f}-{pv:03.0f}.{ext}'")
    ar.add_argument("--ldr", choices=["png8", "png16"], help="write sRGB PNG captures (auto-exposed per capture, recorded in the sidecar, with --naming sidecar)")
    ar.add_argument("--truth", help="ground-truth JSON lines file")
    ar.add_argument("--captures", type=int, help="stop after this many captures")
    ar.add_argument("--speed", type=float, default=0.0, help="0 = as fast as possible (default), k = k times real time")
    ar.add_argument("--seed", type=int)
    ls = sub.add_parser("lockstep", help="run a session in lockstep with `goniowatch lockstep` (no pty, no wall-clock waits)")
    ls.add_argument("scenario")
    ls.add_argument("--session", required=True, help="a new goniowatch session folder")
    ls.add_argument("--config", help="the daemon's config (default: the scenario's rig_config)")
    ls.add_argument("--goniowatch", default=os.environ.get("GONIOWATCH_BIN", "goniowatch"), help="the goniowatch binary (default: $GONIOWATCH_BIN, else goniowatch on PATH)")
    ls.add_argument("--capture-root", help="directory the captures are written under")
    ls.add_argument("--truth", help="ground-truth JSON lines file")
    ls.add_argument("--captures", type=int, help="stop after this many captures")
    ls.add_argument("--seed", type=int)
    st = sub.add_parser("stats", help="the paper's Table 2 from a truth file's noiseless means")
    st.add_argument("truth")
    st.add_argument("--rgb-scale", type=float, default=100.0)
    rf = sub.add_parser(
        "reference",
        help="write an independent reference BRDF measurement of the scenario's material (docs/reference-format.md)",
    )
    rf.add_argument("scenario")
    rf.add_argument("--out", required=True, help="the reference file to write")
    rf.add_argument("--seed", type=int, help="noise seed (default: the scenario's session.seed)")
    rf.add_argument("--no-calibration", action="store_true", help="a calibrated instrument (no scale, no spectral tilt)")
    rf.add_argument("--noise-pct", type=float, default=0.5, help="multiplicative Gaussian noise per value, in %% (default 0.5)")
    a = ap.parse_args(argv)

    if a.cmd == "reference":
        return _reference(a)

    if a.cmd == "stats":
        from .colour import table2

        with open(a.truth, encoding="utf-8") as f:
            recs = [json.loads(line) for line in f if line.strip()]
        n, m = table2(recs, a.rgb_scale)
        names = ["|dX|", "|dY|", "|dZ|", "dE*ab", "dC*ab", "dH*ab", "dE00"]
        print(json.dumps({"pairs": n, **{k: round(v, 4) for k, v in zip(names, m)}}))
        return 0

    if a.cmd == "archive":
        return _archive(a)

    if a.cmd == "lockstep":
        return _lockstep(a)

    overrides = {}
    for key, val in (
        ("port", a.port),
        ("capture_root", a.capture_root),
        ("truth", a.truth),
        ("captures", a.captures),
        ("speed", a.speed),
        ("seed", a.seed),
    ):
        if val is not None:
            overrides[key] = val
    try:
        sc = S.load(a.scenario, overrides)
    except (S.ScenarioError, OSError, ValueError) as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 2
    from .controller import Controller

    ctl = Controller(sc, linger_s=a.linger)
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    print(f"goniosim: port {sc.port} -> {ctl.cable.rig_path} (rig side), captures under {sc.capture_root}", file=sys.stderr, flush=True)
    try:
        ctl.run()
    except KeyboardInterrupt:
        pass
    finally:
        ctl.close()
    return 0


def _archive(a) -> int:
    # --out is taken from the working folder (paths inside a scenario are from its own folder)
    overrides = {"capture_root": os.path.abspath(a.out), "speed": a.speed}
    for key, val in (("truth", a.truth), ("captures", a.captures), ("seed", a.seed)):
        if val is not None:
            overrides[key] = val
    try:
        sc = S.load(a.scenario, overrides)
    except (S.ScenarioError, OSError, ValueError) as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 2
    link_faults = sorted({f.kind for f in sc.faults} & LINK_FAULTS)
    if link_faults:
        print(f"goniosim: {', '.join(link_faults)}: a serial-link fault has no effect on a capture set without a link", file=sys.stderr)
    from .controller import Controller

    if a.name_format is not None:
        try:
            a.name_format.format(idx=0, entry=0, tl=0.0, pl=0.0, tv=0.0, pv=0.0, ext="hdr")
        except (KeyError, IndexError, ValueError) as e:
            print(f"goniosim: --name-format {a.name_format!r}: {e!r} (fields: idx, entry, tl, pl, tv, pv, ext)", file=sys.stderr)
            return 2
    ctl = Controller(sc, naming=a.naming, ldr=a.ldr, name_format=a.name_format)
    names = f"names {a.name_format!r}" if a.name_format else f"{a.naming} names"
    print(f"goniosim: writing {sc.capture_count} captures to {sc.capture_root}/{sc.session_id}/ ({names})", file=sys.stderr, flush=True)
    try:
        ctl.run()
    except KeyboardInterrupt:
        pass
    finally:
        ctl.close()
    return 0


def _lockstep(a) -> int:
    overrides = {"speed": 0.0}
    for key, val in (("capture_root", a.capture_root and os.path.abspath(a.capture_root)), ("truth", a.truth), ("captures", a.captures), ("seed", a.seed)):
        if val is not None:
            overrides[key] = val
    try:
        sc = S.load(a.scenario, overrides)
    except (S.ScenarioError, OSError, ValueError) as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 2
    config = a.config or sc.rig_config
    if not config:
        print("goniosim: lockstep needs the daemon's config: give --config or set rig_config in the scenario", file=sys.stderr)
        return 2
    link_faults = sorted({f.kind for f in sc.faults} & LINK_FAULTS - {"duplicate-index", "malformed-announcement", "encoder-mismatch"})
    if link_faults:
        print(f"goniosim: {', '.join(link_faults)}: a serial-link fault has no effect in lockstep (use `goniosim run`)", file=sys.stderr)
    from .controller import Controller
    from .lockstep import DaemonLink, LockstepError

    argv = [a.goniowatch, "lockstep", "--config", os.path.abspath(config), "--session", os.path.abspath(a.session),
            "--capture-root", os.path.abspath(sc.capture_root)]
    try:
        link = DaemonLink(argv)
    except OSError as e:
        print(f"goniosim: cannot start {a.goniowatch}: {e}", file=sys.stderr)
        return 2
    ctl = None
    try:
        ctl = Controller(sc, link=link, log=None)
        ctl.run()
    except LockstepError as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 1
    finally:
        if ctl is not None:
            ctl.close()
        rc = link.close()
    return rc


# Faults of the serial link (and of the announcement on it), which a set without a link cannot show.
LINK_FAULTS = {"reboot", "unplug", "corrupt-bytes", "drop-lines", "slow-link", "malformed-announcement", "duplicate-index", "encoder-mismatch"}


def _reference(a) -> int:
    from .material import PRESETS
    from .reference import write_reference

    try:
        sc = S.load(a.scenario, {"seed": a.seed} if a.seed is not None else None)
    except (S.ScenarioError, OSError, ValueError) as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 2
    try:
        n = write_reference(PRESETS[sc.material], a.out, sc.seed, calibration=not a.no_calibration, noise_pct=a.noise_pct)
    except (OSError, ValueError) as e:
        print(f"goniosim: {e}", file=sys.stderr)
        return 2
    print(f"goniosim: reference of {sc.material!r} ({n} directions, seed {sc.seed}) -> {a.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
