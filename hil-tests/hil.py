"""Hardware-in-the-loop tests: the goniowatch binary against the simulated rig over a real
pseudo-terminal (or against a real rig: set GONIOWATCH_HIL_PORT and GONIOWATCH_HIL_CAPTURE_ROOT;
then the tests that inject faults are skipped)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "sim"))

REAL_PORT = os.environ.get("GONIOWATCH_HIL_PORT")
REAL_ROOT = os.environ.get("GONIOWATCH_HIL_CAPTURE_ROOT")
RESULT_FILES = ["captures.jsonl", "pairs.jsonl", "isotropy.jsonl", "sweeps.jsonl", "alarms.jsonl", "manifest.jsonl", "summary.json"]


def binary():
    """GONIOWATCH_BIN, else the most recently built of target/{debug,release}/goniowatch."""
    if os.environ.get("GONIOWATCH_BIN"):
        return os.environ["GONIOWATCH_BIN"]
    built = [p for p in (os.path.join(REPO, "target", k, "goniowatch") for k in ("debug", "release")) if os.path.exists(p)]
    if not built:
        pytest.skip("goniowatch binary not built (cargo build)")
    return max(built, key=os.path.getmtime)


def needs_simulator():
    if REAL_PORT:
        pytest.skip("fault injection needs the simulated rig (GONIOWATCH_HIL_PORT points at a real one)")


def read_jsonl(path):
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def write_scenario(tmp, name, faults, capture_root, **session):
    """A simulator scenario file (16 × 16 images, full speed, seed 7, walkway, realistic unless
    given); returns its path and the session id."""
    preset = session.pop("preset", "walkway")
    realism = session.pop("realism", "realistic")
    sc = {"id": name, "capture_root": capture_root, "image_size": [16, 16], "speed": 0, "seed": 7}
    sc.update(session)
    lines = [f'rig_config = "{os.path.join(REPO, "config", "sim.toml")}"', "[session]"]
    for k, v in sc.items():
        lines.append(f"{k} = {json.dumps(v)}")
    lines += ["[material]", f'preset = "{preset}"', f'realism = "{realism}"']
    for f in faults:
        lines.append("[[faults]]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in f.items()]
    path = tmp / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path, sc["id"]


def write_archive(tmp, name, faults=(), naming="bonn", captures=None, speed=0.0, ldr=None, name_format=None, **session):
    """The capture set of a scenario, written by `goniosim archive` into tmp/<name>-cap/<name>/
    (run to completion unless `speed` > 0, then returned running); returns (folder, process).
    `name_format` names the files as a rig of its own would (`goniosim archive --name-format`)."""
    root = str(tmp / f"{name}-cap")
    scenario, sid = write_scenario(tmp, name, faults, root, **session)
    cmd = [sys.executable, "-m", "goniosim", "archive", str(scenario), "--out", root, "--naming", naming, "--speed", str(speed)]
    if captures is not None:
        cmd += ["--captures", str(captures)]
    if ldr is not None:
        cmd += ["--ldr", ldr]
    if name_format is not None:
        cmd += ["--name-format", name_format]
    p = subprocess.Popen(cmd, cwd=os.path.join(REPO, "sim"), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if speed == 0:
        out, _ = p.communicate(timeout=600)
        assert p.returncode == 0, out
    return tmp / f"{name}-cap" / sid, p


def run_check(folder, session=None, config=None, *extra, timeout=300):
    """`goniowatch check FOLDER` with config/sim.toml unless given; returns (code, out, err)."""
    cmd = [binary(), "check", str(folder), "--quiet", "--config", str(config or os.path.join(REPO, "config", "sim.toml"))]
    if session is not None:
        cmd += ["--session", str(session)]
    r = subprocess.run(cmd + list(extra), capture_output=True, text=True, timeout=timeout)
    return r.returncode, r.stdout, r.stderr


class Rig:
    """A simulated rig session (goniosim in a subprocess), or a real rig's port."""

    def __init__(self, tmp, name, faults=(), linger=60.0, **session):
        self.tmp = tmp
        self.name = name
        self.port = REAL_PORT or str(tmp / f"{name}.port")
        self.capture_root = REAL_ROOT or str(tmp / f"{name}-cap")
        self.proc = None
        if REAL_PORT:
            return
        self.scenario, self.session_id = write_scenario(tmp, name, faults, self.capture_root, port=self.port, **session)
        self.log = open(tmp / f"{name}.sim.log", "w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "goniosim", "run", str(self.scenario), "--linger", str(linger)],
            cwd=os.path.join(REPO, "sim"),
            stdout=self.log,
            stderr=subprocess.STDOUT,
        )
        deadline = time.monotonic() + 20
        while not os.path.exists(self.port):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"simulator did not start: {(tmp / f'{name}.sim.log').read_text()}")
            time.sleep(0.02)

    def truth(self):
        return {t["idx"]: t for t in read_jsonl(os.path.join(self.capture_root, f"{self.session_id}.truth.jsonl"))}

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc:
            self.log.close()


def daemon_config(tmp, name, **overrides):
    """config/sim.toml with some `key = value` lines replaced (keys are unique in that file)."""
    import re

    text = open(os.path.join(REPO, "config", "sim.toml"), encoding="utf-8").read()
    for key, value in overrides.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {json.dumps(value)}", text, count=1)
        assert n == 1, f"no key {key} in config/sim.toml"
    path = tmp / f"{name}.config.toml"
    path.write_text(text)
    return path


def start_daemon(rig, session, config, *extra):
    return subprocess.Popen(
        [binary(), "run", "--config", str(config), "--session", str(session), "--port", rig.port, "--capture-root", rig.capture_root, "--quiet", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def run_daemon(rig, session, config, timeout=300, *extra):
    p = start_daemon(rig, session, config, *extra)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        raise AssertionError(f"daemon did not finish in {timeout} s\nstdout:\n{out}\nstderr:\n{err[-4000:]}")
    return p.returncode, out, err


def assert_replay_identical(session, tmp):
    """Replay the recorded session; every result file must be byte-identical."""
    out = tmp / (os.path.basename(str(session)) + "-replay")
    r = subprocess.run([binary(), "replay", str(session), "--out", str(out), "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    for name in RESULT_FILES:
        a = open(os.path.join(session, name), "rb").read()
        b = open(os.path.join(out, name), "rb").read()
        assert a == b, f"replay differs in {name}"
    return r.stdout


@pytest.fixture
def hil(tmp_path):
    rigs = []

    def make(name, faults=(), **session):
        r = Rig(tmp_path, name, faults, **session)
        rigs.append(r)
        return r

    yield make
    for r in rigs:
        r.stop()
