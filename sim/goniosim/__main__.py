"""Command line: `python -m goniosim run SCENARIO ...`, `python -m goniosim stats TRUTH`."""

from __future__ import annotations

import argparse
import json
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
    st = sub.add_parser("stats", help="the paper's Table 2 from a truth file's noiseless means")
    st.add_argument("truth")
    st.add_argument("--rgb-scale", type=float, default=100.0)
    a = ap.parse_args(argv)

    if a.cmd == "stats":
        from .colour import table2

        with open(a.truth, encoding="utf-8") as f:
            recs = [json.loads(line) for line in f if line.strip()]
        n, m = table2(recs, a.rgb_scale)
        names = ["|dX|", "|dY|", "|dZ|", "dE*ab", "dC*ab", "dH*ab", "dE00"]
        print(json.dumps({"pairs": n, **{k: round(v, 4) for k, v in zip(names, m)}}))
        return 0

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


if __name__ == "__main__":
    sys.exit(main())
