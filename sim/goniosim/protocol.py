"""Line framing of docs/protocol.md: `SEQ VERB key=value ...*CRC16` with CRC-16/CCITT-FALSE."""

from __future__ import annotations

import binascii
import re

from dataclasses import dataclass, field

MAX_LINE = 512  # bytes, LF included
SEQ_MOD = 1_000_000


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor (binascii's
    CRC-CCITT started from 0xFFFF; check value 0x29B1 for b"123456789")."""
    return binascii.crc_hqx(data, 0xFFFF)


_SAFE = set(range(0x21, 0x7F)) - {ord("%"), ord("*"), ord("=")}
# A value made only of safe characters is sent as it is: the common case, tested without a loop.
_ALL_SAFE = re.compile(r"[!-$&-)+-<>-~]*")
# Every byte printable (0x20-0x7E): the framing's rule for a whole line.
_PRINTABLE = re.compile(rb"[ -~]*")


def encode_value(text: str) -> str:
    """Percent-encode a value: bytes outside 0x21-0x7E and % * = become %XX."""
    if _ALL_SAFE.fullmatch(text):
        return text
    out = []
    for b in text.encode("utf-8"):
        out.append(chr(b) if b in _SAFE else f"%{b:02X}")
    return "".join(out)


def decode_value(text: str) -> str:
    raw = bytearray()
    i = 0
    while i < len(text):
        c = text[i]
        if c == "%":
            digits = text[i + 1 : i + 3]
            if len(digits) != 2:
                raise ProtocolError(f"truncated escape in {text!r}")
            try:
                raw.append(int(digits, 16))
            except ValueError as e:
                raise ProtocolError(f"bad escape in {text!r}") from e
            i += 3
        else:
            raw.append(ord(c))
            i += 1
    return raw.decode("utf-8", errors="replace")


class ProtocolError(ValueError):
    """A line that does not follow the framing rules."""


@dataclass
class Message:
    seq: int
    verb: str
    fields: dict[str, str] = field(default_factory=dict)

    def get(self, key: str, default: str | None = None) -> str | None:
        return self.fields.get(key, default)


class Raw(str):
    """A field value sent exactly as given, not percent-encoded (to inject malformed fields)."""


def frame(seq: int, verb: str, fields: dict[str, object] | None = None) -> bytes:
    """Build one line (with the LF). Values are str()'d and percent-encoded, except `Raw` ones."""
    parts = [str(seq % SEQ_MOD), verb]
    for k, v in (fields or {}).items():
        parts.append(f"{k}={v if isinstance(v, Raw) else encode_value(str(v))}")
    payload = " ".join(parts)
    line = f"{payload}*{crc16_ccitt_false(payload.encode('ascii')):04X}\n".encode("ascii")
    if len(line) > MAX_LINE:
        raise ProtocolError(f"line of {len(line)} bytes exceeds {MAX_LINE}")
    return line


def parse(line: bytes) -> Message:
    """Parse one line (with or without the LF / CR LF). Raises ProtocolError."""
    if len(line) > MAX_LINE:
        raise ProtocolError("line too long")
    line = line.rstrip(b"\n").rstrip(b"\r")
    if not _PRINTABLE.fullmatch(line):
        raise ProtocolError("non-printable byte")
    text = line.decode("ascii")
    star = text.rfind("*")
    if star < 0 or len(text) - star - 1 != 4:
        raise ProtocolError("missing CRC")
    payload, crc_text = text[:star], text[star + 1 :]
    try:
        crc = int(crc_text, 16)
    except ValueError as e:
        raise ProtocolError("bad CRC digits") from e
    if crc_text.upper() != crc_text or crc != crc16_ccitt_false(payload.encode("ascii")):
        raise ProtocolError("CRC mismatch")
    tokens = payload.split(" ")
    if len(tokens) < 2:
        raise ProtocolError("missing verb")
    try:
        seq = int(tokens[0])
    except ValueError as e:
        raise ProtocolError("bad sequence number") from e
    if not 0 <= seq < SEQ_MOD:
        raise ProtocolError("sequence number out of range")
    verb = tokens[1]
    fields: dict[str, str] = {}
    for tok in tokens[2:]:
        if "=" not in tok:
            raise ProtocolError(f"field without '=': {tok!r}")
        k, v = tok.split("=", 1)
        if not k or k in fields:
            raise ProtocolError(f"empty or duplicate key {k!r}")
        fields[k] = decode_value(v)
    return Message(seq, verb, fields)


def fmt_pose(p) -> str:
    return ",".join(f"{v:.4f}" for v in p)


def parse_pose(text: str) -> list[float]:
    v = [float(x) for x in text.split(",")]
    if len(v) != 4:
        raise ProtocolError(f"pose needs 4 values, got {text!r}")
    return v


class LineBuffer:
    """Split a byte stream into lines; over-long lines are discarded up to the next LF."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.discarding = False
        self.overlong = 0

    def feed(self, data: bytes) -> list[bytes]:
        out = []
        for b in data:
            if self.discarding:
                if b == 0x0A:
                    self.discarding = False
                continue
            self.buf.append(b)
            if b == 0x0A:
                out.append(bytes(self.buf))
                self.buf.clear()
            elif len(self.buf) >= MAX_LINE:
                self.buf.clear()
                self.discarding = True
                self.overlong += 1
        return out
