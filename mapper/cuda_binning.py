"""The per-pixel pass of ``binning.py`` on the GPU: same arguments, same result.

One CUDA kernel (``kernels/bin_pixels.cu``, built with CuPy's ``RawModule``) back-projects
every pixel, moves it into the world, tests its height and counts it in its cell with
``atomicAdd``; the nearest obstacle point and the farthest free point of each bearing bin
are 64-bit ``atomicMin``/``atomicMax`` of (squared range, pixel index) keys, and a second,
tiny kernel reads back the winning points.

A frame's whole device work is one CUDA graph, captured once per image size, window and
bin count (``CudaBinner``): the frame's parameters and depth go up from page-locked host
buffers, the outputs are reset, the two kernels run, and the window's counts and the
per-bin points (a few tens of kB, all the merge reads) come back into a page-locked buffer.
Per frame the host fills the two upload buffers, launches the graph and waits once: one
launch and one wait instead of the eight calls through CuPy (three memsets, two uploads,
two launches, a read-back, each with its Python wrapping) that were most of the pass's
0.25 ms on the host, and whose tail (p99 1.16 ms in an H100 call) was the frame's.
Everything that varies from frame to frame, the window's corner included, is in the
uploaded parameters, so the captured graph stays valid.
"""

from __future__ import annotations

from pathlib import Path

import cupy as cp
import cupyx
import numpy as np

from .binning import MIN_DEPTH_M, PUSH_M, Binned, Window, bearing_bins

KERNEL = Path(__file__).with_name("kernels") / "bin_pixels.cu"
THREADS = 256
PARAMS = 29
"""The kernel's double parameters (``kernels/bin_pixels.cu``'s P)."""
_MODULES: dict[str, tuple] = {}


def _functions(dtype: np.dtype) -> tuple[cp.RawKernel, cp.RawKernel]:
    """The two kernels for ``dtype``'s depth, compiled once and looked up once."""
    name = "uint16" if dtype == np.uint16 else "float"
    if name not in _MODULES:
        options = ("-std=c++17",) + (("-DDEPTH_FLOAT",) if name == "float" else ())
        mod = cp.RawModule(code=KERNEL.read_text(), options=options)
        _MODULES[name] = (mod.get_function("bin_pixels"), mod.get_function("read_bins"))
    return _MODULES[name]


class FramePass:
    """One image size, window side, map height and bin count: the device buffers, their
    page-locked host twins, the pass's own stream and the frame's work captured on it."""

    def __init__(self, side: int, bins: int, h: int, w: int, map_rows: int,
                 dtype: np.dtype) -> None:  # fmt: skip
        n = 2 * side * side
        # counts | valid, pad | hit, far (doubles). The pad keeps the doubles 8-byte aligned:
        # n is even, so they start at an even int32 offset (n + 1 gave misaligned writes).
        size = n + 2 + 6 * bins * 2
        out = cp.empty(size, cp.int32)
        hit_key, far_key = cp.empty(bins, cp.uint64), cp.empty(bins, cp.uint64)
        params, depth = cp.empty(PARAMS, cp.float64), cp.empty((h, w), dtype)
        self.host = cupyx.empty_pinned(size, np.int32)
        self.params = cupyx.empty_pinned(PARAMS, np.float64)
        self.depth = cupyx.empty_pinned((h, w), dtype)
        # The merge's views of the read-back, made once: a frame's Binned holds these, so it
        # is valid until this pass's next frame (the mapper merges it at once).
        self.counts = self.host[:n].reshape(2, side, side)
        self.hit = self.host[n + 2 : n + 2 + 6 * bins].view(np.float64).reshape(bins, 3)
        self.far = self.host[n + 2 + 6 * bins :].view(np.float64).reshape(bins, 3)
        self.n = n
        self.stream = cp.cuda.Stream(non_blocking=True)  # capture needs a stream of its own
        bin_pixels, read_bins = _functions(np.dtype(dtype))  # loaded before the capture
        s, rt = self.stream, cp.cuda.runtime
        # The copies and resets through the runtime itself: CuPy's own copy methods refuse
        # any host transfer while a stream captures (they cannot tell page-locked memory).
        s.begin_capture()
        try:
            rt.memcpyAsync(params.data.ptr, self.params.ctypes.data, params.nbytes,
                           rt.memcpyHostToDevice, s.ptr)  # fmt: skip
            rt.memcpyAsync(depth.data.ptr, self.depth.ctypes.data, depth.nbytes,
                           rt.memcpyHostToDevice, s.ptr)  # fmt: skip
            rt.memsetAsync(out.data.ptr, 0, 4 * (n + 1), s.ptr)
            rt.memsetAsync(hit_key.data.ptr, 0xFF, hit_key.nbytes, s.ptr)  # keys at uint64's max
            rt.memsetAsync(far_key.data.ptr, 0, far_key.nbytes, s.ptr)
            bin_pixels(
                ((h * w + THREADS - 1) // THREADS,), (THREADS,),
                (depth, np.int32(h), np.int32(w), params, np.int32(side),
                 np.int32(map_rows), np.int32(bins), out[:n], hit_key, far_key,
                 out[n : n + 1]), stream=s,
            )  # fmt: skip
            read_bins(
                ((bins + 63) // 64,), (64,),
                (depth, np.int32(w), params, np.int32(bins), hit_key, far_key,
                 out[n + 2 : n + 2 + 6 * bins].view(cp.float64),
                 out[n + 2 + 6 * bins :].view(cp.float64)), stream=s,
            )  # fmt: skip
            rt.memcpyAsync(self.host.ctypes.data, out.data.ptr, out.nbytes,
                           rt.memcpyDeviceToHost, s.ptr)  # fmt: skip
        finally:
            self.graph = s.end_capture()
        self._device = (out, hit_key, far_key, params, depth)  # alive as long as the graph

    def stage(self, depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
              floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
              min_depth: float) -> None:  # fmt: skip
        """The frame's parameters and depth into the page-locked upload buffers (the last
        frame's graph has finished with them: its read-back was waited for)."""
        h, w = depth.shape
        p = self.params
        p[:4] = (intr.fx, intr.fy, intr.cx, intr.cy)
        p[4:13] = np.ravel(rot)
        p[13:16] = t
        p[16:24] = (floor_z, min_h, max_h, max_range, min_depth, win.cell_m, PUSH_M, scale)
        p[24:27] = bearing_bins(rot, intr, w, h)
        p[27:29] = (win.r0, win.c0)
        np.copyto(self.depth, depth)

    def launch(self) -> None:
        self.graph.launch(self.stream)

    def read(self) -> Binned:
        self.stream.synchronize()  # the frame's one wait on the device
        return Binned(self.counts, self.hit, self.far, int(self.host[self.n]))


class CudaBinner:
    """``bin_frame_cpu``'s call on the GPU; each instance (one per mapper) owns its passes,
    so two mappers never share buffers."""

    def __init__(self) -> None:
        self._passes: dict[tuple, FramePass] = {}

    def prepare(self, depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
                floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
                cols_per_bin: int, stride: int,
                min_depth: float = MIN_DEPTH_M) -> FramePass:  # fmt: skip
        """The frame's pass with the frame staged, ready to launch (apart from the call, so
        the bench can time the graph alone: ``scripts/mapper_bench.py --split``)."""
        if stride != 1:
            depth = depth[::stride, ::stride]
            intr = intr.scaled(1.0 / stride)
        if depth.dtype == np.float64:
            depth = depth.astype(np.float32)
        h, w = depth.shape
        bins = (w + cols_per_bin - 1) // cols_per_bin
        key = (win.side, bins, h, w, win.map_rows, depth.dtype.str)
        fp = self._passes.get(key)
        if fp is None:
            fp = self._passes[key] = FramePass(win.side, bins, h, w, win.map_rows, depth.dtype)
        fp.stage(depth, scale, intr, rot, t, floor_z, win, min_h, max_h, max_range, min_depth)
        return fp

    def __call__(self, *args) -> Binned:
        """The frame binned; its arrays are this binner's page-locked read-back, valid until
        its next call."""
        fp = self.prepare(*args)
        fp.launch()
        return fp.read()
