"""The belt's serial frames (``PROTOCOL.md``): encoder, decoders and the incremental parser.

This mirrors ``firmware/frame.c`` line for line, so the driver, the mock firmware and the
real firmware agree on every byte; ``vectors.json`` pins both sides to the same bytes.
Standard library only.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field
from enum import IntEnum

START = 0xA5
VERSION = 0x01
HEADER = 6  # start, version, type, len, seq (u16 LE)
MAX_PAYLOAD = 24
CRC_LEN = 2
MAX_FRAME = HEADER + MAX_PAYLOAD + CRC_LEN

TTL_MIN_MS = 50
TTL_MAX_MS = 5000
PERIOD_MAX_MS = 5000
PERIOD_MIN_MS = 20  # a pulse period, when not 0 (steady)
LINK_WATCHDOG_MS = 500
BYTE_TIMEOUT_MS = 50
HEARTBEAT_MS = 200


class FrameType(IntEnum):
    PATTERN = 0x01
    STOP = 0x02
    PING = 0x03
    ACK = 0x81
    HEARTBEAT = 0x82


class BeltState(IntEnum):
    BOOT = 0  # no valid frame since reset
    ACTIVE = 1  # a pattern is running
    IDLE = 2  # the pattern's own TTL ran out
    WATCHDOG = 3  # no valid frame for 500 ms: every motor off
    STOPPED = 4  # a STOP frame: every motor off until the next pattern


ACK_APPLIED = 0
ACK_REFUSED = 1

PATTERN_LEN = 8
ACK_LEN = 3
HEARTBEAT_LEN = 23
_PATTERN = struct.Struct("<4BHH")
_ACK = struct.Struct("<HB")
_HEARTBEAT = struct.Struct("<BH4B6HI")


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor)."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode(ftype: int, seq: int, payload: bytes = b"") -> bytes:
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = bytes([VERSION, ftype, len(payload)]) + struct.pack("<H", seq & 0xFFFF) + payload
    return bytes([START]) + body + struct.pack(">H", crc16(body))


@dataclass(frozen=True)
class Pattern:
    motors: tuple[int, int, int, int]  # front, right, back, left, 0..255
    period_ms: int = 0  # 0 = steady, else on for the first half of each period
    ttl_ms: int = 1000

    def payload(self) -> bytes:
        return _PATTERN.pack(*self.motors, self.period_ms, self.ttl_ms)

    def valid(self) -> bool:
        return (
            TTL_MIN_MS <= self.ttl_ms <= TTL_MAX_MS
            and (self.period_ms == 0 or PERIOD_MIN_MS <= self.period_ms <= PERIOD_MAX_MS)
            and all(0 <= m <= 255 for m in self.motors)
        )

    @classmethod
    def unpack(cls, payload: bytes) -> Pattern:
        *motors, period, ttl = _PATTERN.unpack(payload)
        return cls(tuple(motors), period, ttl)  # type: ignore[arg-type]


def pattern_frame(seq: int, pattern: Pattern) -> bytes:
    return encode(FrameType.PATTERN, seq, pattern.payload())


def stop_frame(seq: int) -> bytes:
    return encode(FrameType.STOP, seq)


def ping_frame(seq: int) -> bytes:
    return encode(FrameType.PING, seq)


@dataclass(frozen=True)
class Ack:
    seq: int
    result: int  # ACK_APPLIED or ACK_REFUSED

    def payload(self) -> bytes:
        return _ACK.pack(self.seq, self.result)


@dataclass(frozen=True)
class Counters:
    rx_frames: int = 0  # frames with a good CRC
    crc_errors: int = 0
    oversized: int = 0
    truncated: int = 0
    malformed: int = 0  # bad version, unknown type, wrong length, values out of range


@dataclass(frozen=True)
class Heartbeat:
    state: BeltState
    last_seq: int
    outputs: tuple[int, int, int, int]
    counters: Counters
    watchdog_trips: int
    uptime_ms: int

    def payload(self) -> bytes:
        c = self.counters
        return _HEARTBEAT.pack(
            self.state, self.last_seq, *self.outputs, c.rx_frames, c.crc_errors,
            c.oversized, c.truncated, c.malformed, self.watchdog_trips, self.uptime_ms,
        )  # fmt: skip

    @classmethod
    def unpack(cls, payload: bytes) -> Heartbeat:
        v = _HEARTBEAT.unpack(payload)
        return cls(BeltState(v[0]), v[1], tuple(v[2:6]), Counters(*v[6:11]), v[11], v[12])  # type: ignore[arg-type]


@dataclass(frozen=True)
class Frame:
    ftype: int
    seq: int
    payload: bytes

    def decode(self) -> Ack | Heartbeat | Pattern | None:
        """The typed message, or None for a type/length this side does not know."""
        n = len(self.payload)
        if self.ftype == FrameType.ACK and n == ACK_LEN:
            return Ack(*_ACK.unpack(self.payload))
        if self.ftype == FrameType.HEARTBEAT and n == HEARTBEAT_LEN:
            return Heartbeat.unpack(self.payload)
        if self.ftype == FrameType.PATTERN and n == PATTERN_LEN:
            return Pattern.unpack(self.payload)
        return None


@dataclass
class Parser:
    """Incremental parser: bytes in, good frames out, bad ones counted.

    A frame that fails a check loses only its start byte, so a good frame hidden behind
    garbage is still found. ``timeout()`` (the line quiet for ``BYTE_TIMEOUT_MS`` in the
    middle of a frame) counts it as truncated and drops it.
    """

    buf: bytearray = field(default_factory=bytearray)
    rx_frames: int = 0
    crc_errors: int = 0
    oversized: int = 0
    truncated: int = 0
    malformed: int = 0

    def counters(self) -> Counters:
        return Counters(
            self.rx_frames, self.crc_errors, self.oversized, self.truncated, self.malformed
        )

    @property
    def pending(self) -> bool:
        return bool(self.buf)

    def feed(self, data: bytes) -> list[Frame]:
        frames = []
        for byte in data:
            if not self.buf and byte != START:
                continue  # noise between frames
            self.buf.append(byte)
            while (frame := self._scan()) is not None:
                frames.append(frame)
        return frames

    def timeout(self) -> None:
        if self.buf:
            self.truncated += 1
            self.buf.clear()

    def _scan(self) -> Frame | None:
        buf = self.buf
        while True:
            skip = 0
            while skip < len(buf) and buf[skip] != START:
                skip += 1
            del buf[:skip]
            if len(buf) < 2:
                return None
            if buf[1] != VERSION:
                self.malformed += 1
                del buf[:1]
                continue
            if len(buf) < 4:
                return None
            if buf[3] > MAX_PAYLOAD:
                self.oversized += 1
                del buf[:1]
                continue
            need = HEADER + buf[3] + CRC_LEN
            if len(buf) < need:
                return None
            if crc16(bytes(buf[1 : need - 2])) != int.from_bytes(buf[need - 2 : need], "big"):
                self.crc_errors += 1
                del buf[:1]
                continue
            self.rx_frames += 1
            frame = Frame(buf[2], buf[4] | buf[5] << 8, bytes(buf[HEADER : need - 2]))
            del buf[:need]
            return frame
