"""How a ``fast`` call reaches the device (``CudaPlanner`` mixes this in).

Every fast call is posted to the resident loop (``resident.py``): the params words and the raw
delta go into the mapped mailbox, the post last; the loop checks and applies the delta, repairs
or recomputes the field, extracts the path when asked, writes its result words into the mapped
io buffer and sets the done word, which the host polls. The host reads the result words
(``RESULT_WORDS``) in one unpack.
"""

from __future__ import annotations

import struct
import weakref

import cupy as cp
import numpy as np

from . import abi, device, resident

# Compiled once: struct's module functions parse the format string at every call, and these
# run at every step.
PARAMS_WORDS = struct.Struct("5i")
_ORDER = (abi.PARAM_NDELTA, abi.PARAM_MODE, abi.PARAM_START, abi.PARAM_GOAL, abi.PARAM_SEQ)
assert tuple(range(5)) == _ORDER, "the order _stage_fast packs the words in"
FOCUS_WORD = struct.Struct("i")
"""PARAM_FOCUS, after the mailbox's words (which the post writes, last)."""
RESULT_WORDS = struct.Struct(
    f"<{abi.CTRL_READ}I{4 * (abi.IO_REJECT - abi.CTRL_READ)}x"
    f"I{4 * (abi.IO_PATH - abi.IO_REJECT - 1)}x2i"
)
"""What a finished call left before its path, in one read: the ctrl words it copies back (the
statistics), the rejection bits of its delta, the path's count and status. One unpack after
the done word instead of three reads: right after the walk's other work, each read of the
mapped buffer from Python costs 1-3 µs."""
R_REJECT, R_COUNT, R_STATUS = abi.CTRL_READ, abi.CTRL_READ + 1, abi.CTRL_READ + 2


class FastCall:
    """The fast call over ``CudaPlanner``'s buffers (see ``CudaPlanner._allocate``)."""

    _shape: tuple[int, int]
    _goal: tuple[int, int]
    _seq: int
    _stage: device.Pinned
    _stage_views: tuple[np.ndarray, ...]
    _io_host: device.Pinned
    _params: cp.ndarray
    _g: cp.ndarray
    _blocked_d: cp.ndarray
    _raised: cp.ndarray
    _flags: cp.ndarray
    _ctrl: cp.ndarray
    _exits: cp.ndarray
    _segs: cp.ndarray
    _path_cap: int
    _result: tuple[int, ...]
    _loop: resident.Slot | None
    sweeps: int
    raised_cells: int
    cut_cells: int
    cut_over: int
    _unsettled: bool
    tiles: int
    exit_tiles: int

    def _call_fast(
        self,
        eds: bool,
        cells: np.ndarray | None,
        blocked: np.ndarray | None,
        start: int = -1,
        again: bool = False,
        focus: int = -1,
    ) -> None:
        """One fast call (lock held), the delta ``cells`` / ``blocked`` (none: ``cells`` is
        None), the path from the flat cell ``start`` if >= 0; the result words end in
        ``_result``; ``focus`` >= 0 (a flat cell, EDS): the repair is focused on it and may
        defer tiles (fast.cu). Every step of a walk runs this, so it does its staging itself
        and handles its rare cases at the end (a cold Python call or numpy access costs ~1 µs
        right after the walk's other work). The loop checks the delta: a cell outside the map is an
        IndexError (nothing applied); cells out of order (a cell twice, say) are sorted here,
        each keeping its last value, and posted ``again``."""
        seq, n = self._stage_fast(eds, cells, blocked, start, focus)
        loop = self._loop
        assert loop is not None
        loop.post(seq, n)
        loop.wait(self._io_host.view, seq)
        self._finish_fast(eds, cells, blocked, start, again, focus)

    def _stage_fast(
        self,
        eds: bool,
        cells: np.ndarray | None,
        blocked: np.ndarray | None,
        start: int = -1,
        focus: int = -1,
    ) -> tuple[int, int]:
        """A fast call's params and delta into this planner's mailbox, the slot made if it has
        none; the call's seq and delta length, for a post (``_call_fast``, or a batch's:
        ``batch.py``)."""
        n = 0
        if cells is not None:
            # Cells as int64, then a byte per cell (resident.cuh, take_delta): two numpy
            # copies, which cast and broadcast as needed.
            cells = cells if isinstance(cells, np.ndarray) else np.asarray(cells)
            if cells.ndim != 1:
                cells = cells.ravel()
            n = cells.size
            # 8 + 1 bytes a cell after the params, in whole 16-byte chunks (the loop reads the
            # stage in chunks).
            words = abi.PARAMS + 4 * ((9 * n + 15) // 16)
            if words > self._stage.count or abi.PARAMS + n > self._params.size:
                self._grow_stage(words, n)
            if self._stage_views[0] is not self._stage.array:  # views of the stage as it is now
                stage = self._stage.array
                self._stage_views = (stage, stage.view(np.int64), stage.view(np.uint8))
            _, as_int64, as_bytes = self._stage_views
            as_int64[abi.PARAMS // 2 : abi.PARAMS // 2 + n] = cells
            at = 4 * abi.PARAMS + 8 * n
            as_bytes[at : at + n] = blocked
        if self._loop is None:  # after staging: a stage that had to grow stopped the loop
            self._loop = self._new_loop()
        if focus >= 0 and eds:
            self._unsettled = True
        # The params words for the call's new seq (written out here: every step stages).
        self._seq = seq = self._seq % 0x7FFFFFFF + 1
        goal = self._goal[0] * self._shape[1] + self._goal[1]
        view = self._stage.view
        PARAMS_WORDS.pack_into(view, 0, n, abi.MODE_EDS if eds else abi.MODE_DSS, start, goal, seq)
        FOCUS_WORD.pack_into(view, 4 * abi.PARAM_FOCUS, focus)
        return seq, n

    def _finish_fast(
        self,
        eds: bool,
        cells: np.ndarray | None,
        blocked: np.ndarray | None,
        start: int,
        again: bool,
        focus: int,
    ) -> None:
        """After the done word: the result words into ``_result``; a refused delta raised, or
        sorted and called again."""
        self._result = result = RESULT_WORDS.unpack_from(self._io_host.view)
        reject = result[R_REJECT]
        if not reject:
            return
        if reject & abi.REJECT_RANGE:
            h, w = self._shape
            raise IndexError(f"a cell index is outside the map of {h * w} cells")
        if again or cells is None or blocked is None:
            raise RuntimeError("the resident loop refused a sorted delta")
        cells, blocked = device.unique_last(cells, blocked)
        self._call_fast(eds, cells, blocked, start, again=True, focus=focus)

    def _read_fast_stats(self) -> tuple[int, int]:
        st = self._result
        self.sweeps, self.raised_cells = st[abi.C_SWEEPS], st[abi.C_RAISED]
        self.tiles, self.exit_tiles = st[abi.C_TILES], st[abi.C_EXITS]
        self.cut_cells = st[abi.C_CUT]
        return st[abi.C_ROUNDS], self.raised_cells + st[abi.C_CHANGED]

    def _new_loop(self) -> resident.Slot:
        """This planner's slot in the device's loop, over its buffers as they are now."""
        h, w = self._shape
        words = [0] * abi.SLOT_WORDS
        for at, array in (
            (abi.SLOT_G, self._g), (abi.SLOT_BLOCKED, self._blocked_d),
            (abi.SLOT_RAISED, self._raised), (abi.SLOT_PARAMS, self._params),
            (abi.SLOT_FLAGS, self._flags), (abi.SLOT_CTRL, self._ctrl),
            (abi.SLOT_EXITS, self._exits), (abi.SLOT_SEGS, self._segs),
        ):  # fmt: skip
            words[at] = array.data.ptr
        words[abi.SLOT_IO], words[abi.SLOT_MAIL] = self._io_host.device_ptr, self._stage.device_ptr
        words[abi.SLOT_H], words[abi.SLOT_W] = h, w
        words[abi.SLOT_CAP], words[abi.SLOT_LIMIT] = self._path_cap, self.cut_over
        # The slot keeps every buffer its words point to (a Pinned that grows lets go of its own
        # memory), so none is freed or reused while the loop may still read it.
        keep = (self._g, self._blocked_d, self._raised, self._params, self._flags, self._ctrl,
                self._exits, self._segs, self._io_host.memory, self._stage.memory)  # fmt: skip
        slot = resident.shared().attach(tuple(words), keep)
        weakref.finalize(self, slot.stop)
        return slot
