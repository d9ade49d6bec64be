"""The per-pixel pass of ``binning.py`` on the GPU: same arguments, same result.

One CUDA kernel (``kernels/bin_pixels.cu``, built with CuPy's ``RawModule``) back-projects
every pixel, moves it into the world, tests its height and counts it in its cell with
``atomicAdd``; the nearest obstacle point and the farthest free point of each bearing bin
are 64-bit ``atomicMin``/``atomicMax`` of (squared range, pixel index) keys, and a second,
tiny kernel reads back the winning points.

A frame's whole device work is one CUDA graph, captured once per image size, window and
bin count (``CudaBinner``): the frame's parameters and depth go up in one copy from one
page-locked host buffer, the outputs are reset, the two kernels run, and the window's counts
and the per-bin points (a few tens of kB, all the merge reads) come back into a page-locked
buffer. The kernel also counts the pixels the frame check counts (``frame.count_valid``, a
70 µs pass over the image on the H100's host) and works out the bearing bins' yaw and span
from the uploaded pose (``binning.bearing_bins``, 12-25 µs of numpy there), so neither is
host work on the frame's path any more. Per frame the host fills the upload buffer (one
numpy call for the parameters, one copy of the depth), launches the graph and waits once: one
launch and one wait instead of the eight calls through CuPy (three memsets, two uploads,
two launches, a read-back, each with its Python wrapping) that were most of the pass's
0.25 ms on the host, and whose tail (p99 1.16 ms in an H100 call) was the frame's.
Everything that varies from frame to frame, the window's corner included, is in the
uploaded parameters, so the captured graph stays valid. The mapper's passes also merge the
frame into the map kept on the device (``cuda_merge``): their read-back is then only the
changed cells and the proximity's figures, not the window's counts.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cupy as cp
import cupyx
import numpy as np

from .binning import MIN_DEPTH_M, PUSH_M, TAN_LIMIT, Binned, Window
from .cuda_merge import DeviceMap, MergeTail
from .frame import count_valid
from .merge import HOST_PRESENT

KERNEL = Path(__file__).with_name("kernels") / "bin_pixels.cu"
THREADS = 256
PARAMS = 27
"""The kernel's double parameters (``kernels/bin_pixels.cu``'s P); the merge's follow them
(``kernels/merge_cells.cu``, ``cuda_merge.merge_params``)."""
HEAD = 512
"""Bytes the parameters take ahead of the depth in the one upload (keeps the depth aligned)."""
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
                 dtype: np.dtype, dmap: DeviceMap | None = None) -> None:  # fmt: skip
        n = 2 * side * side
        # counts | valid, present | hit, far (doubles). n is even, so the doubles start at
        # an even int32 offset: 8-byte aligned.
        size = n + 2 + 6 * bins * 2
        depth_bytes = h * w * np.dtype(dtype).itemsize
        out = cp.empty(size, cp.int32)
        hit_key, far_key = cp.empty(bins, cp.uint64), cp.empty(bins, cp.uint64)
        up = cp.empty(HEAD + depth_bytes, cp.uint8)  # parameters, then the depth: one copy
        params, depth = up[:HEAD].view(cp.float64), up[HEAD:].view(dtype).reshape(h, w)
        self.host = cupyx.empty_pinned(size, np.int32)
        self.up = cupyx.empty_pinned(HEAD + depth_bytes, np.uint8)
        self.params = self.up[:HEAD].view(np.float64)
        self.depth = self.up[HEAD:].view(dtype).reshape(h, w)
        # The merge's views of the read-back, made once, and the one Binned that holds them
        # (valid until this pass's next frame: the mapper merges it at once).
        hit = self.host[n + 2 : n + 2 + 6 * bins].view(np.float64).reshape(bins, 3)
        far = self.host[n + 2 + 6 * bins :].view(np.float64).reshape(bins, 3)
        self.binned = Binned(self.host[:n].reshape(2, side, side), hit, far, 0, 0)
        self.n = n
        self.stream = cp.cuda.Stream(non_blocking=True)  # capture needs a stream of its own
        bin_pixels, read_bins = _functions(np.dtype(dtype))  # loaded before the capture
        s, rt = self.stream, cp.cuda.runtime

        def resets() -> None:
            rt.memsetAsync(out.data.ptr, 0, 4 * (n + 2), s.ptr)
            rt.memsetAsync(hit_key.data.ptr, 0xFF, hit_key.nbytes, s.ptr)  # keys at uint64's max
            rt.memsetAsync(far_key.data.ptr, 0, far_key.nbytes, s.ptr)

        if dmap is not None:  # the merge resets them after each frame: once here, for the first
            resets()
            s.synchronize()
        # The copies and resets through the runtime itself: CuPy's own copy methods refuse
        # any host transfer while a stream captures (they cannot tell page-locked memory).
        s.begin_capture()
        try:
            rt.memcpyAsync(up.data.ptr, self.up.ctypes.data, up.nbytes, rt.memcpyHostToDevice,
                           s.ptr)  # fmt: skip
            if dmap is None:
                resets()
            bin_pixels(
                ((h * w + THREADS - 1) // THREADS,), (THREADS,),
                (depth, np.int32(h), np.int32(w), params, np.int32(side),
                 np.int32(map_rows), np.int32(bins), out[:n], hit_key, far_key,
                 out[n : n + 1], out[n + 1 : n + 2]), stream=s,
            )  # fmt: skip
            read_bins(
                ((bins + 63) // 64,), (64,),
                (depth, np.int32(w), params, np.int32(bins), hit_key, far_key,
                 out[n + 2 : n + 2 + 6 * bins].view(cp.float64),
                 out[n + 2 + 6 * bins :].view(cp.float64)), stream=s,
            )  # fmt: skip
            if dmap is None:
                rt.memcpyAsync(self.host.ctypes.data, out.data.ptr, out.nbytes,
                               rt.memcpyDeviceToHost, s.ptr)  # fmt: skip
            else:  # the merge runs here too: only its changed cells come back
                self.merge = MergeTail(side, dmap)
                self.merge.capture(s, out, params, bins, hit_key, far_key)
        finally:
            self.graph = s.end_capture()
        self._device = (out, hit_key, far_key, up)  # alive as long as the graph

    def stage(self, depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
              floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
              min_depth: float, merge: Sequence[float] = ()) -> None:  # fmt: skip
        """The frame's parameters and depth into the page-locked upload buffer (the last
        frame's graph has finished with it: its read-back was waited for). One numpy call
        for the parameters (``merge``: the merge's, ``cuda_merge.merge_params``); the depth
        is cast on the way in where it is float64, and not copied at all where it is this
        buffer itself (``CudaBinner.depth_buffer``: its producer wrote it there)."""
        self.params[: PARAMS + len(merge)] = [
            intr.fx, intr.fy, intr.cx, intr.cy, *rot.ravel().tolist(), *t.ravel().tolist(),
            floor_z, min_h, max_h, max_range, min_depth, win.cell_m, PUSH_M, scale,
            win.r0, win.c0, TAN_LIMIT, *merge,
        ]  # fmt: skip
        if depth is not self.depth:
            np.copyto(self.depth, depth, casting="same_kind")

    def launch(self) -> None:
        self.graph.launch(self.stream)

    def wait(self) -> None:
        self.stream.synchronize()  # the frame's one wait on the device

    def read(self) -> Binned:
        self.wait()
        b = self.binned
        b.valid, b.present = int(self.host[self.n]), int(self.host[self.n + 1])
        return b


class CudaBinner:
    """``bin_frame_cpu``'s call on the GPU; each instance (one per mapper) owns its passes,
    so two mappers never share buffers. It also counts the pixels the frame check counts
    (``Binned.present``), so that count is no pass over the image on the host."""

    def __init__(self) -> None:
        self._passes: dict[tuple, FramePass] = {}
        self._maps: dict[tuple[int, int], DeviceMap] = {}

    def prepare(self, depth: np.ndarray, scale: float, intr, rot: np.ndarray, t: np.ndarray,
                floor_z: float, win: Window, min_h: float, max_h: float, max_range: float,
                cols_per_bin: int, stride: int,
                min_depth: float = MIN_DEPTH_M, dmap: DeviceMap | None = None,
                merge: Sequence[float] = ()) -> FramePass:  # fmt: skip
        """The frame's pass with the frame staged, ready to launch (apart from the call, so
        the bench can time the graph alone: ``scripts/mapper_bench.py --split``); with
        ``dmap``, the pass that also merges into it (``merge``: its parameters)."""
        if stride != 1:
            depth = depth[::stride, ::stride]
            intr = intr.scaled(1.0 / stride)
        h, w = depth.shape
        bins = (w + cols_per_bin - 1) // cols_per_bin
        dtype = np.dtype(np.float32) if depth.dtype == np.float64 else depth.dtype
        fp = self._pass(win.side, bins, h, w, win.map_rows, dtype, dmap)
        fp.stage(depth, scale, intr, rot, t, floor_z, win, min_h, max_h, max_range, min_depth,
                 merge)  # fmt: skip
        return fp

    def _pass(self, side: int, bins: int, h: int, w: int, map_rows: int, dtype: np.dtype,
              dmap: DeviceMap | None) -> FramePass:  # fmt: skip
        key = (side, bins, h, w, map_rows, dtype, dmap and dmap.shape)
        fp = self._passes.get(key)
        if fp is None:
            fp = self._passes[key] = FramePass(side, bins, h, w, map_rows, dtype, dmap)
        return fp

    def _map(self, shape: tuple[int, int]) -> DeviceMap:
        dmap = self._maps.get(shape)
        if dmap is None:
            dmap = self._maps[shape] = DeviceMap(shape)
        return dmap

    def depth_buffer(self, map_shape: tuple[int, int], side: int, bins: int, h: int, w: int,
                     dtype: np.dtype) -> np.ndarray:  # fmt: skip
        """The page-locked array the merging pass for this map, window and image uploads
        its depth from. A frame whose depth is this very array is not copied on its path:
        its producer wrote it there. It may be written only between frames (``merge``
        returns once the upload is done) and holds one frame at a time."""
        return self._pass(side, bins, h, w, map_shape[0], np.dtype(dtype),
                          self._map(map_shape)).depth  # fmt: skip

    def merge(self, maps: tuple, merge: list[float], *args) -> tuple:
        """The frame binned and merged into the map kept on the device (``cuda_merge``):
        ``maps`` the mapper's host occupancy, log-odds, seen-at and fixed cells (uploaded
        when they are not the ones the device holds), ``merge`` the merge's parameters
        (``merge.merge_params``), ``args`` the pass's. One launch and one wait; returns
        ``MergeTail.result``."""
        dmap = self._map(maps[0].shape)
        dmap.attach(*maps)
        depth, stride = args[0], args[11]
        if stride != 1 or depth.dtype == np.float64:
            # The device sees a subsampled or float32 copy: the check counts the original.
            merge = list(merge)
            merge[HOST_PRESENT] = float(count_valid(depth))
        fp = self.prepare(*args, dmap=dmap, merge=merge)
        fp.launch()
        fp.wait()
        return fp.merge.result()

    def pull(self, logodds: np.ndarray, seen_at: np.ndarray) -> None:
        """The device map's log-odds and seen-at into the mapper's host arrays."""
        self._maps[logodds.shape].pull(logodds, seen_at)

    def __call__(self, *args) -> Binned:
        """The frame binned; its arrays are this binner's page-locked read-back, valid until
        its next call."""
        fp = self.prepare(*args)
        fp.launch()
        b = fp.read()
        depth, stride = args[0], args[11]
        if stride != 1 or depth.dtype == np.float64:
            # The device saw a subsampled or float32 copy: the check's count is the original's.
            b.present = count_valid(depth)
        return b
