"""The reader's line protocol (see PROTOCOL.md): format and strict parsing of one line.

A line is either a read accepted whole or rejected with one reason from ``REJECT_REASONS``;
the caller counts the reasons and keeps going.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass

RSSI_MIN_DBM = -100.0
"""Below the reader's sensitivity: a line claiming this could not have been decoded."""
RSSI_MAX_DBM = 0.0
"""A passive tag's backscatter never arrives stronger than this."""
MAX_LINE_BYTES = 112
"""A memory line at its longest: a 32-digit id and a tag's 32 bytes of user memory in hex."""
MAX_MEMORY_BYTES = 32
"""A UHF tag's user memory as the reader reports it (``tag_payload``'s 256 bits)."""

_LINE_RE = re.compile(
    r"^TAG,(?P<id>[0-9A-F]{4,32}),(?P<rssi>-?[0-9]{1,3}(?:\.[0-9])?),(?P<t>[0-9]{1,10})"
    r"\*(?P<cs>[0-9A-F]{2})$"
)

_MEM_RE = re.compile(
    r"^MEM,(?P<id>[0-9A-F]{4,32}),(?P<data>(?:[0-9A-F]{2}){1,"
    + str(MAX_MEMORY_BYTES)
    + r"})\*(?P<cs>[0-9A-F]{2})$"
)

REJECT_REASONS = ("garbage", "checksum", "impossible_rssi", "unknown_tag")


@dataclass(frozen=True)
class Read:
    """One tag read: who, how strong, when (host clock, seconds)."""

    tag_id: str
    rssi: float
    t: float
    reader_ms: int = 0


@dataclass(frozen=True)
class Memory:
    """A tag's user memory, which the reader reads once when a tag first answers."""

    tag_id: str
    data: bytes
    t: float


class BadLine(ValueError):
    """A rejected line; ``reason`` is one of REJECT_REASONS."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


def checksum(body: str) -> str:
    """XOR of the bytes of ``body`` (the part before ``*``), two upper-case hex digits."""
    cs = 0
    for b in body.encode("ascii"):
        cs ^= b
    return f"{cs:02X}"


def format_read(tag_id: str, rssi: float, reader_ms: int) -> bytes:
    """The line a reader sends for one read (what the mock reader writes)."""
    body = f"TAG,{tag_id},{rssi:.1f},{reader_ms % 2**32}"
    return f"{body}*{checksum(body)}\n".encode("ascii")


def format_memory(tag_id: str, data: bytes) -> bytes:
    """The line a reader sends for a tag's user memory."""
    body = f"MEM,{tag_id},{data.hex().upper()}"
    return f"{body}*{checksum(body)}\n".encode("ascii")


def parse_line(raw: bytes, t: float) -> Read | Memory | None:
    """Parse one line (without or with its ``\\n``); ``None`` for info and empty lines.

    Raises BadLine for anything else that is not a well-formed read. Unknown tag ids are
    not judged here — the tag map does that (``ReadFilter``).
    """
    if len(raw) > MAX_LINE_BYTES + 2:
        raise BadLine("garbage", f"line of {len(raw)} bytes")
    try:
        line = raw.decode("ascii").rstrip("\r\n")
    except UnicodeDecodeError:
        raise BadLine("garbage", "not ASCII") from None
    if not line or line.startswith("#"):
        return None
    mem = _MEM_RE.match(line)
    if mem is not None:
        body = line[: line.index("*")]
        if checksum(body) != mem["cs"]:
            raise BadLine("checksum", f"{mem['cs']} != {checksum(body)}")
        return Memory(tag_id=mem["id"], data=bytes.fromhex(mem["data"]), t=t)
    m = _LINE_RE.match(line)
    if m is None:
        raise BadLine("garbage", repr(line[:40]))
    body = line[: line.index("*")]
    if checksum(body) != m["cs"]:
        raise BadLine("checksum", f"{m['cs']} != {checksum(body)}")
    rssi = float(m["rssi"])
    if not (math.isfinite(rssi) and RSSI_MIN_DBM <= rssi <= RSSI_MAX_DBM):
        raise BadLine("impossible_rssi", f"{rssi} dBm")
    reader_ms = int(m["t"])
    if reader_ms >= 2**32:
        raise BadLine("garbage", f"reader time {reader_ms} ms")
    return Read(tag_id=m["id"], rssi=rssi, t=t, reader_ms=reader_ms)


class ReadFilter:
    """Parses lines, keeps reads of known tags, counts every rejection by reason."""

    def __init__(self, known_ids: frozenset[str] | set[str]) -> None:
        self.known_ids = frozenset(known_ids)
        self.accepted = 0
        self.rejected: Counter[str] = Counter({r: 0 for r in REJECT_REASONS})
        self.info_lines = 0
        self.memories = 0
        """Memory lines of known tags passed on (not reads: not in ``accepted``)."""

    def feed(self, raw: bytes, t: float) -> Read | Memory | None:
        try:
            read = parse_line(raw, t)
        except BadLine as exc:
            self.rejected[exc.reason] += 1
            return None
        if read is None:
            if raw.strip():
                self.info_lines += 1
            return None
        if read.tag_id not in self.known_ids:
            self.rejected["unknown_tag"] += 1
            return None
        if isinstance(read, Memory):
            self.memories += 1
            return read
        self.accepted += 1
        return read

    def counts(self) -> dict[str, int]:
        return {"accepted": self.accepted, **self.rejected, "info": self.info_lines}
