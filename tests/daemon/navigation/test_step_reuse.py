"""What a step keeps from the last one gives what working it out afresh gives."""

from __future__ import annotations

import numpy as np

import daemon.guidance.turning_points as tp
from daemon.guidance.turning_points import KeptPoints, turning_points
from daemon.navigation import Inbox, Navigator, NavigatorSettings, StepOutput
from daemon.planning.inflation import InflatedMap
from protocol import codec
from protocol.messages import Goal, GoalCell, MapDelta, MapSnapshot, Pose

N = 40
CELL_M = 0.1


def _pose(r: float, c: float, t: float, sigma: float | None = None) -> Pose:
    return Pose(x=(c + 0.5) * CELL_M, y=(N - r - 0.5) * CELL_M, heading=1.57, stamp=t,
                sigma_m=sigma)  # fmt: skip


def _box(r: int, c: int, size: int = 3) -> np.ndarray:
    rr, cc = np.mgrid[r : r + size, c : c + size]
    return (rr * N + cc).ravel()


def _wire(out: StepOutput) -> list[bytes]:
    """Everything the step would publish, as bytes."""
    msgs = [*out.belt, *out.voice, *out.statuses]
    path = out.path()
    return [codec.encode(m) for m in msgs] + ([codec.encode(path)] if path is not None else [])


def _walk() -> list[Inbox]:
    """Poses at 20 Hz up the middle with stops, boxes on and beside the way at 10 Hz that
    come and go, an unsure pose (a wider margin), and a snapshot of the same map."""
    walls = np.flatnonzero(np.pad(np.zeros((N - 2, N - 2), bool), 1, constant_values=True))
    occ = np.zeros((N, N), np.uint8)
    occ.reshape(-1)[walls] = 1
    t = 100.0
    first = MapDelta.from_arrays(0, (N, N), walls, np.ones(walls.size, np.uint8), t)
    goal = Goal(target=GoalCell(row=4, col=20), stamp=t)
    inboxes = [Inbox(deltas=[first], goal=goal, pose=_pose(34, 20, t), pose_received=t)]
    boxes = [_box(20, 19), _box(16, 24), _box(24, 14), _box(12, 20)]
    r, seq, placed = 34.0, 0, None
    for k in range(160):
        t += 0.05
        if k % 40 >= 25:  # stands still for a while, as the load generator's users do
            pass
        else:
            r -= 0.25  # cells: 0.5 m/s
        sigma = 0.25 if 60 <= k < 70 else None
        inbox = Inbox(pose=_pose(r, 20.2, t, sigma), pose_received=t)
        if k % 2 == 0:
            seq += 1
            if placed is None:
                placed = boxes[(k // 2) % len(boxes)]
                vals = np.ones(placed.size, np.uint8)
            else:
                vals = np.zeros(placed.size, np.uint8)
            occ.reshape(-1)[placed] = vals
            inbox.deltas = [MapDelta.from_arrays(seq, (N, N), placed, vals, t)]
            if vals[0] == 0:
                placed = None
        if k == 100:
            inbox.snapshot = MapSnapshot.from_array(seq, occ, t)
            inbox.deltas = []
        inboxes.append(inbox)
    return inboxes


def _counted(obj, name: str) -> list[int]:
    calls = [0]
    real = getattr(obj, name)

    def counting(*args, **kwargs):
        calls[0] += 1
        return real(*args, **kwargs)

    setattr(obj, name, counting)
    return calls


def test_what_a_step_keeps_from_the_last_guides_as_working_it_out_afresh(monkeypatch):
    """Turning points and the path read are kept between steps; a navigator that works
    both out afresh at every step publishes the same bytes over the whole walk."""
    kept = Navigator("kept", NavigatorSettings(backend="cpu", cell_m=CELL_M))
    fresh = Navigator("fresh", NavigatorSettings(backend="cpu", cell_m=CELL_M))
    guided = [0]

    def afresh(path, blocked, max_leg_cells, version):
        guided[0] += 1
        return turning_points(path, blocked, max_leg_cells=max_leg_cells)

    fresh.guidance._kept_points = afresh  # type: ignore[assignment]
    path_from = fresh.route.path_from

    def path_afresh(*args, **kwargs):
        fresh.route._kept = None
        return path_from(*args, **kwargs)

    fresh.route.path_from = path_afresh  # type: ignore[method-assign]
    points = [0]

    def counted_points(*args, **kwargs):
        points[0] += 1
        return turning_points(*args, **kwargs)

    # Only the kept navigator's points go through the module's name.
    monkeypatch.setattr(tp, "turning_points", counted_points)
    inboxes = _walk()
    first, rest = inboxes[0], inboxes[1:]
    for nav in (kept, fresh):
        nav.step(first, first.pose.stamp)
    reads = {"kept": _counted(kept.route.planner, "path"),
             "fresh": _counted(fresh.route.planner, "path")}  # fmt: skip
    for inbox in rest:
        now = inbox.pose.stamp if inbox.pose is not None else 0.0
        assert _wire(kept.step(inbox, now)) == _wire(fresh.step(inbox, now))
    assert kept.steps == fresh.steps == 161
    assert guided[0] > 120  # guided on most steps (the unsure poses WAIT)
    # Reused where the path ahead and the map were the last step's: most pose-only steps.
    assert points[0] < 0.75 * guided[0]
    assert reads["fresh"][0] > 60
    assert reads["kept"][0] < 0.75 * reads["fresh"][0]


def test_kept_points_are_worked_out_again_when_the_map_changes_in_place():
    grid = InflatedMap(np.zeros((N, N), np.uint8), 2)
    # Up, then right: free, the whole corner is cut by one straight leg.
    path = np.array([(r, 10) for r in range(34, 19, -1)] + [(20, c) for c in range(11, 31)])
    kept = KeptPoints()
    before = kept(path, grid.blocked, 80.0, grid.version)
    assert len(before) == 2
    assert kept(path, grid.blocked, 80.0, grid.version) is before  # the same path and map
    assert not before.flags.writeable  # shared with later steps
    # A box inside the corner, off the path: the same path, no longer one leg.
    v = grid.version
    grid.apply(_box(26, 17), np.ones(9, np.uint8))
    assert grid.version > v
    after = kept(path, grid.blocked, 80.0, grid.version)
    assert len(after) > 2
    assert np.array_equal(after, turning_points(path, grid.blocked, max_leg_cells=80.0))
    # An apply that flips nothing leaves the version; a reinflation moves it on.
    v = grid.version
    grid.apply(np.array([0]), np.zeros(1, np.uint8))
    assert grid.version == v
    grid.reinflate(3)
    assert grid.version == v + 1
    # A map of its own is never taken for the one kept, whatever its version says.
    other = InflatedMap(np.zeros((N, N), np.uint8), 2)
    assert len(kept(path, other.blocked, 80.0, grid.version)) == 2
