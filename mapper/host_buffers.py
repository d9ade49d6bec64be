"""A frame source's own depth buffers, page-locked once so the device reads frames from them.

A camera SDK hands each frame in its own memory and recycles a few buffers (a frame pool).
Copying each 640 × 480 frame into the mapper's page-locked upload buffer cost 134 µs of a
paced frame's host time on the H100's host; registering the pool once with the driver
(``cudaHostRegister``) lets the upload's DMA read the frame where it lies instead: each
pass captures its frame's graph once per registered buffer (``FramePass.read_from``).

Finding out whether a frame lies in registered memory must itself be cheap: a cold
``ndarray.__array_interface__`` or ``ndarray.ctypes.data`` (the array's address) took 82 and
60 µs of CPU on the dev VM between paced frames. So the very arrays registered are known by
identity (they are held here, so their ids are not reused while registered), and only
another array, a view a source made afresh, is looked up by its address.
"""

from __future__ import annotations

from collections.abc import Sequence

import cupy as cp
import numpy as np


class HostBuffers:
    """Registered buffers: each array held until ``clear``, by id and by address."""

    def __init__(self) -> None:
        self._by_id: dict[int, tuple[np.ndarray, int]] = {}
        self._bytes: dict[int, int] = {}
        """Start address -> bytes registered there."""

    def register(self, arrays: Sequence[np.ndarray]) -> None:
        """Page-lock each array's memory (C-ordered, and allocated until ``clear``).
        Registering takes milliseconds: once, at start-up, never per frame."""
        for a in arrays:
            if not a.flags.c_contiguous:
                raise ValueError("a registered depth buffer must be C-ordered")
            at = a.__array_interface__["data"][0]
            if at not in self._bytes:
                cp.cuda.runtime.hostRegister(at, a.nbytes, 0)  # cudaHostRegisterDefault
                self._bytes[at] = a.nbytes
            self._by_id[id(a)] = (a, at)

    def address(self, depth: np.ndarray, nbytes: int) -> int:
        """Where ``depth`` starts, if ``nbytes`` from there are registered; else 0."""
        hit = self._by_id.get(id(depth))
        if hit is not None and hit[0] is depth:
            at = hit[1]
        elif self._bytes:
            at = depth.__array_interface__["data"][0]
        else:
            return 0
        return at if self._bytes.get(at, 0) >= nbytes else 0

    def covering(self, nbytes: int) -> list[int]:
        """The registered addresses with at least ``nbytes`` there."""
        return [at for at, size in self._bytes.items() if size >= nbytes]

    def __len__(self) -> int:
        return len(self._bytes)

    def clear(self) -> None:
        """Unregister everything (no upload may still be reading any of it)."""
        for at in self._bytes:
            cp.cuda.runtime.hostUnregister(at)
        self._bytes.clear()
        self._by_id.clear()
