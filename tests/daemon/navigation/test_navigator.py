"""``Navigator`` without zenoh: coalescing, resync, the margin's way out."""

from __future__ import annotations

import time

import numpy as np

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.planning.dijkstra import dijkstra_field
from protocol.messages import Goal, GoalCell, MapDelta, MapSnapshot, NavState, Pose

SHAPE = (30, 30)


def navigator(**overrides) -> Navigator:
    return Navigator("u", NavigatorSettings(backend="cpu", **overrides))


def delta(seq, cells, values, shape=SHAPE) -> MapDelta:
    return MapDelta.from_arrays(seq, shape, np.array(cells), np.array(values), time.time())


def pose(cell, stamp=None) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57,
                stamp=stamp or time.time())


def goal(r, c) -> Goal:
    return Goal(target=GoalCell(row=r, col=c), stamp=time.time())


def test_deltas_in_one_step_are_applied_together_and_the_field_stays_exact():
    s = navigator()
    s.step(Inbox(deltas=[delta(0, [], [])], goal=goal(3, 15), pose=pose((26, 15))), time.time())
    assert s.state == NavState.GUIDING
    wall = [12 * 30 + c for c in range(0, 25)]
    # Three deltas arrive while a step runs: the next step takes them in one update.
    batch = [delta(1, wall[:10], [1] * 10), delta(2, wall[10:], [1] * 15), delta(3, [5], [1])]
    out = s.step(Inbox(deltas=batch, pose=pose((26, 15))), time.time())
    assert s.maps.seq == 3
    assert np.array_equal(s.route.planner.costs(), dijkstra_field(s.maps.map.blocked, (3, 15)))
    assert out.path() is not None and out.path().cells[0] == (26, 15)
    assert s.replans == 1  # the wall cut the straight path


def test_a_gap_buffers_deltas_and_a_snapshot_replays_the_newer_ones():
    s = navigator()
    s.step(Inbox(deltas=[delta(0, [1], [1])]), time.time())
    out = s.step(Inbox(deltas=[delta(3, [2], [1]), delta(4, [3], [1])]), time.time())
    assert out.want_snapshot and s.maps.resyncing
    assert [st.code for st in out.statuses] == ["sequence_gap"]
    assert s.maps.map.occupancy.reshape(-1)[[2, 3]].tolist() == [2, 2]  # nothing applied
    occ = np.full(SHAPE, 2, np.uint8)
    occ.reshape(-1)[[1, 2]] = 1
    snap = MapSnapshot.from_array(3, occ, time.time())  # includes delta 3, not 4
    s.step(Inbox(snapshot=snap), time.time())
    assert not s.maps.resyncing and s.maps.seq == 4
    assert s.maps.map.occupancy.reshape(-1)[[1, 2, 3]].tolist() == [1, 1, 1]


def test_a_delta_for_another_shape_changes_nothing():
    s = navigator()
    s.step(Inbox(deltas=[delta(0, [1], [1])]), time.time())
    before = s.maps.map.occupancy.copy()
    out = s.step(Inbox(deltas=[delta(1, [2], [1], shape=(40, 40))]), time.time())
    assert [st.code for st in out.statuses] == ["shape_mismatch"]
    assert np.array_equal(s.maps.map.occupancy, before) and s.maps.seq == 0


def test_a_pose_before_the_map_is_used_once_the_map_comes():
    s = navigator()
    s.step(Inbox(goal=goal(3, 15), pose=pose((20, 15))), time.time())
    assert s.state == NavState.PLANNING
    out = s.step(Inbox(deltas=[delta(0, [], [])]), time.time())
    assert out.path() is not None and s.state == NavState.GUIDING


def test_from_inside_the_inflation_margin_the_path_leads_out_then_on():
    s = navigator()
    wall = [10 * 30 + c for c in range(5, 25)]  # inflated 3 cells up and down
    s.step(Inbox(deltas=[delta(0, wall, [1] * len(wall))], goal=goal(3, 15)), time.time())
    out = s.step(Inbox(pose=pose((12, 15))), time.time())  # 2 cells below the wall
    assert s.maps.map.blocked[12, 15] and s.state == NavState.GUIDING
    cells = out.path().cells
    assert cells[0] == (12, 15) and cells[-1] == (3, 15)
    first_free = next(i for i, c in enumerate(cells) if not s.maps.map.blocked[c])
    assert all(not s.maps.map.blocked[c] for c in cells[first_free:])
    assert first_free <= s.radius_cells  # straight out of the margin, not through the wall
