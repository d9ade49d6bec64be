"""Pure computation, no I/O: grid, inflation, planners, path extraction.

Imports only numpy, numba (cpu backend) and cupy (cuda backend, where present), so the GPU
machine — which has no zenoh or pydantic — can run the planner's tests and benchmarks.

Start at ``interface.py`` (what a planner offers) and ``registry.py`` (planners by name);
``cpu/`` and ``cuda/`` hold EDS and DSS, each beside the paper's Figure 4 form.
"""

from .cuda.errors import DeviceFault, device_errors
from .field import FieldPlanner
from .grid import CELL_M, DIAGONAL, FREE, INF, OCCUPIED, STRAIGHT, UNKNOWN, Cell
from .inflation import InflatedMap
from .interface import GlobalPlanner, UpdateStats
from .registry import PLANNERS, cuda_available, make_planner, register, resolve_backend

__all__ = [
    "CELL_M",
    "DIAGONAL",
    "FREE",
    "INF",
    "OCCUPIED",
    "PLANNERS",
    "STRAIGHT",
    "UNKNOWN",
    "Cell",
    "DeviceFault",
    "FieldPlanner",
    "GlobalPlanner",
    "InflatedMap",
    "UpdateStats",
    "cuda_available",
    "device_errors",
    "make_planner",
    "register",
    "resolve_backend",
]
