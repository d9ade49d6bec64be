"""Pure computation, no I/O: grid, inflation, planners, path extraction.

Imports only numpy, numba (cpu fast backend) and cupy (cuda backend, where present), so
the GPU machine — which has no zenoh or pydantic — can run the planner's tests and
benchmarks.
"""

from .backends import cuda_available
from .fallback import DeviceFault, device_errors
from .grid import CELL_M, DIAGONAL, FREE, INF, OCCUPIED, STRAIGHT, UNKNOWN, Cell
from .inflation import InflatedMap
from .interface import Planner, UpdateStats
from .registry import PLANNERS, make_planner

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
    "InflatedMap",
    "Planner",
    "UpdateStats",
    "cuda_available",
    "device_errors",
    "make_planner",
]
