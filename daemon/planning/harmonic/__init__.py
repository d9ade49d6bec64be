"""Hong & DeSouza's harmonic potential fields: the planner (``planner.py``), its relaxation
on the CPU (``relax.py``, ``cpu.py``) and on the GPU (``cuda.py``, ``kernels/harmonic.cu``),
and the paper's rubber band (``rubber_band.py``).

``make_harmonic(backend, variant)`` is the one place an engine is chosen: ``cuda`` builds the
CuPy engine (imported only then), ``cpu`` and ``reference`` the numba one. Variant ``fast``:
four-colour SOR from the distance-like first guess (``kernels/harmonic.cu``); ``paper``: the
paper's forms — row-wise Gauss–Seidel on the CPU, eq. (1)'s Jacobi sweeps on the GPU — from
the median-range guess. Both stop a replanning step early on a field without a pit
(``planner.py``). The rubber band: ``rubber_band.py`` (numba), ``band_cuda.py`` (the GPU's).
"""

from __future__ import annotations

from .planner import HarmonicPlanner

VARIANTS = ("fast", "paper")


def make_harmonic(backend: str, variant: str = "fast") -> HarmonicPlanner:
    if variant not in VARIANTS:
        raise ValueError(f"unknown variant {variant!r}; choose one of {VARIANTS}")
    init = "distance" if variant == "fast" else "paper"
    if backend == "cuda":
        from .cuda import CudaField

        engine = CudaField(order="rb" if variant == "fast" else "jacobi")
    else:
        from .cpu import CpuField

        engine = CpuField(order="rb" if variant == "fast" else "rows")
    suffix = "" if variant == "fast" else "-paper"
    return HarmonicPlanner(engine, init=init, name=f"harmonic-{engine.backend}{suffix}")


__all__ = ["VARIANTS", "HarmonicPlanner", "make_harmonic"]
