"""How the cuda backend's path comes back to the host (``CudaPlanner`` mixes this in).

The ``fast`` call writes the path into the mapped I/O buffer itself; otherwise (the ``paper``
variant) a launch of the path kernel (``path_tiles.cu``) writes it on the device and it is
copied back. A path longer than the buffer
comes in chunks, each continued by a launch of the path kernel from the chunk's last cell.
"""

from __future__ import annotations

import struct

import cupy as cp
import numpy as np

from ..grid import Cell
from . import abi, device, resident
from .call import R_COUNT, R_STATUS

PATH_HEAD = struct.Struct("2i")  # the path's cell count and status (compiled once)


class PathReader:
    """The path's read-back over ``CudaPlanner``'s buffers (see ``CudaPlanner._allocate``)."""

    _shape: tuple[int, int]
    _io_host: device.Pinned
    _io: cp.ndarray
    _g: cp.ndarray
    _exits: cp.ndarray
    _segs: cp.ndarray
    _path_d: cp.ndarray
    _path_ctrl: cp.ndarray
    _path_cap: int
    _path_guess: int
    _result: tuple[int, ...]
    _pairs: tuple[np.ndarray, np.ndarray]
    _path_blocks: int
    _path_bar: int

    def _path_locked(self, start: Cell, fused: bool = False) -> np.ndarray:
        """The path from ``start`` (lock held): with ``fused``, the one the fast call just
        wrote into the mapped I/O buffer; else from a launch of the path kernel, copied back.
        Paths longer than the buffer come in chunks, each continued by the path kernel."""
        host, at = self._io_host, abi.IO_PATH
        words = host.array
        if fused:  # the common case first: one chunk, complete, already in host memory
            # The fast call's result words, read with the statistics once it was done.
            count, status = self._result[R_COUNT], self._result[R_STATUS]
            if status == abi.PATH_DONE:
                if self._pairs[0] is not words:  # the path words as (row, column) pairs
                    end = words.size - words.size % 2
                    self._pairs = (words, words[at + 2 : end].reshape(-1, 2))
                return self._pairs[1][:count].copy()
        w = self._shape[1]
        chunks: list[np.ndarray] = []
        cur = start[0] * w + start[1]
        copied = self._path_cap if fused else None
        while True:
            if copied is None:
                self._launch_path(cur)
                copied = min(self._path_guess, self._path_cap)
                host.from_device(self._io, 2 + 2 * copied, offset=at)
                device.synchronize()
            count, status = PATH_HEAD.unpack_from(words, 4 * at)
            if count > copied:
                host.from_device(self._io, 2 * (count - copied), offset=at + 2 + 2 * copied)
                device.synchronize()
            self._path_guess = max(256, 2 * count)
            # The kernels write (row, column) pairs: the path as the caller gets it.
            cells = words[at + 2 : at + 2 + 2 * count].reshape(count, 2)
            if status != abi.PATH_MORE:  # the last chunk, copied out below
                chunks.append(cells if not chunks else cells[1:])
                break
            chunks.append(cells.copy() if not chunks else cells[1:].copy())
            cur, copied = int(cells[-1, 0]) * w + int(cells[-1, 1]), None
        if status == abi.PATH_NONE:
            return np.empty((0, 2), dtype=np.int32)
        if status == abi.PATH_BROKEN:
            raise RuntimeError(f"g is not a consistent cost field on the way from {start}")
        return chunks[0].copy() if len(chunks) == 1 else np.concatenate(chunks)

    def _launch_path(self, cur: int) -> None:
        resident.evict()  # its grid barrier needs SMs a resident loop holds
        h, w = self._shape
        hw, start, cap = (np.int32(h), np.int32(w)), np.int32(cur), np.int32(self._path_cap)
        device.kernel("path_tiles", "path_tiles")(
            (self._path_blocks,), (128,),
            (self._g, *hw, start, self._exits, self._segs, self._path_d, cap, self._path_ctrl,
             np.uint32(self._path_bar)),
        )  # fmt: skip
        self._path_bar = (self._path_bar + 2 * self._path_blocks) % 2**32
