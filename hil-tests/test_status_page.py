"""The live status page of `run --http` in a real headless browser (Debian's chromium driven by
Playwright): the page loads, its progress advances, an injected fault shows up as an alarm, it
comes back after the browser is closed and reopened; each alarm's code links to its entry in the
alarm catalogue at /alarms; /status.json, /metrics and /alarms answer; a non-loopback address is
refused. A screenshot is left in the test's temporary folder (or in
$GONIOWATCH_SCREENSHOT_DIR)."""

import json
import os
import re
import signal
import subprocess
import threading
import time
import urllib.error
import urllib.request

import pytest

from hil import binary, daemon_config, needs_simulator, start_daemon

CHROMIUM = os.environ.get("GONIOWATCH_CHROMIUM", "/usr/bin/chromium")
ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def browser_or_skip():
    if not os.path.exists(CHROMIUM):
        if os.environ.get("GONIOWATCH_REQUIRE_BROWSER"):
            pytest.fail(f"{CHROMIUM} is missing (CI installs Debian's chromium)")
        pytest.skip(f"{CHROMIUM} is not installed")
    try:
        from playwright.sync_api import sync_playwright  # noqa: F401
    except ImportError:
        if os.environ.get("GONIOWATCH_REQUIRE_BROWSER"):
            raise
        pytest.skip("playwright is not installed (pip install -r hil-tests/requirements.txt)")


def status_url(proc, timeout=20):
    """Read the daemon's stderr until it names the status page; keep draining it after."""
    found = {}
    lines = []

    def drain():
        for line in proc.stderr:
            lines.append(line)
            m = re.search(r"status page on (http://\S+)", line)
            if m and "url" not in found:
                found["url"] = m.group(1)

    t = threading.Thread(target=drain, daemon=True)
    t.start()
    deadline = time.monotonic() + timeout
    while "url" not in found:
        if time.monotonic() > deadline or proc.poll() is not None:
            raise AssertionError("no status page address: " + "".join(lines)[-2000:])
        time.sleep(0.05)
    return found["url"], lines


def test_status_page_in_a_headless_browser(hil, tmp_path):
    needs_simulator()
    browser_or_skip()
    from playwright.sync_api import sync_playwright

    # a dark frame (a capture-quality alarm) and a short encoder mismatch (a positioning alarm,
    # ticked on the time plots)
    faults = [
        {"kind": "dark-frame", "at_capture": 400},
        {"kind": "encoder-mismatch", "at_capture": 500, "until_capture": 505, "joint": 2, "offset_deg": 0.3},
    ]
    rig = hil("page", faults, captures=1500, speed=7.0 / 0.012)
    session = tmp_path / "page-session"
    # drift probes on, so that the drift chart has an estimate to draw
    # --keep-running: the page, the event streams and /metrics are read after the run may have
    # ended (how long the browser takes moves with machine load); the daemon is stopped at the end
    daemon = start_daemon(rig, session, daemon_config(tmp_path, "page", every=25), "--http", "127.0.0.1:0", "--keep-running")
    try:
        url, _ = status_url(daemon)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1280, "height": 1100})
            page.goto(url)
            page.wait_for_function("document.getElementById('conn').textContent === 'live'", timeout=20000)
            page.wait_for_function("Number(document.getElementById('done').textContent) > 0", timeout=20000)
            first = int(page.text_content("#done"))
            page.wait_for_function(f"Number(document.getElementById('done').textContent) >= {min(first + 50, 1500)}", timeout=30000)
            # the coverage map and the residual plot are drawn
            assert page.locator("#coverage circle").count() >= 81
            page.wait_for_function("document.querySelectorAll('#resid circle').length > 0", timeout=30000)
            page.wait_for_function("document.querySelectorAll('#drift polygon').length === 1", timeout=60000)
            assert "%/h" in page.text_content("#driftnow")
            # the lamp colour estimate and its plot (isotropy classes)
            page.wait_for_function("document.querySelectorAll('#colourplot polygon').length === 1", timeout=60000)
            assert "K/h" in page.text_content("#colournow")
            # the lamp's stability and joint 3 are said, watched or not (an isotropic sample)
            assert page.text_content("#scatternow") != "—"
            assert "not watched" in page.text_content("#sentinelnow")
            # the light sweeps: levels against the layer's prediction and joint offsets over time,
            # the encoder episode as a tick on the same time axis
            page.wait_for_function("document.querySelectorAll('#sweeplevel circle').length >= 5", timeout=60000)
            page.wait_for_function("document.querySelectorAll('#joints circle').length > 0", timeout=60000)
            assert "light directions compared" in page.text_content("#sweepnow")
            ticked = "(id) => [...document.querySelectorAll(`#${id} line.tick title`)].some((t) => t.textContent.startsWith('encoder-mismatch at'))"
            page.wait_for_function(f"({ticked})('sweeplevel') && ({ticked})('drift')", timeout=60000)
            # the injected dark frame appears as an alarm with its message
            page.wait_for_selector('#alarms li[data-code="dark-capture"]', timeout=60000)
            text = page.text_content('#alarms li[data-code="dark-capture"]')
            assert "capture 400" in text and "dark" in text, text
            # its code links to its catalogue entry, opened beside the live page
            link = page.locator('#alarms li[data-code="dark-capture"] a')
            assert page.evaluate("(a) => { const u = new URL(a.href); return u.pathname + u.hash; }", link.element_handle()) == "/alarms#alarm-dark-capture"
            with page.expect_popup() as opened:
                link.click()
            entry_page = opened.value
            entry_page.wait_for_load_state()
            assert entry_page.evaluate("document.querySelector(':target') && document.querySelector(':target').id") == "alarm-dark-capture"
            entry = entry_page.text_content("#alarm-dark-capture")
            assert "what to do" in entry and "capture-quality" in entry, entry
            entry_page.close()
            shots = os.environ.get("GONIOWATCH_SCREENSHOT_DIR") or str(tmp_path)
            page.screenshot(path=os.path.join(shots, "status-page.png"), full_page=True)
            browser.close()
            # the browser closed and opened again: the page picks up where the run is
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page()
            page.goto(url)
            page.wait_for_function(f"Number(document.getElementById('done').textContent) >= {min(first + 50, 1500)}", timeout=20000)
            page.wait_for_selector('#alarms li[data-code="dark-capture"]', timeout=20000)
            browser.close()
        # clients that open the event stream and never read it must not hold the run up
        import socket
        from urllib.parse import urlparse

        host, port = urlparse(url).hostname, urlparse(url).port
        stuck = []
        for _ in range(6):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1024)
            s.connect((host, port))
            s.sendall(b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
            stuck.append(s)
        status = json.load(urllib.request.urlopen(url + "status.json", timeout=10))
        assert status["summary"]["checked"]["captures"] > 0 and len(status["directions"]) == 81
        assert any(a["code"] == "dark-capture" for a in status["alarms"])
        # a page on another site cannot read the status through a name that resolves to 127.0.0.1
        try:
            urllib.request.urlopen(urllib.request.Request(url + "status.json", headers={"Host": "evil.example"}), timeout=10)
            raise AssertionError("a foreign Host header was served")
        except urllib.error.HTTPError as e:
            assert e.code == 403
        # the alarm catalogue: an entry for every code `goniowatch alarms --json` lists, each once
        listed = subprocess.run([binary(), "alarms", "--json"], capture_output=True, text=True, timeout=30, check=True).stdout
        codes = [json.loads(line)["code"] for line in listed.splitlines() if line.strip()]
        answer = urllib.request.urlopen(url + "alarms", timeout=10)
        assert answer.status == 200 and answer.headers.get_content_type() == "text/html"
        catalogue = answer.read().decode()
        assert sorted(re.findall(r' id="(alarm-[^"]+)"', catalogue)) == sorted(f"alarm-{c}" for c in codes) and len(codes) > 40
        try:
            urllib.request.urlopen(urllib.request.Request(url + "alarms", headers={"Host": "evil.example"}), timeout=10)
            raise AssertionError("the alarm catalogue was served to a foreign Host header")
        except urllib.error.HTTPError as e:
            assert e.code == 403
        metrics = urllib.request.urlopen(url + "metrics", timeout=10).read().decode()
        assert re.search(r"^goniowatch_captures_checked \d+", metrics, re.M), metrics[:500]
        assert "# TYPE goniowatch_alarms_total gauge" in metrics
        assert re.search(r"^goniowatch_colour_drift_k_per_h ", metrics, re.M), metrics[:2000]
        # the stuck clients did not hold the run up: it is checked to the end
        deadline = time.monotonic() + 120
        while not json.load(urllib.request.urlopen(url + "status.json", timeout=10))["summary"]["finished"]:
            assert time.monotonic() < deadline, "the run did not finish"
            time.sleep(0.2)
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(timeout=60)
        assert daemon.returncode == 128 + signal.SIGTERM
        assert json.load(open(session / "summary.json"))["finished"]
        for s in stuck:
            s.close()
    finally:
        if daemon.poll() is None:
            daemon.kill()
            daemon.wait()


def test_a_non_loopback_status_address_is_refused(hil, tmp_path):
    needs_simulator()
    rig = hil("remote", captures=10, speed=0)
    r = subprocess.run(
        [binary(), "run", "--config", str(daemon_config(tmp_path, "remote")), "--session", str(tmp_path / "remote-session"),
         "--port", rig.port, "--capture-root", rig.capture_root, "--quiet", "--http", "0.0.0.0:0"],
        capture_output=True, text=True, timeout=60,
    )
    assert r.returncode == 2 and "http.allow_remote" in r.stderr, r.stderr
    # refused before anything was created
    assert not (tmp_path / "remote-session").exists()
