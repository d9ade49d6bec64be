"""Pure computation, no I/O: grid, inflation, planners, path extraction.

Imports only numpy, numba (cpu fast backend) and cupy (cuda backend, where present), so
the GPU machine — which has no zenoh or pydantic — can run the planner's tests and
benchmarks.
"""

from .backends import cuda_available, make_planner
from .grid import CELL_M, DIAGONAL, FREE, INF, OCCUPIED, STRAIGHT, UNKNOWN, Cell
from .inflation import InflatedMap
from .interface import Planner, UpdateStats

__all__ = [
    "CELL_M",
    "DIAGONAL",
    "FREE",
    "INF",
    "OCCUPIED",
    "STRAIGHT",
    "UNKNOWN",
    "Cell",
    "InflatedMap",
    "Planner",
    "UpdateStats",
    "cuda_available",
    "make_planner",
]
