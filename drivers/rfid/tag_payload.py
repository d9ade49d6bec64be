"""Tags that carry the map: a UHF tag's memory holds its obstacle's feature points.

Chen et al. (seed 003) put the UHF tags on the obstacles at their feature points, and each
tag carries "its global coordinates and the feature points of the obstacle" it is fixed to,
so the reader builds the map as it goes: the obstacle polygons (convex, fewer than seven
edges, §2.1) that the visibility-graph planner plans around.

The payload, little-endian, in a tag's user memory (32 bytes at most, 256 bits):

    version u8 = 1 | obstacle u16 | tag x u16, y u16 (cm) | n u8 (3..6) | n × (x u16, y u16) cm

Centimetres in 16 bits reach 655 m: a building's floor. ``decode`` rejects the whole payload
with a clear reason when anything is off (a short read, a concave or self-crossing polygon,
more than six vertices, a point off the map), and ``ObstacleBook`` turns the polygons it has
read into ``MapDelta``s: the cells whose centres lie inside a polygon become OCCUPIED, and
the cells an obstacle's earlier polygon held and its new one does not become FREE.
"""

from __future__ import annotations

import struct

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from protocol.map_messages import MapDelta

VERSION = 1
MAX_VERTICES = 6
"""The paper's "edge number less than seven"."""
_HEAD = struct.Struct("<BHHHB")
_POINT = struct.Struct("<HH")
CM = 0.01
FREE, OCCUPIED = 0, 1


class ObstaclePayload(BaseModel):
    """One tag's memory: which obstacle it is on, where the tag is, the obstacle's polygon."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    obstacle: int = Field(ge=0, lt=2**16)
    x: float = Field(ge=0, lt=655.36, allow_inf_nan=False)
    y: float = Field(ge=0, lt=655.36, allow_inf_nan=False)
    vertices: tuple[tuple[float, float], ...] = Field(min_length=3, max_length=MAX_VERTICES)
    """The feature points, metres (x east, y north), counter-clockwise."""

    @field_validator("vertices")
    @classmethod
    def _convex(cls, v: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
        pts = np.asarray(v, dtype=float)
        if not np.all(np.isfinite(pts)) or pts.min() < 0 or pts.max() >= 655.36:
            raise ValueError("feature points must lie within 0..655.36 m")
        edges = np.roll(pts, -1, axis=0) - pts
        turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1]
        turns = turns - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        if np.any(turns <= 0):
            raise ValueError("the feature points are not a convex polygon counter-clockwise")
        # A star (a pentagram's points in order) turns left at every vertex yet crosses
        # itself: its edge directions wind round twice, a convex polygon's once.
        angles = np.arctan2(edges[:, 1], edges[:, 0])
        winding = np.sum((np.roll(angles, -1) - angles) % (2 * np.pi))
        if winding > 2 * np.pi + 1e-6:
            raise ValueError("the feature points cross themselves")
        return v


def encode(p: ObstaclePayload) -> bytes:
    """The bytes written to the tag (positions rounded to the centimetre)."""
    out = [_HEAD.pack(VERSION, p.obstacle, round(p.x / CM), round(p.y / CM), len(p.vertices))]
    out += [_POINT.pack(round(x / CM), round(y / CM)) for x, y in p.vertices]
    return b"".join(out)


def decode(raw: bytes) -> ObstaclePayload:
    """A tag's memory as a payload; ValueError naming what is wrong, and nothing kept."""
    if len(raw) < _HEAD.size:
        raise ValueError(f"tag payload of {len(raw)} bytes is shorter than its header")
    version, obstacle, x, y, n = _HEAD.unpack_from(raw)
    if version != VERSION:
        raise ValueError(f"tag payload version {version}, expected {VERSION}")
    if not 3 <= n <= MAX_VERTICES:
        raise ValueError(f"an obstacle of {n} feature points: 3 to {MAX_VERTICES} expected")
    if len(raw) != _HEAD.size + n * _POINT.size:
        raise ValueError(f"tag payload of {len(raw)} bytes does not hold {n} feature points")
    pts = [_POINT.unpack_from(raw, _HEAD.size + i * _POINT.size) for i in range(n)]
    return ObstaclePayload(obstacle=obstacle, x=x * CM, y=y * CM,
                           vertices=tuple((px * CM, py * CM) for px, py in pts))  # fmt: skip


def polygon_cells(vertices: np.ndarray, shape: tuple[int, int], cell_m: float) -> np.ndarray:
    """Flat indices of the cells whose centres lie inside the convex polygon (metres)."""
    h, w = shape
    v = np.asarray(vertices, dtype=float)
    lo = np.floor(v.min(axis=0) / cell_m).astype(int)
    hi = np.ceil(v.max(axis=0) / cell_m).astype(int)
    cols = np.arange(max(lo[0], 0), min(hi[0], w))
    rows_up = np.arange(max(lo[1], 0), min(hi[1], h))  # counted from the south edge
    if cols.size == 0 or rows_up.size == 0:
        return np.empty(0, dtype=np.int64)
    cx, cy = np.meshgrid((cols + 0.5) * cell_m, (rows_up + 0.5) * cell_m)
    inside = np.ones(cx.shape, dtype=bool)
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):  # left of every edge
        inside &= (b[0] - a[0]) * (cy - a[1]) - (b[1] - a[1]) * (cx - a[0]) >= 0
    c_idx, r_up = np.meshgrid(cols, rows_up)
    rows = h - 1 - r_up[inside]
    return (rows * w + c_idx[inside]).astype(np.int64)


class ObstacleBook:
    """The obstacles read so far, and the map deltas they make."""

    def __init__(self, shape: tuple[int, int], cell_m: float) -> None:
        self.shape = shape
        self.cell_m = cell_m
        self.width_m, self.height_m = shape[1] * cell_m, shape[0] * cell_m
        self.polygons: dict[int, tuple[tuple[float, float], ...]] = {}
        self._cells: dict[int, np.ndarray] = {}
        self._pending: dict[int, tuple[tuple[float, float], ...]] = {}
        self.rejected: list[str] = []

    def read(self, raw: bytes) -> bool:
        """One tag's memory; True when it brings an obstacle new or changed. A bad payload
        is rejected whole (its reason kept in ``rejected``) and changes nothing."""
        try:
            p = decode(raw)
        except ValueError as exc:
            self.rejected.append(str(exc))
            return False
        pts = np.asarray(p.vertices)
        if pts[:, 0].max() > self.width_m or pts[:, 1].max() > self.height_m:
            self.rejected.append(f"obstacle {p.obstacle} reaches past the map")
            return False
        known = self._pending.get(p.obstacle, self.polygons.get(p.obstacle))
        if known == p.vertices:
            return False  # another tag of an obstacle already read
        self._pending[p.obstacle] = p.vertices
        return True

    def delta(self, seq: int, stamp: float, epoch: int | None = None) -> MapDelta | None:
        """The cells the obstacles read since the last delta change; None if none did."""
        if not self._pending:
            return None
        freed: list[np.ndarray] = []
        taken: list[np.ndarray] = []
        for key, verts in self._pending.items():
            new = polygon_cells(np.asarray(verts), self.shape, self.cell_m)
            old = self._cells.get(key)
            if old is not None:
                freed.append(np.setdiff1d(old, new))
            self.polygons[key], self._cells[key] = verts, new
            taken.append(new)
        self._pending = {}
        held = np.concatenate(list(self._cells.values()))
        gone = np.setdiff1d(np.concatenate(freed), held) if freed else np.empty(0, np.int64)
        cells = np.concatenate([np.unique(np.concatenate(taken)), gone])
        values = np.concatenate(
            [np.full(cells.size - gone.size, OCCUPIED), np.full(gone.size, FREE)]
        )
        return MapDelta.from_arrays(seq, self.shape, cells, values.astype(np.uint8), stamp,
                                    epoch=epoch)  # fmt: skip
