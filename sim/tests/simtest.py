import os
import shutil
import sys
import threading
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
SIM = os.path.dirname(HERE)
REPO = os.path.dirname(SIM)
sys.path.insert(0, SIM)

from goniosim import protocol as P  # noqa: E402
from goniosim import scenario as S  # noqa: E402


def goniowatch_binary():
    """The daemon binary if it has been built (cargo build / cargo test), else None."""
    for p in ("target/debug/goniowatch", "target/release/goniowatch"):
        full = os.path.join(REPO, p)
        if os.path.exists(full):
            return full
    return shutil.which("goniowatch")


@pytest.fixture
def make_scenario(tmp_path):
    def make(faults=(), **session):
        base = {
            "id": "t",
            "capture_root": str(tmp_path / "cap"),
            "port": str(tmp_path / "port"),
            "image_size": [16, 16],
            "speed": 0.0,
            "seed": 3,
        }
        base.update(session)
        return S.from_dict({"session": base, "faults": list(faults)}, base_dir=str(tmp_path))

    return make


class Client:
    """A plain pyserial client of the simulated rig, speaking docs/protocol.md."""

    def __init__(self, port, timeout=5.0):
        import serial

        deadline = time.monotonic() + timeout
        while not os.path.exists(port):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{port} never appeared")
            time.sleep(0.01)
        self.ser = serial.Serial(port, 115200, timeout=0.05)
        self.buf = P.LineBuffer()
        self.seq = 0
        self.inbox = []
        self.bad = 0

    def send(self, verb, fields=None):
        self.ser.write(P.frame(self.seq, verb, fields))
        self.seq += 1
        return self.seq - 1

    def send_raw(self, data):
        self.ser.write(data)

    def pump(self):
        data = self.ser.read(65536)
        for line in self.buf.feed(data):
            try:
                self.inbox.append(P.parse(line))
            except P.ProtocolError:
                self.bad += 1

    def wait(self, pred, timeout=10.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for i, m in enumerate(self.inbox):
                if pred(m):
                    return self.inbox.pop(i)
            self.pump()
        raise TimeoutError("no matching message; inbox: " + ", ".join(f"{m.seq} {m.verb}" for m in self.inbox[-10:]))

    def close(self):
        self.ser.close()


@pytest.fixture
def run_controller():
    started = []

    def start(sc, linger_s=30.0):
        from goniosim.controller import Controller

        ctl = Controller(sc, log=None, linger_s=linger_s)
        th = threading.Thread(target=ctl.run, daemon=True)
        th.start()
        started.append((ctl, th))
        return ctl, th

    yield start
    for ctl, th in started:
        ctl.stop.set()
        th.join(timeout=60)
        ctl.close()
