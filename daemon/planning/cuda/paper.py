"""The ``paper`` variant of the cuda backend: Díaz-Toro et al.'s Figure 4 form, for comparison.

Read-only and write-only maps for g, pred and incon (``kernels/paper.cu``), one
``kernel_planner`` launch per iteration and ``flag_stop`` read back after each, so the form is
launch-bound by construction: it is here to be compared with, not to guide a user. EDS
raises the whole subtree of the stored pred map of each newly blocked cell (the paper's rule,
a superset of the cells whose cost must rise); the fixpoint is the same exact field as every
other backend's.

``PaperForm`` holds the state and the launches; ``CudaPlanner`` mixes it in and owns the
shared parts (the map, g, the delta upload, the path). Terms are the paper's: ``g``, ``pred``,
``incon``, the read-only (``_r``, here the plain name) and write-only (``_w``) maps,
``kernel_planner``, ``flag_stop``.
"""

from __future__ import annotations

import cupy as cp
import numpy as np

from ..grid import INF
from . import abi, device, resident

PAPER_THREADS = 256


class PaperForm:
    """The paper's per-iteration form over ``CudaPlanner``'s ``_g``, ``_blocked_d`` and the
    delta staged in ``_stage`` (pinned) for ``_params`` (on the device; ``_delta`` views it)."""

    _shape: tuple[int, int]
    _goal: tuple[int, int]
    _g: cp.ndarray
    _blocked_d: cp.ndarray
    _delta: cp.ndarray
    _params: cp.ndarray
    _stage: device.Pinned
    _slot: int

    def _allocate_paper(self, n: int) -> None:
        self._g_w = cp.full(n, INF, dtype=np.int32)
        self._pred = cp.full(n, -1, dtype=np.int8)
        self._pred_w = cp.full(n, -1, dtype=np.int8)
        self._incon = cp.zeros(n, dtype=np.uint8)
        self._incon_w = cp.zeros(n, dtype=np.uint8)
        self._raised = cp.zeros(n, dtype=np.uint8)
        self._raised_w = cp.zeros(n, dtype=np.uint8)
        # flag_stop of the two slots, then a 64-bit count of the cells relaxed so far
        self._flag = cp.zeros(4, dtype=np.int32)
        self._flag_host = device.Pinned(4, np.int32)
        self._flag_host.array[:] = 0

    def _launch_paper(self, name: str, args: tuple, n: int) -> None:
        k = device.kernel("paper", name)
        k((-(-n // PAPER_THREADS),), (PAPER_THREADS,), args)

    def _flag_after(self, name: str, args: tuple) -> bool:
        """Launch one iteration and read its flag_stop back (the paper's per-iteration sync)."""
        h, w = self._shape
        self._launch_paper(name, (*args, self._flag, np.int32(self._slot)), h * w)
        self._flag_host.from_device(self._flag, 4)
        device.synchronize()
        changed = bool(self._flag_host.array[self._slot])
        self._slot ^= 1
        return changed

    def _run_paper(self, eds: bool, n_delta: int) -> tuple[int, int]:
        resident.evict()  # a resident loop holds the SMs these launches need
        h, w = self._shape
        n = h * w
        goal = np.int32(self._goal[0] * w + self._goal[1])
        hw = (np.int32(h), np.int32(w))
        if n_delta:
            self._stage.to_device(self._params, n_delta, offset=abi.PARAMS)
            self._launch_paper(
                "paper_apply",
                (self._delta, np.int32(n_delta), self._blocked_d, self._raised, self._raised_w,
                 self._incon, np.int32(1 if eds else 0)),
                n_delta,
            )  # fmt: skip
        relaxed_before = int(self._flag_host.array[2:4].view(np.uint64)[0])
        iterations = 0
        if not eds:
            self._launch_paper(
                "paper_init",
                (self._g, self._pred, self._incon, self._incon_w, self._raised, self._raised_w,
                 self._blocked_d, *hw, goal, self._flag),
                n,
            )  # fmt: skip
            self._slot = 0
        else:
            while True:  # raise the pred-tree descendants of newly blocked cells
                iterations += 1
                changed = self._flag_after(
                    "kernel_raise", (self._pred, self._raised, self._raised_w, *hw)
                )
                self._raised, self._raised_w = self._raised_w, self._raised
                if not changed:
                    break
            self._launch_paper(
                "paper_reset",
                (self._g, self._pred, self._raised, self._raised_w, self._incon, self._blocked_d,
                 np.int32(n)),
                n,
            )  # fmt: skip
        while True:
            iterations += 1
            changed = self._flag_after(
                "kernel_planner",
                (self._g, self._g_w, self._pred, self._pred_w, self._incon, self._incon_w,
                 self._blocked_d, *hw, goal),
            )  # fmt: skip
            self._g, self._g_w = self._g_w, self._g
            self._pred, self._pred_w = self._pred_w, self._pred
            self._incon, self._incon_w = self._incon_w, self._incon
            if not changed:
                break
        relaxed = int(self._flag_host.array[2:4].view(np.uint64)[0]) - relaxed_before
        return iterations, relaxed
