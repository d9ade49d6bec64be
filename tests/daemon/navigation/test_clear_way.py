"""From one cell beside a known box, the belt never points past the box's corner.

A user pressed against a known obstacle stands deep in the inflation margin; the path leads
out of it from the cell's centre, but the user is elsewhere in the cell. The step's direction
is checked here against the true geometry of the box's cells (exact segment-square clipping,
not the code's own test)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import daemon.navigation.navigator as navigator_module
from daemon.guidance.patterns import decode
from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.planning import make_planner
from daemon.planning.escape import escape_path
from daemon.planning.grid import FREE, OCCUPIED
from daemon.planning.inflation import InflatedMap
from protocol.messages import Goal, GoalCell, MapSnapshot, PatternKind, Pose

N = 30
CELL_M = 0.1
STEP_M = 0.15
"""A walker beside an obstacle steps about 0.125 m (the fastest pulse); a little more."""
BOX = (slice(10, 15), slice(5, 11))
"""Rows 10-14, columns 5-10: its top-right cell is (10, 10)."""


def box_map() -> np.ndarray:
    occ = np.full((N, N), FREE, np.uint8)
    occ[BOX] = OCCUPIED
    occ[4:22, 14] = OCCUPIED  # a wall 3 cells east of the box: the gap between is all margin
    occ[21, 5:15] = OCCUPIED
    return occ


def segment_enters_cell(x0: float, y0: float, x1: float, y1: float, r: int, c: int) -> bool:
    """Liang-Barsky: does the segment (metres) pass through the open square of cell (r, c)?"""
    left, right = c * CELL_M, (c + 1) * CELL_M
    bottom, top = (N - 1 - r) * CELL_M, (N - r) * CELL_M
    t0, t1 = 0.0, 1.0
    dx, dy = x1 - x0, y1 - y0
    for p, q in ((-dx, x0 - left), (dx, right - x0), (-dy, y0 - bottom), (dy, top - y0)):
        if p == 0:
            if q <= 0:
                return False
            continue
        t = q / p
        if p < 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
    return t1 - t0 > 1e-9


def clips(occ: np.ndarray, x: float, y: float, heading: float) -> bool:
    x1, y1 = x + STEP_M * math.cos(heading), y + STEP_M * math.sin(heading)
    return any(segment_enters_cell(x, y, x1, y1, r, c) for r, c in np.argwhere(occ == OCCUPIED))


def given_direction(occ: np.ndarray, x: float, y: float, goal, heading: float) -> float | None:
    """The world heading of the step's GUIDE for a user at (x, y), None if no GUIDE."""
    now = 1000.0
    nav = Navigator("u", NavigatorSettings(backend="cpu"))
    out = nav.step(Inbox(snapshot=MapSnapshot.from_array(0, occ, now),
                         goal=Goal(target=GoalCell(row=goal[0], col=goal[1]), stamp=now),
                         pose=Pose(x=x, y=y, heading=heading, stamp=now)), now)  # fmt: skip
    guide = [b for b in out.belt if b.kind == PatternKind.GUIDE]
    return heading - decode(guide[0].motors) if guide else None


BESIDE = [
    # Pressed against the east face 1 mm below the top-right corner (the walks' bump), and
    # further down the face; 5 cm off the face; above the top face near the corner.
    (1.101, 1.991),
    (1.101, 1.95),
    (1.101, 1.75),
    (1.15, 1.99),
    (1.15, 1.8),
    (1.05, 2.001),
]
GOALS = [(2, 2), (2, 10), (25, 2)]


def count_clipping(occ: np.ndarray) -> tuple[int, int]:
    guided = clipped = 0
    for x, y in BESIDE:
        for goal in GOALS:
            for heading in np.radians(np.arange(0, 360, 45)):
                d = given_direction(occ, x, y, goal, float(heading))
                if d is not None:
                    guided += 1
                    clipped += clips(occ, x, y, d)
    return guided, clipped


def test_beside_a_known_box_the_direction_never_clips_it():
    guided, clipped = count_clipping(box_map())
    assert guided > 100 and clipped == 0


def test_without_the_check_the_step_would_clip_the_corner(monkeypatch):
    # The case is real: the path's own direction, unchecked, walks the user past the corner.
    monkeypatch.setattr(navigator_module, "keep_clear", lambda *a, **k: None)
    monkeypatch.setattr("daemon.planning.escape._keeps_clear", lambda *a: True)
    _, clipped = count_clipping(box_map())
    assert clipped > 0


def test_away_from_obstacles_the_direction_is_the_guidances_own(monkeypatch):
    occ = box_map()
    checked = [given_direction(occ, 2.5, 0.5, (2, 25), h) for h in (0.0, 1.0, 2.5)]
    monkeypatch.setattr(navigator_module, "keep_clear", lambda *a, **k: None)
    plain = [given_direction(occ, 2.5, 0.5, (2, 25), h) for h in (0.0, 1.0, 2.5)]
    assert None not in checked and checked == pytest.approx(plain)


def diagonal_wall() -> InflatedMap:
    """Cells r + c = 21 from map edge to map edge: neighbours only at their corners, a wall
    nobody passes (nor does the planner: inflated, it is three cells thick)."""
    occ = np.full((N, N), FREE, np.uint8)
    for r in range(22):
        occ[r, 21 - r] = OCCUPIED
    return InflatedMap(occ, 1)


@pytest.mark.parametrize("checked", [True, False])
def test_a_way_out_never_passes_between_two_diagonal_obstacle_cells(monkeypatch, checked):
    # The user at (11, 11) just below the wall, on the side with no way to the goal: the
    # nearest usable cells are beyond it, and every straight line there runs through a
    # corner two wall cells share. The lead's own cells ((11, 11), (10, 10), (10, 9)) miss it.
    if not checked:
        monkeypatch.setattr("daemon.planning.escape._keeps_clear", lambda *a: True)
    m = diagonal_wall()
    planner = make_planner("eds", "cpu")
    planner.plan(m.blocked, (2, 2))
    assert m.blocked[11, 11] and len(planner.path((12, 12))) == 0
    path, _ = escape_path(planner, m.blocked, m.occupancy, (11, 11), 5)
    if checked:
        assert len(path) == 0  # no way out: NO_PATH, never a lead through the wall
    else:
        assert len(path) and (10, 10) in {tuple(int(v) for v in p) for p in path}


def test_the_cell_of_a_position_is_the_cell_numpy_floors_to():
    """``_cell`` on scalars: the cell the array form gave, on and off the map and on borders."""
    from daemon.navigation.clear_way import _cell

    rng = np.random.default_rng(3)
    xs = np.concatenate([rng.uniform(-2.0, 12.0, 500), np.arange(-3, 104) * 0.1])
    ys = np.concatenate([rng.uniform(-2.0, 12.0, 500), np.arange(-3, 104)[::-1] * 0.1])
    for shape, cell_m in (((100, 100), 0.1), ((200, 150), 0.05)):
        for x, y in zip(xs, ys, strict=True):
            r = shape[0] - 1 - np.floor(np.array([y]) / cell_m).astype(np.int64)[0]
            c = np.floor(np.array([x]) / cell_m).astype(np.int64)[0]
            assert _cell(shape, float(x), float(y), cell_m) == (r, c)
