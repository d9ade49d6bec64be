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
STATUS_MS = 1000
INTENSITY_MAX = 100
INTENSITY_FLOOR_PCT = 40  # intensity scales motor levels by 40..100 %, never to nothing
DEBOUNCE_MS = 20  # a button's level must hold this long to count
LONG_PRESS_MS = 800  # held this long: a long press, reported while still held
BUTTON_RESEND_MS = 100  # an unacknowledged press goes again this often...
BUTTON_EXPIRE_MS = 2000  # ...until acknowledged or this old (then counted as dropped)
BUTTON_QUEUE = 4
BUTTONS = 3


class FrameType(IntEnum):
    PATTERN = 0x01
    STOP = 0x02
    PING = 0x03
    INTENSITY = 0x04
    BUTTON_ACK = 0x05
    ACK = 0x81
    HEARTBEAT = 0x82
    BUTTON = 0x83
    STATUS = 0x84


class PressKind(IntEnum):
    SHORT = 1  # released before LONG_PRESS_MS: reported at the release
    LONG = 2  # held LONG_PRESS_MS: reported at that moment, the release is not


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
INTENSITY_LEN = 1
BUTTON_ACK_LEN = 2
BUTTON_LEN = 4
STATUS_LEN = 8
_PATTERN = struct.Struct("<4BHH")
_ACK = struct.Struct("<HB")
_HEARTBEAT = struct.Struct("<BH4B6HI")
_BUTTON = struct.Struct("<HBB")
_STATUS = struct.Struct("<HBBHH")


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


def intensity_frame(seq: int, intensity: int) -> bytes:
    return encode(FrameType.INTENSITY, seq, bytes([intensity]))


def button_ack_frame(seq: int, press: int) -> bytes:
    return encode(FrameType.BUTTON_ACK, seq, struct.pack("<H", press & 0xFFFF))


def scale_level(level: int, intensity: int) -> int:
    """A motor level as the firmware drives it at ``intensity`` (``frame_scale_level``).

    Every level is scaled by the same factor, 40 % at intensity 0 up to 100 % at 100, so a
    pattern keeps its shape (which motors, which period: what tells events apart by touch)
    and a GUIDE blend keeps its direction; the 40 % floor keeps every pattern felt."""
    intensity = min(intensity, INTENSITY_MAX)
    pct = INTENSITY_FLOOR_PCT + (INTENSITY_MAX - INTENSITY_FLOOR_PCT) * intensity // INTENSITY_MAX
    out = (level * pct + 50) // 100
    return 1 if level and not out else out  # a motor that is on stays on


@dataclass(frozen=True)
class Button:
    """A debounced press: ``press`` numbers the belt's presses (1, 2, …, wrapping at 2¹⁶,
    never 0), so a press repeated until acknowledged is recognised as the same one."""

    press: int
    button: int  # 0..BUTTONS-1
    kind: PressKind

    def payload(self) -> bytes:
        return _BUTTON.pack(self.press, self.button, self.kind)

    @classmethod
    def unpack(cls, payload: bytes) -> Button:
        press, button, kind = _BUTTON.unpack(payload)
        return cls(press, button, PressKind(kind))


@dataclass(frozen=True)
class Status:
    battery_mv: int  # the battery, from ADC0 through the 1:2 divider
    intensity: int  # the level applied, 0..100
    pending: int  # presses not yet acknowledged
    presses: int  # presses since reset (wraps)
    presses_dropped: int  # presses that expired unacknowledged or found the queue full

    def payload(self) -> bytes:
        return _STATUS.pack(
            self.battery_mv, self.intensity, self.pending, self.presses, self.presses_dropped
        )

    @classmethod
    def unpack(cls, payload: bytes) -> Status:
        return cls(*_STATUS.unpack(payload))


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

    def decode(self) -> Ack | Heartbeat | Pattern | Button | Status | None:
        """The typed message, or None for a type/length this side does not know."""
        n = len(self.payload)
        if self.ftype == FrameType.BUTTON and n == BUTTON_LEN and self.payload[3] in (1, 2):
            return Button.unpack(self.payload)
        if self.ftype == FrameType.STATUS and n == STATUS_LEN:
            return Status.unpack(self.payload)
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
