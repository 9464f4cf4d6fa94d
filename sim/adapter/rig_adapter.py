#!/usr/bin/env python3
"""rig_adapter: the controller's side of docs/protocol.md, for a rig whose own acquisition
software does not speak it. goniowatch runs unchanged (`goniowatch run --port PORT`); this program
stands in for the controller and learns of each capture from the lab's software, either way:

- Python: `a = RigAdapter(port=..., session=..., captures=...).start()`, then after each capture
  `a.announce_capture(index, relative_path, (q1, q2, q3, w), t=...)` and after the last
  `a.run_done()`. Both only queue: the caller never waits for goniowatch.
- A log line, read from `--follow LOGFILE` as it grows (or from standard input):

      CAPTURE <index> <file> <q1> <q2> <q3> <w> [entry=N] [t=S] [enc=Q1,Q2,Q3,W] [sub=DEG] [exp=TEXT] [exposure=X]
      RUN-DONE

  Text before the keyword (a logger's time stamp) is ignored, and so are lines without one.
  index: 0, 1, 2, ... in the order taken, once the file is completely written. file: relative
  to goniowatch's capture root (%20 for a space, %3D for =; absolute paths are made relative with
  --capture-root). q1 q2 q3 w: commanded arm joints and wagon, degrees, in the convention of
  goniowatch's [rig] config (or one comma list). entry: plan entry (default: the index). t:
  seconds on any steady clock, Unix time too (sent relative to the first capture; default: when
  read). enc: encoder reading (default: the commanded pose). sub: the θi used when the entry was
  taken at a substitute pose. The log is read from its start, so a restarted adapter rebuilds
  its capture log: one log file per session.

It answers HELLO, SUBSCRIBE, RESYNC (replaying its log), POSE? (the last capture's pose),
PAUSE/RESUME/PROBE (NAK refused unless the lab gives a hook) and NAKs any other verb. Framing,
CRC and percent-encoding are goniosim's (sim/goniosim/protocol.py: stdlib only, no side effects).
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import pty
import queue
import re
import select
import signal
import sys
import termios
import threading
import time
import tty

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from goniosim import protocol as P  # noqa: E402  (framing, CRC, percent-encoding)

PROTO = "1"


class RigAdapter:
    """A controller for goniowatch. `port`: a symlink to create for a pty (one PC); `serial`: a
    real serial device to open instead. `hooks`: optional {"PAUSE": f(), "RESUME": f(),
    "PROBE": f(entry)}, each returning True to accept; they run on the adapter's thread, so they
    must return quickly (queue the work)."""

    def __init__(self, port="/tmp/goniowatch-rig", serial=None, baud=115200, session="lab",
                 captures=6561, rig="lab-rig", fw="rig-adapter-1", hooks=None, log=sys.stderr):
        self.port, self.serial, self.baud = port, serial, baud
        self.ident = {"rig": rig, "fw": fw, "proto": PROTO, "session": session, "captures": captures,
                      "boot": int(time.time())}  # higher on every start, as the spec's counter
        self.hooks = hooks or {}
        self.log = log
        self.inbox = queue.SimpleQueue()  # lab -> adapter thread; put() never blocks
        self.captures = {}  # idx -> CAPTURE fields: the controller's log, replayed on RESYNC
        self.t0 = None  # the first capture's time on the lab's clock
        self.state, self.seq, self.subscribed = "running", 0, False
        self.fd, self.slave_name = None, None  # our end: a pty master or the serial device
        self.attached = False  # a daemon has the pty open (always true for a real port)
        self.rx, self.out = P.LineBuffer(), bytearray()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, name="rig-adapter", daemon=True)

    # -- the lab's side: both calls only queue, so the acquisition never waits for goniowatch --
    def announce_capture(self, index, relative_path, pose, t=None, entry=None, enc=None, sub=None,
                         exp="lab", exposure=None):
        """Capture `index` was taken at commanded `pose` (q1, q2, q3, w in degrees) and its file
        is completely written. Raises ValueError at once on a malformed announcement."""
        fields = {"idx": int(index), "entry": int(index if entry is None else entry),
                  "file": str(relative_path), "t": time.time() if t is None else float(t),
                  "cmd": P.fmt_pose(_pose(pose)), "enc": P.fmt_pose(_pose(pose if enc is None else enc)),
                  "exp": exp}
        if fields["idx"] < 0 or fields["entry"] < 0 or not fields["file"] or os.path.isabs(fields["file"]):
            raise ValueError(f"bad capture {index}: negative number, empty or absolute path")
        if not math.isfinite(fields["t"]):
            raise ValueError(f"bad capture {index}: time {t!r} is not a finite number of seconds")
        if sub is not None:
            if not math.isfinite(float(sub)):
                raise ValueError(f"bad capture {index}: sub {sub!r} is not a finite angle")
            fields["sub"] = f"{float(sub):.4f}"
        if exposure is not None:
            if not (math.isfinite(float(exposure)) and float(exposure) > 0):
                raise ValueError(f"bad capture {index}: exposure {exposure!r} is not a positive number")
            fields["exposure"] = float(exposure)
        P.frame(P.SEQ_MOD - 1, "CAPTURE", {**fields, "replay": 1})  # too long for the 512-byte line: fail here
        self.inbox.put(("capture", fields))

    def run_done(self):
        """No further capture will come: goniowatch finishes once it has checked them all."""
        self.inbox.put(("done", None))

    def start(self):
        self.thread.start()
        return self

    def close(self):
        self.stop.set()
        self.thread.join(timeout=2)
        self._close_fd()
        if self.serial is None and os.path.islink(self.port) and os.readlink(self.port) == self.slave_name:
            os.unlink(self.port)  # only our own link: a newer adapter may have taken the name

    # -- the endpoint ----------------------------------------------------------------------------
    def _open(self):
        if self.serial is None:
            # A fresh pty pair behind the stable name. Our copy of the slave is closed, so the
            # master reports a hang-up whenever no daemon has it open: that is how a departed
            # daemon is noticed, and a new pair for the next one carries no stale bytes.
            self.fd, slave = pty.openpty()
            try:
                tty.setraw(slave)
                tmp = f"{self.port}.tmp{os.getpid()}"
                if os.path.lexists(tmp):
                    os.unlink(tmp)
                self.slave_name = os.ttyname(slave)
                os.symlink(self.slave_name, tmp)
                os.replace(tmp, self.port)  # atomic: the name never dangles
            finally:
                os.close(slave)
        else:
            fd = os.open(self.serial, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            tty.setraw(fd)
            a = termios.tcgetattr(fd)
            a[2] |= termios.CLOCAL | termios.CREAD  # 8N1 raw; no modem lines (a 3-wire cable)
            a[4] = a[5] = getattr(termios, f"B{self.baud}")
            termios.tcsetattr(fd, termios.TCSANOW, a)
            self.fd = fd
            self._attach()
        os.set_blocking(self.fd, False)

    def _attach(self):
        self.attached, self.subscribed = True, False
        self.rx, self.out = P.LineBuffer(), bytearray()
        self._send("IDENT", self.ident)  # unsolicited, as after a boot; HELLO gets it again

    def _close_fd(self):
        if self.fd is not None:
            os.close(self.fd)
        self.fd, self.attached, self.subscribed = None, False, False

    def _serve(self):
        while not self.stop.is_set():
            try:
                if self.fd is None:
                    self._open()
                self._take_inbox()
                self._pump()
            except OSError as e:
                self._close_fd()
                if self.serial is not None or e.errno != errno.EIO:  # EIO: the daemon just left the pty
                    self._say(f"{self.serial or self.port}: {e}; retrying")  # unplugged, not there yet
                    self.stop.wait(1.0)

    def _pump(self):
        p = select.poll()
        p.register(self.fd, select.POLLIN | (select.POLLOUT if self.out else 0))
        ev = dict(p.poll(20)).get(self.fd, 0)
        if ev & (select.POLLHUP | select.POLLERR):
            if self.serial is not None:  # a USB-serial adapter unplugged: reopen after a pause
                raise OSError(errno.EIO, "the port hung up")
            if self.attached:  # the daemon closed the pty (exit, crash, reconnect)
                self._close_fd()
            else:
                time.sleep(0.02)  # nobody there yet
            return
        if not self.attached:
            self._attach()
        if ev & select.POLLIN:
            overlong = self.rx.overlong
            for line in self.rx.feed(os.read(self.fd, 65536)):
                self._line(line)
            for _ in range(self.rx.overlong - overlong):  # a framing error like a bad CRC
                self._send("NAK", {"ref": -1, "reason": "bad-crc"})
        if ev & select.POLLOUT:  # what the daemon has room for; the rest on the next round
            del self.out[: os.write(self.fd, self.out)]

    def _send(self, verb, fields, event=False):
        """Queue a line; events (CAPTURE, STATUS) only on a subscribed link. The sequence number
        counts every line sent since the adapter started, across daemon reconnects."""
        if self.attached and (self.subscribed or not event):
            self.out += P.frame(self.seq, verb, fields)
            self.seq = (self.seq + 1) % P.SEQ_MOD

    def _status(self):  # the controller's clock: the latest capture's time
        now = max((float(c["t"]) for c in self.captures.values()), default=0.0)
        self._send("STATUS", {"state": self.state, "t": f"{now:.3f}", "next": self._next()}, event=True)

    def _next(self):
        return max(self.captures, default=-1) + 1

    # -- what the lab reports --------------------------------------------------------------------
    def _take_inbox(self):
        while True:
            try:
                kind, f = self.inbox.get_nowait()
            except queue.Empty:
                return
            if kind == "done":
                if self.state != "done":
                    self.state = "done"
                    self._status()
                continue
            self.t0 = f["t"] if self.t0 is None else self.t0
            f["t"] = f"{max(0.0, f['t'] - self.t0):.3f}"  # controller time: since the session began
            old = self.captures.get(f["idx"])
            if old is None:
                self.captures[f["idx"]] = f
            elif (old["file"], old["entry"]) != (f["file"], f["entry"]):
                # keep the first for RESYNC; goniowatch raises its duplicate-index alarm
                self._say(f"capture {f['idx']} announced again as {f['file']}; keeping {old['file']}")
            else:
                continue  # the same capture again (a log read twice): nothing new
            self._send("CAPTURE", f, event=True)

    # -- what the daemon asks --------------------------------------------------------------------
    def _line(self, raw):
        try:
            m = P.parse(raw)
        except P.ProtocolError:
            self._send("NAK", {"ref": -1, "reason": "bad-crc"})  # the daemon can resend
            return
        ref = m.seq
        if m.verb == "HELLO":
            if PROTO in (m.get("proto") or "").split(","):
                self._send("IDENT", self.ident)
            else:
                self._send("NAK", {"ref": ref, "reason": "unsupported-version", "supported": PROTO})
        elif m.verb == "SUBSCRIBE":
            self.subscribed = True
            self._send("ACK", {"ref": ref})
            self._status()
        elif m.verb == "RESYNC":
            start = m.get("from")
            if start is None or not start.isdigit():
                self._send("NAK", {"ref": ref, "reason": "bad-args"})
                return
            replay = [self.captures[i] for i in sorted(self.captures) if i >= int(start)]
            for f in replay:
                self._send("CAPTURE", {**f, "replay": 1})
            self._send("ACK", {"ref": ref, "count": len(replay), "next": self._next(), "state": self.state})
        elif m.verb == "POSE?":
            last = self.captures.get(self._next() - 1)
            if last is None:
                self._send("NAK", {"ref": ref, "reason": "refused"})
            else:
                self._send("POSE", {"t": last["t"], "cmd": last["cmd"], "enc": last["enc"], "ref": ref})
        elif m.verb in ("PAUSE", "RESUME", "PROBE"):
            self._action(m)
        else:
            self._send("NAK", {"ref": ref, "reason": "unknown-verb"})

    def _action(self, m):
        entry = m.get("entry") or ""
        if m.verb == "PROBE" and not entry.isdigit():
            return self._send("NAK", {"ref": m.seq, "reason": "bad-args"})
        args = [int(entry)] if m.verb == "PROBE" else []
        try:
            ok = m.verb in self.hooks and bool(self.hooks[m.verb](*args))
        except Exception as e:  # a lab hook's bug must not stop the adapter
            self._say(f"{m.verb} hook failed: {e!r}")
            ok = False
        if not ok:
            return self._send("NAK", {"ref": m.seq, "reason": "refused"})
        self._send("ACK", {"ref": m.seq})
        if m.verb != "PROBE" and self.state != "done":
            self.state = "paused" if m.verb == "PAUSE" else "running"
            self._status()

    def _say(self, text):
        if self.log:
            print(f"rig_adapter: {text}", file=self.log, flush=True)


def _pose(p):
    v = [float(x) for x in (p.split(",") if isinstance(p, str) else p)]
    if len(v) != 4:
        raise ValueError(f"a pose is q1, q2, q3, w: got {p!r}")
    if not all(math.isfinite(x) for x in v):
        raise ValueError(f"a pose's angles are finite degrees: got {p!r}")
    return v


KEYWORD = re.compile(r"(?:^|\s)(CAPTURE|RUN-DONE)(?=\s|$)(.*)")
OPTIONAL = {"entry", "t", "enc", "sub", "exp", "exposure"}


def parse_log_line(line, capture_root=None):
    """One log line -> ("capture", kwargs for announce_capture), ("done", None) or None (not
    ours). Raises ValueError on a CAPTURE line that does not follow the format."""
    m = KEYWORD.search(line)
    if not m:
        return None
    if m.group(1) == "RUN-DONE":
        return ("done", None)
    words = m.group(2).split()
    pos = [w for w in words if "=" not in w]
    opts = dict(w.split("=", 1) for w in words if "=" in w)
    angles = pos[2].split(",") if len(pos) == 3 else pos[2:]
    if len(pos) < 3 or len(angles) != 4 or not opts.keys() <= OPTIONAL:
        raise ValueError(f"expected CAPTURE <index> <file> <q1> <q2> <q3> <w> [{'|'.join(sorted(OPTIONAL))}=...]")
    path = P.decode_value(pos[1])
    if os.path.isabs(path) and capture_root:
        path = os.path.relpath(path, capture_root)
    return ("capture", {"index": int(pos[0]), "relative_path": path, "pose": angles, **opts})


def follow(path, adapter, capture_root=None, stop=None):
    """Feed the adapter from a log file as it grows (like `tail -F`: from its start, reopened
    when it is replaced or truncated), or from standard input with "-". Runs until `stop`."""
    stop = stop or threading.Event()
    f, ident, partial = None, None, ""
    while not stop.is_set():
        if path == "-":
            line = sys.stdin.readline()
            if not line:
                return
        else:
            try:
                st = os.stat(path)
                if f is None or (st.st_dev, st.st_ino) != ident or st.st_size < f.tell():
                    if f is not None:
                        f.close()
                    f, ident, partial = open(path, encoding="utf-8", errors="replace"), (st.st_dev, st.st_ino), ""
            except FileNotFoundError:
                stop.wait(0.2)  # the lab software has not created it yet
                continue
            partial += f.readline()
            if not partial.endswith("\n"):  # nothing new, or a line still being written
                stop.wait(0.05)
                continue
            line, partial = partial, ""
        try:
            item = parse_log_line(line, capture_root)
            if item and item[0] == "done":
                adapter.run_done()
            elif item:
                adapter.announce_capture(**item[1])
        except ValueError as e:
            print(f"rig_adapter: skipped {line.strip()!r}: {e}", file=sys.stderr, flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="rig_adapter.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--port", default="/tmp/goniowatch-rig", help="create a pty behind this symlink (default %(default)s)")
    where.add_argument("--serial", metavar="DEVICE", help="use this real serial port instead of a pty")
    ap.add_argument("--baud", type=int, default=115200, help="with --serial (default %(default)s)")
    ap.add_argument("--follow", default="-", metavar="LOGFILE", help="the lab's log file, or - for standard input (default)")
    ap.add_argument("--session", default="lab", help="session (plan) id sent in IDENT (default %(default)s)")
    ap.add_argument("--captures", type=int, default=6561, help="captures the session plans (default %(default)s)")
    ap.add_argument("--rig", default="lab-rig", help="rig id sent in IDENT (default %(default)s)")
    ap.add_argument("--capture-root", metavar="DIR", help="make absolute capture paths in the log relative to DIR")
    a = ap.parse_args(argv)
    adapter = RigAdapter(port=a.port, serial=a.serial, baud=a.baud, session=a.session,
                         captures=a.captures, rig=a.rig).start()
    signal.signal(signal.SIGTERM, _interrupt)
    print(f"rig_adapter: {a.serial or a.port} ready, following {a.follow}", file=sys.stderr, flush=True)
    try:
        follow(a.follow, adapter, a.capture_root)
        while True:  # the log ended (stdin closed): keep answering goniowatch until stopped
            time.sleep(1)
    except KeyboardInterrupt:
        pass
    finally:
        adapter.close()
    return 0


def _interrupt(*_):
    raise KeyboardInterrupt  # SIGTERM ends the adapter like Ctrl-C, also inside a blocking read


if __name__ == "__main__":
    sys.exit(main())
