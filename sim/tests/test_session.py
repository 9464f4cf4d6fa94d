"""A short session end to end over a real pseudo-terminal with a plain pyserial client."""

import json
import os
import time

import pytest
from simtest import Client

from goniosim import protocol as P
from goniosim.render import decode_hdr


def test_short_session_with_a_pyserial_client(make_scenario, run_controller):
    sc = make_scenario(captures=30, speed=7.0 / 0.04)  # 40 ms per capture
    ctl, th = run_controller(sc)
    c = Client(sc.port)
    try:
        c.send("HELLO", {"proto": "1", "client": "pytest"})
        ident = c.wait(lambda m: m.verb == "IDENT")
        assert ident.fields["proto"] == "1" and ident.fields["session"] == "t" and ident.fields["captures"] == "30"
        ref = c.send("SUBSCRIBE")
        c.wait(lambda m: m.verb == "ACK" and m.get("ref") == str(ref))
        c.wait(lambda m: m.verb == "STATUS" and m.get("state") == "running")
        # events after subscribing; then a resync for everything before
        first = c.wait(lambda m: m.verb == "CAPTURE")
        ref = c.send("RESYNC", {"from": 0})
        ack = c.wait(lambda m: m.verb == "ACK" and m.get("ref") == str(ref))
        assert int(ack.get("count")) >= int(first.get("idx"))
        ref = c.send("POSE?")
        pose = c.wait(lambda m: m.verb == "POSE" and m.get("ref") == str(ref))
        assert len(P.parse_pose(pose.get("cmd"))) == 4
        ref = c.send("PROBE", {"entry": 40})
        c.wait(lambda m: m.verb == "ACK" and m.get("ref") == str(ref))
        probe = c.wait(lambda m: m.verb == "CAPTURE" and m.get("probe") == "1")
        assert probe.get("entry") == "40"
        ref = c.send("PAUSE")
        c.wait(lambda m: m.verb == "STATUS" and m.get("state") == "paused")
        c.inbox.clear()
        time.sleep(0.3)
        c.pump()
        assert not [m for m in c.inbox if m.verb == "CAPTURE"], "no capture while paused"
        c.send("RESUME")
        c.wait(lambda m: m.verb == "STATUS" and m.get("state") == "running")
        ref = c.send("FROB")
        assert c.wait(lambda m: m.verb == "NAK" and m.get("ref") == str(ref)).get("reason") == "unknown-verb"
        c.send_raw(b"3 HELLO proto=1*0000\n")
        assert c.wait(lambda m: m.verb == "NAK" and m.get("ref") == "-1").get("reason") == "bad-crc"
        ref = c.send("HELLO", {"proto": "2"})
        nak = c.wait(lambda m: m.verb == "NAK" and m.get("ref") == str(ref))
        assert nak.get("reason") == "unsupported-version" and nak.get("supported") == "1"
        done = c.wait(lambda m: m.verb == "STATUS" and m.get("state") == "done", timeout=20)
        assert done.get("next") == "31"  # 30 scheduled + 1 probe
        # every announced file exists, is complete and decodes
        c.inbox.clear()
        ref = c.send("RESYNC", {"from": 0})
        caps = []
        while True:
            m = c.wait(lambda m: m.verb == "CAPTURE" or (m.verb == "ACK" and m.get("ref") == str(ref)))
            if m.verb == "ACK":
                break
            caps.append(m)
        assert [int(m.get("idx")) for m in caps] == list(range(31))
        for m in caps:
            assert m.get("replay") == "1"
            img = decode_hdr(open(os.path.join(sc.capture_root, m.get("file")), "rb").read())
            assert img.shape == (16, 16, 3) and img.mean() > 0
        assert c.bad == 0
    finally:
        c.close()
    truth = [json.loads(line) for line in open(sc.truth_path())]
    assert len(truth) == 31 and sum(t["probe"] for t in truth) == 1


def test_reboot_restarts_sequence_and_needs_resubscribe(make_scenario, run_controller):
    sc = make_scenario([{"kind": "reboot", "at_capture": 15}], captures=30, speed=7.0 / 0.04)
    ctl, th = run_controller(sc)
    c = Client(sc.port)
    try:
        c.send("HELLO", {"proto": "1"})
        assert c.wait(lambda m: m.verb == "IDENT").get("boot") == "1"
        c.send("SUBSCRIBE")
        ident = c.wait(lambda m: m.verb == "IDENT" and m.get("boot") == "2", timeout=20)
        assert ident.seq == 0
        c.inbox.clear()
        time.sleep(0.3)
        c.pump()
        assert not [m for m in c.inbox if m.verb == "CAPTURE"], "no events before re-subscribing"
        c.send("SUBSCRIBE")
        c.wait(lambda m: m.verb == "ACK")
        ref = c.send("RESYNC", {"from": 0})
        ack = c.wait(lambda m: m.verb == "ACK" and m.get("ref") == str(ref))
        assert int(ack.get("count")) == int(ack.get("next")) >= 15, "the capture log survives the reboot"
    finally:
        c.close()


def test_unplug_and_replug_under_the_same_name(make_scenario, run_controller):
    import serial

    sc = make_scenario([{"kind": "unplug", "at_capture": 10, "duration_s": 0.5}], captures=40, speed=7.0 / 0.03)
    ctl, th = run_controller(sc)
    c = Client(sc.port)
    c.send("HELLO", {"proto": "1"})
    c.wait(lambda m: m.verb == "IDENT")
    c.send("SUBSCRIBE")
    with pytest.raises((serial.SerialException, OSError, TimeoutError)):
        # the port dies under the reader
        c.wait(lambda m: False, timeout=10)
    c.close()
    c = Client(sc.port, timeout=10)  # the same path comes back
    try:
        c.send("HELLO", {"proto": "1"})
        assert c.wait(lambda m: m.verb == "IDENT").get("boot") == "1"
    finally:
        c.close()
    assert ctl.cable.stats["unplugs"] >= 1 and ctl.cable.stats["plugs"] == 2
