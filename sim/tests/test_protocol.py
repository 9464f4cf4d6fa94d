import os
import re

import pytest
from simtest import REPO

from goniosim import protocol as P


def test_crc_check_value():
    assert P.crc16_ccitt_false(b"123456789") == 0x29B1
    assert P.crc16_ccitt_false(b"") == 0xFFFF


def test_frame_parse_round_trip_with_escapes():
    line = P.frame(41, "CAPTURE", {"idx": 7, "file": "a b/c*d=e%f.hdr", "reason": "ünïcode"})
    assert line.endswith(b"\n") and b" b/" not in line
    m = P.parse(line)
    assert (m.seq, m.verb) == (41, "CAPTURE")
    assert m.fields == {"idx": "7", "file": "a b/c*d=e%f.hdr", "reason": "ünïcode"}
    assert P.parse(line.rstrip(b"\n") + b"\r\n").fields == m.fields


@pytest.mark.parametrize(
    "bad",
    [
        b"1 HELLO proto=1*0000\n",  # wrong CRC
        b"1 HELLO proto=1\n",  # no CRC
        b"1 HELLO proto=1*12\n",  # short CRC
        b"x HELLO*" + b"%04X" % P.crc16_ccitt_false(b"x HELLO") + b"\n",  # bad seq
        b"1 HELLO bad*" + b"%04X" % P.crc16_ccitt_false(b"1 HELLO bad") + b"\n",  # field without =
        b"1 HELLO a=1 a=2*" + b"%04X" % P.crc16_ccitt_false(b"1 HELLO a=1 a=2") + b"\n",  # duplicate key
        b"1 HEL\x01LO*0000\n",  # non-printable
        b"1*" + b"%04X" % P.crc16_ccitt_false(b"1") + b"\n",  # no verb
        b"1000000 HELLO*" + b"%04X" % P.crc16_ccitt_false(b"1000000 HELLO") + b"\n",  # seq out of range
        b"1 HELLO f=%4*" + b"%04X" % P.crc16_ccitt_false(b"1 HELLO f=%4") + b"\n",  # truncated escape
    ],
)
def test_rejections(bad):
    with pytest.raises(P.ProtocolError):
        P.parse(bad)


def test_lowercase_crc_is_rejected():
    line = P.frame(1, "HELLO").decode()
    payload, crc = line.strip().split("*")
    if crc.lower() != crc:
        with pytest.raises(P.ProtocolError):
            P.parse(f"{payload}*{crc.lower()}\n".encode())


def test_line_buffer_splits_and_discards_overlong_lines():
    lb = P.LineBuffer()
    good = P.frame(1, "POSE?")
    out = lb.feed(good[:5]) + lb.feed(good[5:] + b"x" * 600 + b"\n" + good)
    assert out == [good, good]
    assert lb.overlong == 1
    with pytest.raises(P.ProtocolError):
        P.frame(1, "X", {"v": "y" * 600})


def test_protocol_doc_examples():
    """Every complete example line in docs/protocol.md carries its correct CRC."""
    text = open(os.path.join(REPO, "docs", "protocol.md"), encoding="utf-8").read()
    checked = bad = 0
    for line in text.splitlines():
        mt = re.match(r"^[<>] (\d+ [A-Z?-]+.*?\*[0-9A-F]{4})\s*(\(.*\))?$", line)
        if not mt:
            continue
        if mt.group(2) and "bad CRC" in mt.group(2):
            with pytest.raises(P.ProtocolError):
                P.parse(mt.group(1).encode() + b"\n")
            bad += 1
            continue
        P.parse(mt.group(1).encode() + b"\n")
        checked += 1
    assert checked >= 20 and bad == 1


def test_encode_value_agrees_with_the_byte_rule_on_every_character_class():
    # the fast path (a value sent as it is) must give what the per-byte rule gives
    safe = set(range(0x21, 0x7F)) - {ord("%"), ord("*"), ord("=")}
    samples = ["", "plain", "a/b_c-d.hdr", "%", "*", "=", " ", "~!", "ü", "\x00\x1f\x7f", "x=1*2%3"]
    samples += [chr(c) for c in range(0x00, 0x180)]
    for text in samples:
        slow = "".join(chr(b) if b in safe else f"%{b:02X}" for b in text.encode("utf-8"))
        assert P.encode_value(text) == slow, repr(text)
        assert P.decode_value(P.encode_value(text)) == text


def test_parse_refuses_any_byte_outside_the_printable_range():
    for b in list(range(0x00, 0x20)) + list(range(0x7F, 0x100)):
        if b in (0x0A, 0x0D):
            continue  # the line ending, stripped
        payload = b"1 HELLO x=" + bytes([b])
        line = payload + b"*%04X\n" % P.crc16_ccitt_false(payload)
        with pytest.raises(P.ProtocolError):
            P.parse(line)
