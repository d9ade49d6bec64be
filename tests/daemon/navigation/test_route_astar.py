"""The navigator's ``Route`` with the A* planner: it searches at every path read, so a read
without a change reports that search, and the escape from the margin reads ``costs()``."""

from __future__ import annotations

import numpy as np

from daemon.navigation.route import Route
from daemon.planning import make_planner
from daemon.planning.grid import FREE, INF, OCCUPIED, path_cost


def route(name: str) -> Route:
    return Route(lambda backend: make_planner(name, backend), "cpu", escape_reach=4)


def test_a_path_read_without_a_change_reports_the_search():
    blocked = np.zeros((40, 40), bool)
    blocked[20, 5:35] = True
    occupancy = np.where(blocked, OCCUPIED, FREE).astype(np.uint8)
    r, e = route("astar"), route("eds")
    for cell in [(35, 20), (34, 20)]:
        pa, ca = r.path_from(blocked, occupancy, (5, 20), cell)
        _, ce = e.path_from(blocked, occupancy, (5, 20), cell)
        assert ca == ce == path_cost(pa) and tuple(pa[-1]) == (5, 20)
    stats = r.report.stats
    assert stats is not None and stats.iterations > 0 and stats.cells_touched >= stats.iterations
    assert e.report.stats is None  # EDS reads its field: nothing to report
    # A change goes to the planner with the next read, in one update_and_path.
    blocked[20, 35:] = True
    r.change(np.array([20 * 40 + 35]), np.array([True]))
    pa, ca = r.path_from(blocked, occupancy, (5, 20), (34, 20))
    assert ca < INF and not blocked[pa[:, 0], pa[:, 1]].any()
    assert r.report.stats is not None and r.report.stats.iterations > 0


def test_from_inside_the_margin_astar_leads_out_as_eds_does():
    occupancy = np.zeros((30, 30), np.uint8)
    occupancy[15, 10:20] = OCCUPIED
    blocked = occupancy == OCCUPIED
    blocked[14:17, 9:21] = True  # the margin around the obstacle
    cell = (14, 15)  # inside the margin
    answers = {}
    for name in ("astar", "eds"):
        path, cost = route(name).path_from(blocked, occupancy, (2, 15), cell)
        assert tuple(path[0]) == cell and tuple(path[-1]) == (2, 15)
        answers[name] = (cost, tuple(path[1]))
    assert answers["astar"] == answers["eds"]
