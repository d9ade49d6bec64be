"""The paper's rubber band on the GPU (Hong & DeSouza, Figure 4: a thread per band point),
over ``kernels/rubber_band.cu``: the same iteration as ``rubber_band.py``'s, read from the
field where it already lies — the cuda planner's padded ``w`` on the device — so a guidance
call copies only the path and the inflated map over, and the band back.

One launch per band: the kernel runs every iteration in one block (block barriers only),
moving all points from the last iteration's positions, as the CPU form does; the result
agrees with it to the rounding of ``exp`` and ``hypot`` (a tie between two moves may fall
the other way; ``tests/daemon/planning/harmonic/test_band_cuda.py`` states the bound).
"""

from __future__ import annotations

import functools
from pathlib import Path

import cupy as cp
import numpy as np

SOURCE = Path(__file__).with_name("kernels") / "rubber_band.cu"
THREADS = 256
"""A guidance call's band is a few hundred points (guidance looks 2.5 legs ahead): one
block of 256 threads covers it in one or two strides."""


@functools.cache
def _kernel(real: str) -> cp.RawKernel:
    return cp.RawKernel(SOURCE.read_text(), "rubber_band",
                        options=("--std=c++17", f"-DW={real}"))  # fmt: skip


def rubber_band_cuda(
    path: np.ndarray,
    w: cp.ndarray | np.ndarray,
    blocked: np.ndarray,
    *,
    pad: int = 0,
    delta: float = 0.25,
    iterations: int = 200,
    tol: float = 1e-3,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """The band of ``path`` (``(k, 2)`` cells) in the field ``w`` (``(h + 2 pad, width + 2
    pad)``, float32 or float64, on the device or the host) over ``blocked`` (``(h, width)``);
    ``(k, 2) float64`` in continuous cell units and the iterations run. Ends stay fixed.
    ``start``: the first points (``rubber_band.warm_points``; default the cell centres)."""
    pts = np.asarray(path, dtype=np.float64) + 0.5 if start is None else start.copy()
    k = len(pts)
    if k <= 2:
        return pts, 0
    h, width = blocked.shape
    wd = cp.asarray(w)
    if wd.dtype not in (cp.float32, cp.float64):
        wd = wd.astype(cp.float64)
    if wd.size != (h + 2 * pad) * (width + 2 * pad):
        raise ValueError(f"field of {wd.size} cells does not match the map {h}x{width}, pad {pad}")
    wd = cp.ascontiguousarray(wd)
    real = "double" if wd.dtype == cp.float64 else "float"
    dev = cp.asarray(np.ascontiguousarray(pts))
    spare = cp.empty_like(dev)
    done = cp.zeros(1, dtype=cp.int32)
    mask = cp.asarray(np.ascontiguousarray(blocked, dtype=np.bool_).view(np.uint8))
    _kernel(real)(
        (1,), (THREADS,),
        (dev, spare, np.int32(k), wd, mask, np.int32(h), np.int32(width), np.int32(pad),
         np.float64(delta), np.int32(iterations), np.float64(tol), done),
    )  # fmt: skip
    return dev.get(), int(done.get()[0])
