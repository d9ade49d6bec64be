"""The tag map: where every tag is. A JSON file, validated whole on load, and a generator.

UHF tags sit on obstacle corners, as in Chen et al., carrying their coordinates; a flat wall
also gets one every ``edge_spacing_m`` so that no stretch of floor is out of range. LF
tags lie in the floor on a 20 cm lattice and are read from 10 cm: a read pins the user
down. The paper lays them at intersections; ``lf_layout`` says where they go here:
``corners`` (patches on the floor around the obstacle corners, where a route turns),
``crossings`` (the paper's Figure 4: a small patch, tags 20 cm apart, where the ways around
each convex corner of an obstacle meet — centred ``lf_offset_m`` out along the corner's
diagonal, where a walk kept ω/2 clear of the obstacle bends, of radius ``crossing_patch_m``;
and one at each of ``landmarks_xy``, the goals a user may name),
``floor`` (the whole walkable
floor — in an open courtyard every spot is a crossing) or ``none``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

FORMAT = "guidebelt-tagmap"
LF_LAYOUTS = ("none", "corners", "crossings", "floor")


class Tag(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str = Field(pattern=r"^[0-9A-F]{4,32}$")
    kind: Literal["uhf", "lf"]
    x: float = Field(allow_inf_nan=False)
    y: float = Field(allow_inf_nan=False)


class TagMapFile(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Literal["guidebelt-tagmap"] = FORMAT
    version: Literal[1] = 1
    width_m: float = Field(gt=0, allow_inf_nan=False)
    height_m: float = Field(gt=0, allow_inf_nan=False)
    lf_range_m: float = Field(default=0.10, gt=0, le=1.0)
    tags: list[Tag]

    @model_validator(mode="after")
    def _consistent(self) -> TagMapFile:
        ids = [t.id for t in self.tags]
        if len(set(ids)) != len(ids):
            dup = sorted({i for i in ids if ids.count(i) > 1})[:5]
            raise ValueError(f"duplicate tag ids: {dup}")
        for t in self.tags:
            if not (0 <= t.x <= self.width_m and 0 <= t.y <= self.height_m):
                raise ValueError(f"tag {t.id} at ({t.x}, {t.y}) is outside the map")
        if sum(t.kind == "uhf" for t in self.tags) < 3:
            raise ValueError("trilateration needs at least 3 UHF tags")
        return self


class TagMap:
    """The loaded map, as arrays for the localiser and the read model."""

    def __init__(self, spec: TagMapFile) -> None:
        self.spec = spec
        self.width_m = spec.width_m
        self.height_m = spec.height_m
        self.lf_range_m = spec.lf_range_m
        uhf = [t for t in spec.tags if t.kind == "uhf"]
        lf = [t for t in spec.tags if t.kind == "lf"]
        self.uhf_ids = [t.id for t in uhf]
        self.uhf_xy = np.array([[t.x, t.y] for t in uhf], dtype=float).reshape(-1, 2)
        self.lf_ids = [t.id for t in lf]
        self.lf_xy = np.array([[t.x, t.y] for t in lf], dtype=float).reshape(-1, 2)
        self.uhf_index = {tid: i for i, tid in enumerate(self.uhf_ids)}
        self.lf_index = {tid: i for i, tid in enumerate(self.lf_ids)}

    @property
    def ids(self) -> frozenset[str]:
        return frozenset(self.uhf_index) | frozenset(self.lf_index)

    def dump(self, path: str | Path) -> None:
        Path(path).write_text(self.spec.model_dump_json(indent=1))

    @classmethod
    def load(cls, path: str | Path) -> TagMap:
        """Read and validate a tag map file; raises ValueError naming what is wrong."""
        try:
            raw = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ValueError(f"cannot read tag map {path}: {exc}") from exc
        return cls(TagMapFile.model_validate(raw))


def _corner_vertices(occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid vertices at a corner of an obstacle, and vertices on an obstacle's edge.

    A vertex touches four cells (outside the map counts as wall). One or three of them
    occupied: a convex or concave corner. Two, side by side: a straight edge.
    """
    pad = np.pad(occupied, 1, constant_values=True).astype(np.int8)
    nw, ne, sw, se = pad[:-1, :-1], pad[:-1, 1:], pad[1:, :-1], pad[1:, 1:]
    count = nw + ne + sw + se
    corner = (count == 1) | (count == 3)
    edge = (count == 2) & (nw == ne) | (count == 2) & (nw == sw)
    return np.argwhere(corner), np.argwhere(edge)


def _convex_corners(occupied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices with exactly one occupied cell, and the outward diagonal (drow, dcol) of each.

    The map's border is not padded here: the courtyard's own walls are cells of the map.
    """
    pad = np.pad(occupied, 1, constant_values=False).astype(np.int8)
    nw, ne, sw, se = pad[:-1, :-1], pad[:-1, 1:], pad[1:, :-1], pad[1:, 1:]
    one = (nw + ne + sw + se) == 1
    v = np.argwhere(one)
    # Away from the one occupied cell: south-east of a north-west cell, and so on.
    dr = np.where(nw[one] | ne[one], 1, -1)
    dc = np.where(nw[one] | sw[one], 1, -1)
    return v, np.column_stack([dr, dc])


def _thin(points: np.ndarray, spacing: float, kept: list[np.ndarray]) -> list[np.ndarray]:
    """Greedy: keep each point farther than ``spacing`` from every point kept so far."""
    for p in points:
        if all(math.dist(p, q) >= spacing for q in kept):
            kept.append(p)
    return kept


def _ids(rng: np.random.Generator, n: int, digits: int, taken: set[str]) -> list[str]:
    out = []
    while len(out) < n:
        tid = "".join(rng.choice(list("0123456789ABCDEF"), digits))
        if tid not in taken:
            taken.add(tid)
            out.append(tid)
    return out


def generate(
    occupancy: np.ndarray,
    cell_m: float,
    *,
    seed: int = 0,
    corner_spacing_m: float = 1.0,
    edge_spacing_m: float = 2.0,
    lf_layout: str = "floor",
    lf_spacing_m: float = 0.20,
    lf_range_m: float = 0.10,
    lf_patch_m: float = 0.8,
    lf_offset_m: float = 0.45,
    crossing_patch_m: float = 0.5,
    landmarks_xy: np.ndarray | None = None,
    walkable: np.ndarray | None = None,
) -> TagMap:
    """Place tags in a map of known obstacles (``occupancy`` != 0 is an obstacle).

    ``walkable`` (bool, same shape) is where LF tags may lie; by default every free cell.
    Row 0 is north; metres have their origin at the south-west corner.
    """
    if lf_layout not in LF_LAYOUTS:
        raise ValueError(f"unknown lf_layout {lf_layout!r}; choose one of {LF_LAYOUTS}")
    occupied = np.asarray(occupancy) != 0
    h, w = occupied.shape
    rng = np.random.default_rng(seed)

    def vertex_xy(v: np.ndarray) -> np.ndarray:  # (row, col) of a vertex → metres
        return np.column_stack([v[:, 1] * cell_m, (h - v[:, 0]) * cell_m]).astype(float)

    corners, edges = _corner_vertices(occupied)
    corner_xy = vertex_xy(corners)
    kept = _thin(corner_xy, corner_spacing_m, [])
    n_corner = len(kept)
    kept = _thin(vertex_xy(edges), edge_spacing_m, kept)
    uhf_xy = np.array(kept).reshape(-1, 2)

    lf_xy = np.empty((0, 2))
    if lf_layout != "none":
        free = ~occupied if walkable is None else np.asarray(walkable, dtype=bool)
        gx, gy = np.meshgrid(
            np.arange(lf_spacing_m / 2, w * cell_m, lf_spacing_m),
            np.arange(lf_spacing_m / 2, h * cell_m, lf_spacing_m),
        )
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        rows = np.clip(h - 1 - np.floor(pts[:, 1] / cell_m).astype(int), 0, h - 1)
        cols = np.clip(np.floor(pts[:, 0] / cell_m).astype(int), 0, w - 1)
        keep = free[rows, cols]
        if lf_layout in ("corners", "crossings"):
            if lf_layout == "corners":
                centres = uhf_xy[:n_corner]
            else:
                v, out = _convex_corners(occupied)
                diag = np.column_stack([out[:, 1], -out[:, 0]]) / math.sqrt(2.0)
                centres = vertex_xy(v) + lf_offset_m * diag
                if landmarks_xy is not None:  # the doors a user may ask for are signposted too
                    centres = np.vstack([centres, np.asarray(landmarks_xy, float).reshape(-1, 2)])
            radius = lf_patch_m if lf_layout == "corners" else crossing_patch_m
            near = np.zeros(len(pts), dtype=bool)
            for c in centres:
                near |= np.hypot(*(pts - c).T) <= radius
            keep &= near
        lf_xy = pts[keep]

    taken: set[str] = set()
    uhf_ids = _ids(rng, len(uhf_xy), 24, taken)
    lf_ids = _ids(rng, len(lf_xy), 10, taken)
    tags = [
        Tag(id=i, kind=kind, x=float(x), y=float(y))
        for kind, ids, xy in (("uhf", uhf_ids, uhf_xy), ("lf", lf_ids, lf_xy))
        for i, (x, y) in zip(ids, xy, strict=True)
    ]
    spec = TagMapFile(width_m=w * cell_m, height_m=h * cell_m, lf_range_m=lf_range_m, tags=tags)
    return TagMap(spec)
