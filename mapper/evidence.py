"""One frame's evidence per cell, for the log-odds fusion: which cells it hit, which it saw
through.

A depth camera's range noise moves each point along its own ray (sd 1 mm + 2.5 mm/m², the
simulated RealSense's: 1.1 cm at 2 m, 2.3 cm at 3 m). A face some δ behind a cell boundary
therefore leaves a share Φ(−δ/σ) of its points in the free cell in front of it, every frame
the same: fusing frames cannot tell that tail from an obstacle, because the tail is there
in every frame. What tells it is its neighbour: the cell the same rays go on into holds the
face itself, with the bulk of the points. A cell whose obstacle points are fewer than
``tail_share`` of those of the cell just beyond it along the ray is that face's tail: its
rays went through it, and where its floor is seen it counts as a pass. With
``tail_share`` = 0.25 a face nearer the boundary than 0.84 σ (Φ(−δ/σ) / (1 − Φ(−δ/σ)) ≥ 0.25)
still marks the cell in front, which is then within a centimetre of it.
"""

from __future__ import annotations

import math

import numpy as np

from .binning import Window

_OFFSETS = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]
_BEYOND_COS = math.cos(math.radians(50.0))
"""A neighbour is beyond a cell along the ray when its direction is within 50° of the ray's:
one or two of the eight, so a ray meeting a face at a slant still finds the face's cell."""


def beyond_counts(obst: np.ndarray, win: Window, cam_x: float, cam_y: float) -> np.ndarray:
    """Per window cell, the most obstacle points in a neighbour just beyond it along the
    ray from the camera."""
    side = win.side
    inv = 1.0 / win.cell_m
    cam_row = win.map_rows - 1 - cam_y * inv + 0.5 - win.r0
    cam_col = cam_x * inv - 0.5 - win.c0
    rows = np.arange(side, dtype=np.float32)[:, None] - np.float32(cam_row)
    cols = np.arange(side, dtype=np.float32)[None, :] - np.float32(cam_col)
    norm = np.hypot(rows, cols) + np.float32(1e-6)
    ur, uc = rows / norm, cols / norm
    padded = np.pad(obst, 1)
    best = np.zeros_like(obst)
    for dr, dc in _OFFSETS:
        toward = (ur * dr + uc * dc) / math.hypot(dr, dc) > _BEYOND_COS
        there = padded[1 + dr : 1 + dr + side, 1 + dc : 1 + dc + side]
        np.maximum(best, np.where(toward, there, 0), out=best)
    return best


def range_tail(obst: np.ndarray, win: Window, cam_x: float, cam_y: float,
               tail_share: float) -> np.ndarray:  # fmt: skip
    """Cells whose obstacle points are the range-noise tail of the face beyond them."""
    return (obst > 0) & (obst < tail_share * beyond_counts(obst, win, cam_x, cam_y))
