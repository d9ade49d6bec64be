"""A planner that keeps guiding when the GPU fails: cuda first, the CPU for the rest of the session.

``FallbackPlanner`` wraps a device planner and mirrors, on the host, the blocked map and goal
it was last given successfully. When a call raises a device error (cupy's CUDA runtime or
driver errors, an out-of-memory, or ``DeviceFault`` from a test hook), it logs a warning,
builds a CPU planner from the mirror, replays the failed call there and stays on the CPU.
The user keeps being guided; the session's status can report ``active_backend``.

``GUIDEBELT_CUDA_STRICT=1`` turns the fallback off for planners built with the default error
set, so GPU test runs (``scripts/gpu_check.sh``) see device errors instead of CPU results.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from .grid import Cell
from .interface import Planner, UpdateStats

log = logging.getLogger(__name__)


class DeviceFault(RuntimeError):
    """A device failure raised on purpose by tests (see ``CudaPlanner.inject_fault``)."""


def device_errors() -> tuple[type[BaseException], ...]:
    """The exception types that mean "the device failed", cupy's where cupy imports."""
    errors: list[type[BaseException]] = [DeviceFault]
    try:
        import cupy
    except Exception:  # no cupy: only the injected fault can occur
        return tuple(errors)
    errors += [cupy.cuda.runtime.CUDARuntimeError, cupy.cuda.driver.CUDADriverError]
    errors.append(cupy.cuda.memory.OutOfMemoryError)
    return tuple(errors)


def _cpu_planner() -> Planner:
    from .backends import make_planner

    return make_planner("cpu")


class FallbackPlanner(Planner):
    """``primary`` until it raises a device error, then a CPU planner from the host mirror."""

    def __init__(
        self,
        primary: Planner,
        cpu_factory: Callable[[], Planner] = _cpu_planner,
        errors: tuple[type[BaseException], ...] | None = None,
    ) -> None:
        self.primary = primary
        self._cpu_factory = cpu_factory
        if errors is None:
            strict = os.environ.get("GUIDEBELT_CUDA_STRICT") == "1"
            errors = () if strict else device_errors()
        self._errors = errors
        self._active: Planner = primary
        self._blocked: np.ndarray | None = None
        # Changes not yet written into the mirror: (cells, values) copies, applied in batches
        # (_flush) so that a step pays for two small copies, not a scatter into the map.
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []
        self._goal: Cell = (0, 0)
        self.fallback_reason: str | None = None
        # update_and_path's change, copied into _pending by _copy_change while the device
        # works when the primary has that hook (CudaPlanner.while_waiting).
        self._overlap = hasattr(primary, "while_waiting")
        self._change: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def name(self) -> str:  # type: ignore[override]
        return self._active.name

    @property
    def active_backend(self) -> str:
        """``cuda`` while the device planner runs, ``cpu`` after a fallback."""
        return "cuda" if self._active is self.primary else "cpu"

    @property
    def fell_back(self) -> bool:
        return self._active is not self.primary

    def _switch(self, exc: BaseException) -> None:
        self.fallback_reason = f"{type(exc).__name__}: {exc}"
        log.warning(
            "CUDA planner failed (%s); this session continues on the CPU", self.fallback_reason
        )
        cpu = self._cpu_factory()
        if self._blocked is not None:
            cpu.plan(self.mirrored_blocked(), self._goal)
        self._active = cpu

    def _call(self, method: str, *args: object, **kwargs: object) -> Any:
        if self._active is self.primary:
            try:
                return getattr(self.primary, method)(*args, **kwargs)
            except self._errors as exc:
                self._switch(exc)
        return getattr(self._active, method)(*args, **kwargs)

    # -- changes: mirrored on the host after they succeed ------------------------------------

    def plan(self, blocked: np.ndarray, goal: Cell) -> UpdateStats:
        stats = self._call("plan", blocked, goal)
        self._blocked = np.array(blocked, dtype=bool, copy=True)
        self._pending.clear()
        self._goal = (int(goal[0]), int(goal[1]))
        return stats

    def update(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        stats = self._call("update", cells, blocked)
        self._mirror(cells, blocked)
        return stats

    def replan(self, cells: np.ndarray, blocked: np.ndarray) -> UpdateStats:
        stats = self._call("replan", cells, blocked)
        self._mirror(cells, blocked)
        return stats

    def update_and_path(
        self, cells: np.ndarray, blocked: np.ndarray, start: Cell, *, full: bool = False
    ) -> tuple[UpdateStats, np.ndarray]:
        # Every step runs this, so the primary is called directly, not through _call (a cold
        # Python call costs ~1 µs after the caller's other work, a sizeable part of a 0.25 ms
        # step on the GPU; BENCHMARKS.md). The mirror's copy of the change is made while the
        # device works on it, when the primary offers that (CudaPlanner.while_waiting), and
        # taken out again if the step fails: the CPU planner is then built from the mirror as
        # it was before the step and replays the whole step (a failure part-way, the repair
        # done on the device and the path not, included).
        primary = self.primary
        if self._active is not primary:
            result = self._active.update_and_path(cells, blocked, start, full=full)
            self._mirror(cells, blocked)
            return result
        self._change = (cells, blocked)
        if self._overlap:
            primary.while_waiting = self._copy_change  # type: ignore[attr-defined]
        kept = len(self._pending)
        try:
            result = primary.update_and_path(cells, blocked, start, full=full)
        except self._errors as exc:
            del self._pending[kept:]  # the device did not apply the change: the CPU replays it
            self._switch(exc)
            result = self._active.update_and_path(cells, blocked, start, full=full)
        except BaseException:
            del self._pending[kept:]  # refused (a cell outside the map, say): not the mirror's
            raise
        finally:
            if self._overlap:
                primary.while_waiting = None  # type: ignore[attr-defined]
            self._change = None
        if len(self._pending) == kept:  # not copied while the device worked
            self._mirror(cells, blocked)
        elif len(self._pending) >= self.FLUSH_AT:
            self._flush()
        return result

    def _copy_change(self) -> None:
        """The primary's while_waiting hook during update_and_path: the change into the
        mirror's pending list (taken out again if the step fails)."""
        if self._change is not None and self._blocked is not None:
            self._pending.append(self._copies(*self._change))
            self._change = None

    FLUSH_AT = 64
    """Pending changes that trigger a flush into the mirror (bounds memory and flush time)."""

    @staticmethod
    def _copies(cells: np.ndarray, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The change as the mirror keeps it: copies, since the caller may reuse its arrays."""
        return np.array(cells, dtype=np.int64), np.array(blocked, dtype=bool)

    def _mirror(
        self,
        cells: np.ndarray,
        blocked: np.ndarray,
        copies: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        if self._blocked is None:
            return
        self._pending.append(copies if copies is not None else self._copies(cells, blocked))
        if len(self._pending) >= self.FLUSH_AT:
            self._flush()

    def _flush(self) -> None:
        """Write the pending changes into the mirror in one scatter, the latest value of each
        cell winning (as if applied one by one)."""
        if not self._pending or self._blocked is None:
            self._pending.clear()
            return
        cells = [c.ravel() for c, _ in self._pending]
        values = [
            np.broadcast_to(v.ravel(), c.shape)
            for c, (_, v) in zip(cells, self._pending, strict=True)
        ]
        self._pending.clear()
        flat_cells, flat_values = np.concatenate(cells), np.concatenate(values)
        # A scatter with repeated indices keeps no defined value: keep each cell's last one.
        last, at = np.unique(flat_cells[::-1], return_index=True)
        self._blocked.reshape(-1)[last] = flat_values[::-1][at]

    def mirrored_blocked(self) -> np.ndarray | None:
        """The host mirror of the blocked map, every successful change applied."""
        self._flush()
        return self._blocked

    # -- queries ---------------------------------------------------------------------------------

    def costs(self) -> np.ndarray:
        return self._call("costs")

    def blocked(self) -> np.ndarray:
        return self._call("blocked")

    def cost_at(self, cell: Cell) -> int:
        return self._call("cost_at", cell)

    def path(self, start: Cell) -> np.ndarray:
        return self._call("path", start)

    @property
    def goal(self) -> Cell:
        return self._active.goal

    @property
    def shape(self) -> tuple[int, int]:
        return self._active.shape
