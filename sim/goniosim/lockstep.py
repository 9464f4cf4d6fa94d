"""The rig in lockstep with `goniowatch lockstep` (the detection lab's fast path): instead of a
serial port, the controller talks to the daemon's engine over its standard input and output.

Every line the controller sends goes to the daemon's stdin; the daemon answers with the lines
its engine sends, then an empty line, and only then does the controller go on. So the rig never
runs ahead of the checks (a probe the daemon asks for is taken right after the capture that made
it due, as on a real rig at 7 s a capture), and a session costs CPU time, not link time. The
serial link's own faults (corrupt bytes, dropped lines, unplugging, a slow link, a reboot's
lost subscription) have nothing to act on here: those scenarios need the pty (`goniosim run`).
"""

from __future__ import annotations

import subprocess


class LockstepError(RuntimeError):
    pass


class DaemonLink:
    """A serial-port stand-in (`write`, `read`, `close`) whose other end is a `goniowatch
    lockstep` process. `write` returns once the daemon has answered; `read` hands over what it
    answered so far; `pending` says whether anything is waiting to be read."""

    def __init__(self, argv: list[str], stderr=None) -> None:
        self.argv = argv
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=stderr)
        self.buf = bytearray()
        self._turn()  # the daemon's first words (HELLO on connecting)

    def _turn(self) -> None:
        out = self.proc.stdout
        while True:
            line = out.readline()
            if not line:
                rc = self.proc.wait()
                raise LockstepError(f"goniowatch lockstep ended mid-session (exit {rc}): {' '.join(self.argv)}")
            if line == b"\n":
                return
            self.buf += line

    @property
    def pending(self) -> bool:
        return bool(self.buf)

    def write(self, data: bytes) -> int:
        try:
            self.proc.stdin.write(data)
            self.proc.stdin.flush()
        except BrokenPipeError as e:
            rc = self.proc.wait()
            raise LockstepError(f"goniowatch lockstep ended mid-session (exit {rc})") from e
        self._turn()
        return len(data)

    def read(self, _n: int = 65536) -> bytes:
        data = bytes(self.buf)
        self.buf.clear()
        return data

    def close(self) -> int:
        """End of the session: the daemon writes its summary and exits; its exit code."""
        if self.proc.stdin and not self.proc.stdin.closed:
            try:
                self.proc.stdin.close()
            except BrokenPipeError:
                pass
        return self.proc.wait()
