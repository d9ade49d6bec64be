"""Bytes on the wire for every message: JSON for the small ones, binary for maps.

Map deltas and snapshots are a fixed little-endian header and raw arrays, so a
400 × 400 map update costs a ``memcpy``, not a JSON list of numbers:

    MapDelta     "GBMD" u16 version, u16 flags, u32 seq, u32 height, u32 width,
                 f64 stamp, u32 count | [u64 epoch] | count × u32 flat cell index
                 | count × u8 value
    MapSnapshot  "GBMS" u16 version, u16 flags, u32 seq, u32 height, u32 width,
                 f64 stamp, u32 nbytes | [u64 epoch] | nbytes of zlib-compressed occupancy

The epoch is there only when bit 0 of ``flags`` (``FLAG_EPOCH``) is set: a sender that predates
epochs (flags 0) still decodes, as a source without one. Other flag bits are refused.

``decode`` never lets an exception other than ``DecodeError`` out; its ``code`` says
which kind of bad input it was (a ``StatusCode``: ``malformed``, ``unknown_field``,
``wrong_type``, ``invalid``, ``oversized``), so the daemon can count and report each kind.
"""

from __future__ import annotations

import struct
from typing import Any, TypeVar

import numpy as np
import pydantic_core
from pydantic import ValidationError

from .messages import MAX_DELTA_CELLS, MapDelta, MapSnapshot, Message, NavPath, StatusCode

M = TypeVar("M", bound=Message)

DELTA_MAGIC = b"GBMD"
SNAPSHOT_MAGIC = b"GBMS"
VERSION = 1
HEADER = struct.Struct("<4sHHIIIdI")
"""magic, version, flags, seq, height, width, stamp, count (delta) or nbytes (snapshot)."""
EPOCH = struct.Struct("<Q")
FLAG_EPOCH = 0x0001
"""``flags`` bit: a u64 epoch follows the header."""

MAX_SNAPSHOT_BYTES = 64 * 1024 * 1024
MAX_JSON_BYTES = 64 * 1024
"""The longest JSON message (a goal, a pose, a setting, …) taken: the largest real one is a
few hundred bytes; a megabyte of JSON would cost the parser before pydantic could refuse it."""


def max_bytes(kind: type[Message]) -> int:
    """The most bytes a ``kind`` can take on the wire; more is refused before parsing."""
    if kind is MapDelta:
        return HEADER.size + EPOCH.size + 5 * MAX_DELTA_CELLS
    if kind is MapSnapshot:
        return HEADER.size + EPOCH.size + MAX_SNAPSHOT_BYTES
    return MAX_JSON_BYTES


def map_cells(data: bytes) -> int | None:
    """Height × width a map message's header declares, read before anything is decoded or
    allocated (None if it has no header): the caller's memory budget is checked on it."""
    if len(data) < HEADER.size or data[:4] not in (DELTA_MAGIC, SNAPSHOT_MAGIC):
        return None
    _magic, _version, _flags, _seq, height, width, _stamp, _count = HEADER.unpack_from(data)
    return int(height) * int(width)


class DecodeError(ValueError):
    """A message rejected whole; ``code`` names the kind of bad input."""

    def __init__(self, code: StatusCode, reason: str) -> None:
        super().__init__(f"{code.value}: {reason}")
        self.code = code
        self.reason = reason


def encode(msg: Message) -> bytes:
    if isinstance(msg, MapDelta):
        return _encode_delta(msg)
    if isinstance(msg, MapSnapshot):
        return _encode_snapshot(msg)
    return msg.model_dump_json().encode()


def decode(kind: type[M], data: bytes) -> M:
    """Parse and validate ``data`` as a ``kind``; raise ``DecodeError`` if it is not one."""
    if len(data) > max_bytes(kind):
        raise DecodeError(
            StatusCode.OVERSIZED, f"{len(data)} bytes exceeds {max_bytes(kind)} for {kind.__name__}"
        )
    if kind is MapDelta:
        return _decode_delta(data)  # type: ignore[return-value]
    if kind is MapSnapshot:
        return _decode_snapshot(data)  # type: ignore[return-value]
    try:
        return kind.model_validate_json(data)
    except ValidationError as exc:
        raise _classify(exc) from None


def _classify(exc: ValidationError) -> DecodeError:
    errors = exc.errors(include_url=False, include_input=False)
    first = errors[0] if errors else {"type": "", "msg": str(exc), "loc": ()}
    kinds = {e["type"] for e in errors}
    where = ".".join(str(p) for p in first.get("loc", ())) or "message"
    reason = f"{where}: {first['msg']}"
    if kinds & {"json_invalid", "json_type"}:
        return DecodeError(StatusCode.MALFORMED, reason)
    if "extra_forbidden" in kinds:
        extra = next(e for e in errors if e["type"] == "extra_forbidden")
        where = ".".join(map(str, extra["loc"]))
        return DecodeError(StatusCode.UNKNOWN_FIELD, f"unknown field {where}")
    if any(k.endswith(("_type", "_parsing")) or k == "union_tag_invalid" for k in kinds):
        return DecodeError(StatusCode.WRONG_TYPE, reason)
    return DecodeError(StatusCode.INVALID, reason)


def _epoch_part(epoch: int | None) -> tuple[int, bytes]:
    """The header's flags and the bytes that follow it, for ``epoch``."""
    return (0, b"") if epoch is None else (FLAG_EPOCH, EPOCH.pack(epoch))


def _encode_delta(msg: MapDelta) -> bytes:
    return delta_bytes(msg.seq, msg.height, msg.width, msg.stamp, msg.cells, msg.values, msg.epoch)


def delta_bytes(seq: int, height: int, width: int, stamp: float, cells: bytes, values: bytes,
                epoch: int | None = None) -> bytes:  # fmt: skip
    """A delta's wire bytes from its parts, for a producer whose cells are its own (a mapper
    on its frame's path, where the ``MapDelta`` model's checks cost more than the frame's
    other host work together): ``cells`` little-endian uint32 flat indices inside the map,
    ``values`` one uint8 occupancy each, at most ``MAX_DELTA_CELLS``; the bytes are
    ``encode(MapDelta(...))``'s, and ``decode`` checks them as any delta's on arrival."""
    flags, tail = _epoch_part(epoch)
    head = HEADER.pack(DELTA_MAGIC, VERSION, flags, seq, height, width, stamp, len(values))
    return b"".join((head, tail, cells, values))


def proximity_bytes(ahead_m: float | None, nearest_m: float | None, bearing: float | None,
                    frame_stamp: float, stamp: float) -> bytes:  # fmt: skip
    """A ``Proximity``'s wire bytes from its figures, for the mapper on its frame's path
    (the model and its JSON dump were 60 µs of a paced frame's host time on an H100 host):
    the JSON of ``encode(Proximity(...))`` with Python's shortest float repr, which any JSON
    reader parses to the same floats; ``decode`` checks it as any message on arrival. The
    figures must be finite (the mapper's are: none is None)."""
    a = "null" if ahead_m is None else repr(float(ahead_m))
    n = "null" if nearest_m is None else repr(float(nearest_m))
    b = "null" if bearing is None else repr(float(bearing))
    return (
        f'{{"ahead_m":{a},"nearest_m":{n},"bearing":{b},"target_seen":null,'
        f'"frame_stamp":{float(frame_stamp)!r},"stamp":{float(stamp)!r}}}'
    ).encode()


def _header(data: bytes, magic: bytes) -> tuple[int, int | None, int, int, float, int, int]:
    """seq, epoch, height, width, stamp, count or nbytes, and where the body starts."""
    if len(data) < HEADER.size:
        raise DecodeError(StatusCode.MALFORMED, f"{len(data)} bytes is shorter than the header")
    got_magic, version, flags, seq, height, width, stamp, count = HEADER.unpack_from(data)
    if got_magic != magic:
        raise DecodeError(StatusCode.MALFORMED, f"bad magic {got_magic!r}, expected {magic!r}")
    if version != VERSION:
        raise DecodeError(StatusCode.MALFORMED, f"unsupported version {version}")
    if flags & ~FLAG_EPOCH:
        raise DecodeError(StatusCode.MALFORMED, f"unknown header flags {flags:#06x}")
    epoch, body = None, HEADER.size
    if flags & FLAG_EPOCH:
        if len(data) < HEADER.size + EPOCH.size:
            raise DecodeError(StatusCode.MALFORMED, "header says an epoch follows; none does")
        (epoch,) = EPOCH.unpack_from(data, HEADER.size)
        body += EPOCH.size
    return seq, epoch, height, width, stamp, count, body


def _validated(kind: type[M], fields: dict) -> M:
    try:
        return kind.model_validate(fields)
    except ValidationError as exc:
        raise _classify(exc) from None


def _decode_delta(data: bytes) -> MapDelta:
    seq, epoch, height, width, stamp, n, start = _header(data, DELTA_MAGIC)
    # Before touching the body: an oversized delta is refused whatever it holds.
    if n > MAX_DELTA_CELLS:
        raise DecodeError(StatusCode.OVERSIZED, f"delta of {n} cells exceeds {MAX_DELTA_CELLS}")
    if len(data) != start + 5 * n:
        raise DecodeError(StatusCode.MALFORMED, f"{len(data)} bytes for {n} cells")
    body = memoryview(data)[start:]
    fields = dict(
        seq=seq,
        epoch=epoch,
        height=height,
        width=width,
        stamp=stamp,
        cells=bytes(body[: 4 * n]),
        values=bytes(body[4 * n :]),
    )
    return _validated(MapDelta, fields)


def _encode_snapshot(msg: MapSnapshot) -> bytes:
    flags, epoch = _epoch_part(msg.epoch)
    head = HEADER.pack(
        SNAPSHOT_MAGIC, VERSION, flags, msg.seq, msg.height, msg.width, msg.stamp,
        len(msg.occupancy),
    )  # fmt: skip
    return b"".join((head, epoch, msg.occupancy))


def _decode_snapshot(data: bytes) -> MapSnapshot:
    seq, epoch, height, width, stamp, nbytes, start = _header(data, SNAPSHOT_MAGIC)
    if nbytes > MAX_SNAPSHOT_BYTES:
        raise DecodeError(
            StatusCode.OVERSIZED, f"snapshot of {nbytes} bytes exceeds {MAX_SNAPSHOT_BYTES}"
        )
    if len(data) != start + nbytes:
        raise DecodeError(StatusCode.MALFORMED, f"{len(data)} bytes for a {nbytes}-byte body")
    fields = dict(
        seq=seq, epoch=epoch, height=height, width=width, stamp=stamp, occupancy=data[start:]
    )
    snap = _validated(MapSnapshot, fields)
    try:
        snap.array()
    except ValueError as exc:
        raise DecodeError(StatusCode.INVALID, str(exc)) from None
    return snap


_PATH_FIELDS = tuple(NavPath.model_fields)[1:]
"""The path message's fields after ``cells``, in the model's (and so the JSON's) order."""
_PATH_FLOATS = frozenset(k for k in _PATH_FIELDS if NavPath.model_fields[k].annotation is float)


class PathBytes:
    """``encode(NavPath(cells=..., **meta))`` for one user's paths, step after step.

    Between two map deltas most steps read the same path again (the user's cell and the map
    unchanged): the cells' JSON, most of the message, is kept while the cells are equal, and
    the rest (cost, stamps) is written by pydantic's own serialiser, float fields as floats.
    A value of another type than the field's (a numpy integer) takes the model's way."""

    def __init__(self) -> None:
        self._cells: np.ndarray | None = None
        self._json = b""

    def __call__(self, cells: np.ndarray, meta: dict[str, Any]) -> bytes:
        rest: dict[str, Any] = {}
        for name in _PATH_FIELDS:
            value = meta.get(name, NavPath.model_fields[name].default)
            if name in _PATH_FLOATS and type(value) in (float, int):
                value = float(value)
            elif type(value) is not int:
                built = NavPath.model_construct(cells=[tuple(rc) for rc in cells.tolist()], **meta)
                return encode(built)
            rest[name] = value
        if self._cells is None or not np.array_equal(self._cells, cells):
            self._cells = np.array(cells, copy=True)
            self._json = pydantic_core.to_json(cells.tolist())
        return b"".join((b'{"cells":', self._json, b",", pydantic_core.to_json(rest)[1:]))
