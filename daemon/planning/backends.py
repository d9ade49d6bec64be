"""The one place a planner backend is chosen.

``auto`` means cuda when cupy imports and a device answers, else cpu. Heavy imports
(numba, cupy) happen only when their backend is asked for.
"""

from __future__ import annotations

import functools
import logging

from .interface import Planner

log = logging.getLogger(__name__)

BACKENDS = ("auto", "cpu", "cuda", "reference")
VARIANTS = ("fast", "paper")


@functools.cache
def cuda_available() -> bool:
    """True when cupy imports and at least one CUDA device runs a trivial kernel."""
    try:
        import cupy

        if cupy.cuda.runtime.getDeviceCount() < 1:
            return False
        (cupy.arange(4) + 1).sum().item()
        return True
    except Exception as exc:  # no cupy, no driver, no device: all mean "use the CPU"
        log.debug("cuda unavailable: %s", exc)
        return False


def resolve_backend(backend: str) -> str:
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {BACKENDS}")
    if backend == "auto":
        return "cuda" if cuda_available() else "cpu"
    return backend


def make_planner(backend: str = "auto", variant: str = "fast", raw: bool = False) -> Planner:
    """A new planner. ``variant`` picks ``fast`` (default) or the paper's Figure 4 form.

    A cuda planner comes wrapped in ``fallback.FallbackPlanner``, which moves the session to
    the CPU on a CUDA error; ``raw=True`` gives the bare ``CudaPlanner`` (tests, benchmarks).
    """
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    chosen = resolve_backend(backend)
    if chosen == "reference":
        from .reference import ReferencePlanner

        return ReferencePlanner()
    if chosen == "cpu":
        if variant == "paper":
            from .cpu_paper import PaperCpuPlanner

            return PaperCpuPlanner()
        from .cpu_fast import FastCpuPlanner

        return FastCpuPlanner()
    from .cuda_planner import CudaPlanner

    planner = CudaPlanner(variant=variant)
    if raw:
        return planner
    from .fallback import FallbackPlanner

    return FallbackPlanner(planner)
