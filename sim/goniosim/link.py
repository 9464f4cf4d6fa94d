"""The serial cable: two pseudo-terminal pairs joined by a relay thread.

The controller opens the slave of the rig pair with pyserial; the daemon opens the slave of the
daemon pair (through a stable symlink, the "port") with tokio-serial. The relay copies bytes
between the two masters and is where link faults happen: corrupted bytes, dropped lines, pacing
at a baud rate, and unplugging (the daemon's pair is closed and re-created under the same name).
"""

from __future__ import annotations

import collections
import os
import pty
import random
import select
import threading
import time
import tty


class Cable:
    def __init__(self, port: str, baud: int = 0, seed: int = 0) -> None:
        self.port = port
        self.baud = baud
        self.rng = random.Random(seed)
        self.corrupt_rate = 0.0  # probability per byte, controller -> daemon
        self.drop_rate = 0.0  # probability per line, controller -> daemon
        self.stats = collections.Counter()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._rig_master, self._rig_slave = pty.openpty()
        tty.setraw(self._rig_slave)
        self.rig_path = os.ttyname(self._rig_slave)
        self._d_master: int | None = None
        self._d_slave: int | None = None
        self._replug_at: float | None = None
        self._to_daemon = bytearray()
        self._to_rig = bytearray()
        self._line = bytearray()  # controller -> daemon line being assembled (for drops)
        self._budget_t = time.monotonic()
        self._plug()
        self._thread = threading.Thread(target=self._run, name="cable", daemon=True)
        self._thread.start()

    # -- the daemon-side pair ---------------------------------------------------------------
    def _plug(self) -> None:
        m, s = pty.openpty()
        tty.setraw(s)
        self._d_master, self._d_slave = m, s
        os.set_blocking(m, False)
        tmp = f"{self.port}.tmp{os.getpid()}"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(os.ttyname(s), tmp)
        os.replace(tmp, self.port)
        self.stats["plugs"] += 1

    def _unplug_now(self) -> None:
        for fd in (self._d_master, self._d_slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._d_master = self._d_slave = None
        self._to_daemon.clear()
        self._line.clear()
        try:
            os.unlink(self.port)
        except FileNotFoundError:
            pass
        self.stats["unplugs"] += 1

    def unplug(self, duration_s: float) -> None:
        """Pull the cable on the daemon's side; plug a new one in after `duration_s`."""
        with self._lock:
            self._unplug_now()
            self._replug_at = time.monotonic() + duration_s

    @property
    def plugged(self) -> bool:
        return self._d_master is not None

    # -- relay ---------------------------------------------------------------------------------
    def _filter_to_daemon(self, data: bytes) -> bytes:
        out = bytearray()
        for b in data:
            if self.corrupt_rate and self.rng.random() < self.corrupt_rate and b != 0x0A:
                b ^= 1 << self.rng.randrange(7)
                b = b or 0x21
                self.stats["corrupted_bytes"] += 1
            self._line.append(b)
            if b == 0x0A:
                if self.drop_rate and self.rng.random() < self.drop_rate:
                    self.stats["dropped_lines"] += 1
                else:
                    out += self._line
                self._line.clear()
        return bytes(out)

    def _paced(self, n: int) -> int:
        """How many of n bytes may go now at the configured baud rate."""
        if not self.baud:
            return n
        now = time.monotonic()
        rate = self.baud / 10.0
        self._budget_t = max(self._budget_t, now - 0.05)
        allowed = int((now - self._budget_t) * rate)
        k = min(n, allowed)
        self._budget_t += k / rate
        return k

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                if self._replug_at is not None and time.monotonic() >= self._replug_at:
                    self._replug_at = None
                    self._plug()
                fds = [self._rig_master] + ([self._d_master] if self._d_master is not None else [])
            try:
                r, _, _ = select.select(fds, [], [], 0.01)
            except (OSError, ValueError):
                continue
            with self._lock:
                if self._rig_master in r:
                    try:
                        data = os.read(self._rig_master, 65536)
                    except OSError:
                        data = b""
                    if self._d_master is not None:
                        self._to_daemon += self._filter_to_daemon(data)
                        if len(self._to_daemon) > 1 << 20:  # device buffer overflow
                            self.stats["overflow_bytes"] += len(self._to_daemon) - (1 << 20)
                            del self._to_daemon[: len(self._to_daemon) - (1 << 20)]
                if self._d_master is not None and self._d_master in r:
                    try:
                        data = os.read(self._d_master, 65536)
                        self._to_rig += data
                    except OSError:
                        pass
                if self._to_daemon and self._d_master is not None:
                    k = self._paced(len(self._to_daemon))
                    if k:
                        try:
                            w = os.write(self._d_master, self._to_daemon[:k])
                            del self._to_daemon[:w]
                            self.stats["bytes_to_daemon"] += w
                        except BlockingIOError:
                            pass
                        except OSError:
                            pass
                if self._to_rig:
                    try:
                        w = os.write(self._rig_master, self._to_rig)
                        del self._to_rig[:w]
                    except OSError:
                        pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        with self._lock:
            self._unplug_now()
            for fd in (self._rig_master, self._rig_slave):
                try:
                    os.close(fd)
                except OSError:
                    pass
