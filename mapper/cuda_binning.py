"""The per-pixel pass of ``binning.py`` on the GPU: same arguments, same result.

One CUDA kernel (``kernels/bin_pixels.cu``, built with CuPy's ``RawModule``) back-projects
every pixel, moves it into the world, tests its height and counts it in its cell with
``atomicAdd``; the nearest obstacle point and the farthest free point of each bearing bin
are 64-bit ``atomicMin``/``atomicMax`` of (squared range, pixel index) keys, and a second,
tiny kernel reads back the winning points. The depth image goes up once; the window's
counts and the per-bin arrays (a few kB) come back in one copy.

Both copies go through page-locked host buffers on the pass's own stream, and the resets are
memsets on it, so the frame waits on the device once, at the end: a copy from pageable memory
is staged by the driver and waits (round 4 on an H100: about 150 µs of a 210 µs call were the
copies, the kernels 60 µs).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cupy as cp
import cupyx
import numpy as np

from .binning import MIN_DEPTH_M, PUSH_M, Binned, Window, bearing_bins

KERNEL = Path(__file__).with_name("kernels") / "bin_pixels.cu"
THREADS = 256
PARAMS = 27
"""The kernel's double parameters (``kernels/bin_pixels.cu``'s P)."""
_MODULES: dict[str, tuple] = {}
_BUFFERS: dict[tuple, tuple] = {}


def _functions(dtype: np.dtype) -> tuple[cp.RawKernel, cp.RawKernel]:
    """The two kernels for ``dtype``'s depth, compiled once and looked up once."""
    name = "uint16" if dtype == np.uint16 else "float"
    if name not in _MODULES:
        options = ("-std=c++17",) + (("-DDEPTH_FLOAT",) if name == "float" else ())
        mod = cp.RawModule(code=KERNEL.read_text(), options=options)
        _MODULES[name] = (mod.get_function("bin_pixels"), mod.get_function("read_bins"))
    return _MODULES[name]


def _buffers(side: int, bins: int, h: int, w: int, dtype: np.dtype) -> tuple:
    """Device buffers and their page-locked host twins, reused from frame to frame (one
    allocation per window, bin count and image): none on the frame's path."""
    key = (side, bins, h, w, np.dtype(dtype).str)
    if key not in _BUFFERS:
        n = 2 * side * side
        # counts | valid, pad | hit, far (doubles). The pad keeps the doubles 8-byte aligned:
        # n is even, so they start at an even int32 offset (n + 1 gave misaligned writes).
        size = n + 2 + 6 * bins * 2
        _BUFFERS[key] = (
            cp.empty(size, cp.int32),
            cp.empty(bins, cp.uint64),
            cp.empty(bins, cp.uint64),
            cp.empty(PARAMS, cp.float64),
            cp.empty((h, w), dtype),
            cupyx.empty_pinned(size, np.int32),
            cupyx.empty_pinned(PARAMS, np.float64),
            cupyx.empty_pinned((h, w), dtype),
        )
    return _BUFFERS[key]


def launcher(depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
             floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
             cols_per_bin: int, stride: int,
             min_depth: float = MIN_DEPTH_M) -> Callable[[], tuple]:  # fmt: skip
    """Upload the frame and its parameters; returns the call that resets the outputs and
    runs the two kernels on them (what ``bin_frame_cuda`` then reads back). Apart, so the
    kernels' own time can be told from the call's (``scripts/mapper_bench.py --split``)."""
    if stride != 1:
        depth = depth[::stride, ::stride]
        intr = intr.scaled(1.0 / stride)
    if depth.dtype == np.float64:
        depth = depth.astype(np.float32)
    h, w = depth.shape
    bins = (w + cols_per_bin - 1) // cols_per_bin
    out, hit_key, far_key, params, d, host, p, staged = _buffers(win.side, bins, h, w, depth.dtype)
    # The current stream (the profiler's events in ``mapper_bench.py --split`` are on it).
    stream = cp.cuda.get_current_stream()
    n = 2 * win.side * win.side
    # The last frame's copies are done (its read back waited on the stream): the page-locked
    # buffers are free to refill.
    p[:4] = (intr.fx, intr.fy, intr.cx, intr.cy)
    p[4:13] = np.asarray(rot, np.float64).ravel()
    p[13:16] = t
    p[16:24] = (floor_z, min_h, max_h, max_range, min_depth, win.cell_m, PUSH_M, scale)
    p[24:27] = bearing_bins(rot, intr, w, h)
    np.copyto(staged, depth)
    params.set(p, stream=stream)
    d.set(staged, stream=stream)
    bin_pixels, read_bins = _functions(depth.dtype)
    counts, valid = out[:n], out[n : n + 1]
    hit = out[n + 2 : n + 2 + 6 * bins].view(cp.float64)
    far = out[n + 2 + 6 * bins :].view(cp.float64)
    grid = ((h * w + THREADS - 1) // THREADS,)

    def launch() -> tuple[cp.ndarray, int, int, np.ndarray, cp.cuda.Stream]:
        out.data.memset_async(0, 4 * (n + 1), stream)
        hit_key.data.memset_async(0xFF, hit_key.nbytes, stream)  # every key at uint64's max
        far_key.data.memset_async(0, far_key.nbytes, stream)
        bin_pixels(
            grid, (THREADS,),
            (d, np.int32(h), np.int32(w), params, np.int32(win.r0), np.int32(win.c0),
             np.int32(win.side), np.int32(win.map_rows), np.int32(bins), counts,
             hit_key, far_key, valid), stream=stream,
        )  # fmt: skip
        read_bins(
            ((bins + 63) // 64,), (64,),
            (d, np.int32(w), params, np.int32(bins), hit_key, far_key, hit, far),
            stream=stream,
        )  # fmt: skip
        return out, n, bins, host, stream

    return launch


def bin_frame_cuda(depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
                   floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
                   cols_per_bin: int, stride: int,
                   min_depth: float = MIN_DEPTH_M) -> Binned:  # fmt: skip
    launch = launcher(depth, scale, intr, rot, t, floor_z, win, min_h, max_h, max_range,
                      cols_per_bin, stride, min_depth)  # fmt: skip
    out, n, bins, host, stream = launch()
    out.get(stream=stream, out=host)  # the one copy back, into page-locked memory
    stream.synchronize()  # the frame's one wait on the device
    return Binned(
        host[:n].reshape(2, win.side, win.side).copy(),
        host[n + 2 : n + 2 + 6 * bins].view(np.float64).reshape(bins, 3).copy(),
        host[n + 2 + 6 * bins :].view(np.float64).reshape(bins, 3).copy(),
        int(host[n]),
    )
