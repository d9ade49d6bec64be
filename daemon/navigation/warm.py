"""The navigator's compiled code run once before the first user's step (``planning/warm.py``
says why): the planner with the inflation, then guidance's turning points."""

from __future__ import annotations

import time

import numpy as np

from daemon.guidance.clearance import forward_clearance_m
from daemon.guidance.hold import _direction
from daemon.guidance.route_watch import _nearest_m
from daemon.guidance.turning_points import is_core, segment_clear, segment_free, turning_points
from daemon.planning.registry import make_planner
from daemon.planning.warm import exercise


def _warm_guidance() -> None:
    """Turning points of a staircase path around a block: the any-angle shortcuts (clear and
    not) and the end-point fit all run."""
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[4:9, 4:9] = True
    path = [(2, c) for c in range(2, 11)] + [(r, 10) for r in range(3, 13)]
    path += [(12 + i, 10 + i) for i in range(1, 3)]
    turning_points(np.array(path, dtype=np.int32), blocked)
    turning_points(np.array([(r, r) for r in range(10, 16)], dtype=np.int32), blocked)
    # Called from Python too (the guide's leg checks), not only inside the compiled fit.
    a, b = np.array([2.5, 2.5]), np.array([12.5, 12.5])
    segment_free(blocked, a[0], a[1], b[0], b[1])
    segment_clear(blocked, a[0], a[1], b[0], b[1], 1)
    forward_clearance_m(blocked, a, 0.5, 0.1)
    is_core(blocked, 6, 6, 1)  # the guide's "user in the margin" test, a user on a blocked cell
    # The route watch's and the hold's distances, with the types the guide passes.
    pts = np.array(path, dtype=np.float64)
    _nearest_m(pts[:3], pts, 0.1)
    _direction(np.array(path, dtype=np.int64), a, 5.0)


def warm_up(planner: str, backend: str, variant: str = "fast") -> float:
    """Build planner ``planner`` on ``backend`` and run a throw-away walk's calls; the ms taken."""
    t0 = time.perf_counter()
    exercise(make_planner(planner, backend, variant))
    _warm_guidance()
    return (time.perf_counter() - t0) * 1e3
