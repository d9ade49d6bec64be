"""Planners by name, and the one place a backend is chosen.

``make_planner("eds")`` is what the navigator builds; ``"dss"`` is the same field recomputed
from scratch at every change, the paper's baseline. The other papers' planners register
their own factory under their own name (``register``); ``"astar"`` (Ghoniem et al.'s A*,
searched from the user's cell at every path read) runs on the CPU whatever the backend.
``backend="auto"`` means cuda when cupy imports and a device answers, else cpu. Heavy
imports (numba, cupy) happen only when their backend is asked for.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable

from .interface import GlobalPlanner

log = logging.getLogger(__name__)

BACKENDS = ("auto", "cpu", "cuda", "reference")
VARIANTS = ("fast", "paper")

PlannerFactory = Callable[[str, str], GlobalPlanner]
"""``factory(backend, variant)`` with the backend already resolved (never ``auto``)."""


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


DEFER_BLOCKS_ON_DEVICE = True
"""Wrap the cuda backend's EDS in ``DeferredBlocks`` (read when a planner is made, so a bench can
compare the two). On the H100 (2026-11-27, 400², four scenarios, the rule on / off in one call):
EDS's walk 0.24-0.34 of DSS's against 0.45-0.60 off, its p99 within the spread of the plain
walk's (0.15-0.27 ms both), each repair the plain walk's delta (the deferred blocks go to the
device between steps, ``between_steps``)."""


def _field_planner(dss: bool) -> PlannerFactory:
    def factory(backend: str, variant: str) -> GlobalPlanner:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
        planner = _field_backend(dss, backend, variant)
        if dss or backend != "cuda" or not DEFER_BLOCKS_ON_DEVICE:  # DSS: the full-plan baseline
            return planner
        # EDS on the device: a step whose new obstacles all miss the user's path needs no
        # repair and no round trip (deferred_blocks.py: the rule, its proof, and why not on
        # the host, where a repair step costs about what the rule's check does).
        from .deferred_blocks import DeferredBlocks

        return DeferredBlocks(planner)

    return factory


def _field_backend(dss: bool, backend: str, variant: str) -> GlobalPlanner:
    if backend == "reference":
        from .reference import ReferencePlanner

        return ReferencePlanner(dss)
    if backend == "cpu":
        if variant == "paper":
            from .cpu.paper import PaperCpuPlanner

            return PaperCpuPlanner(dss)
        from .cpu.fast import FastCpuPlanner

        return FastCpuPlanner(dss)
    if not dss and variant == "fast":  # EDS on a small grid: the host's repair is quicker
        from .cuda.small_grids import SmallGridsOnCpu

        return SmallGridsOnCpu(variant)
    from .cuda.planner import CudaPlanner

    return CudaPlanner(variant, dss=dss)


def _astar_planner(backend: str, variant: str) -> GlobalPlanner:
    """A* (``cpu/astar.py``) on the CPU whatever the backend: it has no device form, so
    ``cuda``, ``auto`` and ``reference`` build the same CPU planner. ``fast`` breaks ties of
    f only (exact costs); ``paper`` keys the open list as Ghoniem et al. do."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    from .cpu.astar import AStarPlanner

    return AStarPlanner(tie_break="exact" if variant == "fast" else "paper")


def _extended_astar_planner(backend: str, variant: str) -> GlobalPlanner:
    """Rettkowski et al.'s extended A* (``cpu/extended_astar.py``), CPU whatever the backend,
    as ``astar``; the variant picks the same key. Not optimal: for study and comparison, not a
    default. With its fallback on (a search the memory criterion leaves pathless runs again
    without it), so a walk never stops for a door the criterion closed."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    from .cpu.extended_astar import ExtendedAStarPlanner

    return ExtendedAStarPlanner(tie_break="exact" if variant == "fast" else "paper", fallback=True)


def _ga_astar_planner(backend: str, variant: str) -> GlobalPlanner:
    """Ghoniem et al.'s GA with A* fitness (``cpu/ga_astar.py``), CPU whatever the backend, with
    the default ``GaParams`` (seed 0). One form only: the variant is checked, not used. Not
    optimal: for study and comparison, not a default."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    from .cpu.ga_astar import GaAStarPlanner

    return GaAStarPlanner()


def _visgraph_planner(backend: str, variant: str) -> GlobalPlanner:
    """Chen et al.'s visibility graph + A* (``visgraph/planner.py``), CPU whatever the backend.
    ``fast`` and ``paper`` build the same planner (the paper's A* is already its form); where
    the polygons shut a passage the grid keeps open, it answers the grid's A* path."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    from .visgraph.planner import VisGraphPlanner

    return VisGraphPlanner()


def _harmonic_planner(backend: str, variant: str) -> GlobalPlanner:
    """Hong & DeSouza's harmonic potential field (``harmonic/``): the numba engine on ``cpu``
    and ``reference``, the CuPy one on ``cuda``. Its field is not a distance
    (``is_distance = False``): judged by its own contract, descent to the goal."""
    from .harmonic import make_harmonic

    return make_harmonic(backend, variant)


PLANNERS: dict[str, PlannerFactory] = {
    "eds": _field_planner(False),
    "dss": _field_planner(True),
    "astar": _astar_planner,
    "extended-astar": _extended_astar_planner,
    "ga-astar": _ga_astar_planner,
    "visgraph": _visgraph_planner,
    "harmonic": _harmonic_planner,
}
"""The registered planners by name (iterate it for the names; ``register`` adds to it)."""


def register(name: str, factory: PlannerFactory) -> None:
    """Make ``make_planner(name, ...)`` call ``factory(backend, variant)``."""
    if name in PLANNERS:
        raise ValueError(f"a planner named {name!r} is registered already")
    PLANNERS[name] = factory


def make_planner(name: str = "eds", backend: str = "auto", variant: str = "fast") -> GlobalPlanner:
    """A new planner of the registered ``name`` on ``backend``; ``variant`` picks the fast form
    (default) or the paper's Figure 4 form."""
    factory = PLANNERS.get(name)
    if factory is None:
        raise ValueError(f"unknown planner {name!r}; choose one of {tuple(PLANNERS)}")
    return factory(resolve_backend(backend), variant)
