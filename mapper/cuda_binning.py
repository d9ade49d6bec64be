"""The per-pixel pass of ``binning.py`` on the GPU with CuPy, same arguments, same result.

The depth image goes up once; back-projection, the pose, the height test and the cell
index are elementwise kernels over all pixels; the per-cell counts are a ``bincount`` over
the window; the nearest obstacle and the farthest free point of each column bin are
``scatter_min``/``scatter_max`` of the squared range, and the point that reached it is
picked out with a second scatter over the pixel index. Only the window's counts and the
per-bin arrays (a few kB) come back.
"""

from __future__ import annotations

import cupy as cp
import cupyx
import numpy as np

from .binning import MIN_DEPTH_M, PUSH_M, Binned, Window

_GRIDS: dict[tuple[int, int, int], tuple] = {}


def _pixel_grid(h: int, w: int, stride: int) -> tuple:
    """Column and row of every sampled pixel, kept on the device between frames."""
    key = (h, w, stride)
    if key not in _GRIDS:
        v, u = cp.mgrid[0:h:stride, 0:w:stride]
        _GRIDS[key] = (u.ravel().astype(cp.float64), v.ravel().astype(cp.float64),
                       (u.ravel() // 1).astype(cp.int32))  # fmt: skip
    return _GRIDS[key]


def _pick(r2: cp.ndarray, bins: cp.ndarray, nbins: int, best: cp.ndarray, xs, ys, fill):
    """Per bin: (best r2, x, y) of the point whose r2 equals the bin's best (lowest index)."""
    idx = cp.arange(r2.size, dtype=cp.int64)
    winner = cp.full(nbins, r2.size, cp.int64)
    at = r2 == best[bins]
    cupyx.scatter_min(winner, bins[at], idx[at])
    out = cp.full((nbins, 3), fill, cp.float64)
    has = winner < r2.size
    sel = winner[has]
    out[has, 0] = best[has]
    out[has, 1] = xs[sel]
    out[has, 2] = ys[sel]
    return out


def bin_frame_cuda(depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
                   floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
                   cols_per_bin: int, stride: int,
                   min_depth: float = MIN_DEPTH_M) -> Binned:  # fmt: skip
    h, w = depth.shape
    u, v, ucol = _pixel_grid(h, w, stride)
    # float64 as the CPU pass, so both bin a point on a cell boundary alike (H100: fast FP64).
    d = cp.asarray(depth)[::stride, ::stride].ravel().astype(cp.float64) * scale
    ok = (d >= min_depth) & (d < 1e4)  # NaN compares false: missing
    rx = (u - intr.cx) / intr.fx * d
    ry = (v - intr.cy) / intr.fy * d
    r = np.asarray(rot, np.float64)
    tx, ty, tz = (float(x) for x in t)
    px = r[0, 0] * rx + r[0, 1] * ry + r[0, 2] * d + tx
    py = r[1, 0] * rx + r[1, 1] * ry + r[1, 2] * d + ty
    pz = r[2, 0] * rx + r[2, 1] * ry + r[2, 2] * d + (tz - floor_z)
    dx, dy = px - tx, py - ty
    r2 = dx * dx + dy * dy
    nbins = (w + cols_per_bin - 1) // cols_per_bin
    bins = ucol // cols_per_bin
    max_r2 = max_range * max_range
    beyond = ok & (r2 > max_r2)
    inside = ok & ~beyond
    floor = inside & (pz < min_h)
    obst = inside & (pz >= min_h) & (pz <= max_h)
    # Past the range: free as far as the range along the point's direction.
    k = cp.where(beyond, max_range / cp.sqrt(cp.maximum(r2, 1e-12)), 1.0)
    fx, fy = cp.where(beyond, tx + dx * k, px), cp.where(beyond, ty + dy * k, py)
    free_r2 = cp.where(beyond, max_r2, cp.where(floor, r2, -1.0))
    hit_r2 = cp.where(obst, r2, np.inf)
    best_hit = cp.full(nbins, np.inf, cp.float64)
    cupyx.scatter_min(best_hit, bins, hit_r2)
    best_far = cp.full(nbins, -1.0, cp.float64)
    cupyx.scatter_max(best_far, bins, free_r2)
    hit = _pick(hit_r2, bins, nbins, best_hit, px, py, np.inf)
    far = _pick(free_r2, bins, nbins, best_far, fx, fy, -1.0)
    hit[~cp.isfinite(best_hit), 0] = np.inf
    far[best_far < 0, 0] = -1.0
    inv = 1.0 / win.cell_m
    # As binning.py: an obstacle point on a cell boundary belongs to the cell behind it.
    push = cp.where(obst, 1.0 + PUSH_M / cp.sqrt(r2 + 1e-12), 1.0)
    row = (win.map_rows - 1 - cp.floor((ty + dy * push) * inv).astype(cp.int32)) - win.r0
    col = cp.floor((tx + dx * push) * inv).astype(cp.int32) - win.c0
    inwin = inside & (row >= 0) & (row < win.side) & (col >= 0) & (col < win.side)
    # Obstacle points count in plane 0, floor points in plane 1, as in binning.py.
    plane = cp.where(obst, 0, cp.where(floor, 1, -1))
    keep = inwin & (plane >= 0)
    flat = (plane * (win.side * win.side) + row * win.side + col)[keep]
    counts = cp.bincount(flat, minlength=2 * win.side * win.side).astype(cp.int32)
    valid = ok.sum()
    return Binned(
        counts.reshape(2, win.side, win.side).get(), hit.get(), far.get(), int(valid.get())
    )
