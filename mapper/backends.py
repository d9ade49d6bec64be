"""Which backend runs the per-pixel pass: chosen here and nowhere else.

``cpu`` is the numba loop of ``binning.py``; ``cuda`` the CUDA graph of ``cuda_binning.py``
(``cupy`` is optional: imported only when asked for, or when ``auto`` finds a device).
Both take the same arguments and return the same ``Binned``; cuda also merges the frame
into the map it keeps on the device, with the same result as ``merge.merge_frame``.
``auto`` takes cuda when a device answers, else cpu, as the planner does.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .binning import Binned, bin_frame_cpu

BACKENDS = ("auto", "cpu", "cuda")


class Binner:
    def __init__(self, name: str, fn: Callable[..., Binned], counts_valid: bool = False,
                 merges: bool = False) -> None:  # fmt: skip
        self.name, self._fn = name, fn
        self.counts_valid = counts_valid
        """The pass also counts the pixels the frame check counts (``Binned.present``): the
        mapper then checks the depth and the motion once the pass is back, not before."""
        self.merges = merges
        """The pass also merges the frame into a map it keeps (``merge``, ``pull``: cuda,
        ``cuda_merge``); the mapper then calls ``merge`` instead of the pass and
        ``merge.merge_frame``."""

    def __call__(self, *args: Any) -> Binned:
        return self._fn(*args)

    def merge(self, maps: tuple, params: list[float], *args: Any) -> tuple:
        return self._fn.merge(maps, params, *args)  # type: ignore[attr-defined]

    def depth_buffer(self, *args: Any) -> Any:
        """The array the pass uploads a frame's depth from (``CudaBinner.depth_buffer``), or
        None where the pass reads the frame where it lies."""
        lend = getattr(self._fn, "depth_buffer", None)
        return None if lend is None else lend(*args)

    def pull(self, logodds: Any, seen_at: Any) -> None:
        self._fn.pull(logodds, seen_at)  # type: ignore[attr-defined]


def cuda_usable() -> bool:
    try:
        import cupy

        return cupy.cuda.runtime.getDeviceCount() > 0
    except Exception:  # no cupy, no driver, no device: all mean "not here"
        return False


def make_binner(name: str = "auto") -> Binner:
    if name not in BACKENDS:
        raise ValueError(f"mapper backend must be one of {BACKENDS}, not {name!r}")
    if name == "cuda" or (name == "auto" and cuda_usable()):
        from .cuda_binning import CudaBinner

        return Binner("cuda", CudaBinner(), counts_valid=True, merges=True)  # its own graphs
    return Binner("cpu", bin_frame_cpu)
