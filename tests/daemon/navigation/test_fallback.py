"""A device that fails mid-session moves that user to the CPU, and guiding goes on.

The navigator owns the map, so the CPU planner is planned from it, every change included,
and the step that failed is answered from the CPU. Errors that are not the device's (a bug,
a bad cell) are not swallowed: they reach the runner, which reports them as ``internal``.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.planning import DeviceFault, make_planner
from daemon.planning.dijkstra import dijkstra_field
from protocol.messages import Goal, GoalCell, MapDelta, NavState, Pose

SHAPE = (30, 30)
GOAL = (3, 15)
WALL = [12 * 30 + c for c in range(0, 25)]


class Flaky:
    """Stands in for a GPU planner: a CPU planner whose ``method`` raises ``error`` once."""

    name = "cuda-stand-in"

    def __init__(self, method: str, error: BaseException) -> None:
        self.inner = make_planner("eds", "cpu")
        self.method, self.error = method, error

    def __getattr__(self, name: str):
        attr = getattr(self.inner, name)
        if name != self.method or self.error is None:
            return attr

        def fail(*args, **kwargs):
            error, self.error = self.error, None
            raise error

        return fail


def navigator(method: str, error: BaseException) -> Navigator:
    def factory(backend: str):
        return Flaky(method, error) if backend == "cuda" else make_planner("eds", backend)

    return Navigator("u", NavigatorSettings(backend="cuda"), planner_factory=factory)


def delta(seq: int, cells: list[int]) -> MapDelta:
    return MapDelta.from_arrays(seq, SHAPE, np.array(cells), np.ones(len(cells)), time.time())


def pose(cell: tuple[int, int], stamp: float | None = None) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57,
                stamp=stamp or time.time())  # fmt: skip


def walk(s: Navigator) -> list[NavState]:
    """Plan, repair with the path, read a path alone, take a change with no path read (the
    pose has gone stale), then guide again: each planner call a step makes, once; and after
    each step the planner's work between steps, as the runner asks for it."""
    now = time.time()
    states = []
    inboxes = [
        Inbox(deltas=[delta(0, [])], goal=Goal(target=GoalCell(row=3, col=15), stamp=now),
              pose=pose((26, 15))),
        Inbox(deltas=[delta(1, WALL[:10])], pose=pose((26, 15))),
        Inbox(pose=pose((25, 15))),
        Inbox(deltas=[delta(2, WALL[10:])], pose=pose((25, 15), stamp=now - 5)),
        Inbox(pose=pose((25, 15))),
    ]  # fmt: skip
    for i, inbox in enumerate(inboxes):
        s.step(inbox, time.time())
        if i != 3:  # the stale pose's step guides nobody
            states.append(s.state)
        s.between_steps()
    return states


@pytest.mark.parametrize(
    "method", ["plan", "update_and_path", "path", "update", "between_steps"]
)
def test_a_device_error_in_any_call_moves_the_user_to_the_cpu(method, caplog):
    s = navigator(method, DeviceFault("injected: an illegal memory access was encountered"))
    assert s.route.name == "cuda-stand-in"
    with caplog.at_level(logging.WARNING):
        states = walk(s)
    # Guided throughout; the last step's route goes round the whole wall, a new route said.
    assert states == [NavState.GUIDING] * 3 + [NavState.REROUTING]
    assert "cpu" in s.route.name and "illegal memory access" in s.route.fallback_reason
    assert s.status(time.time()).backend == s.route.name
    assert any("on the CPU" in r.getMessage() for r in caplog.records)
    # planned from the navigator's own map: every change, in order, is in the CPU's field
    assert s.maps.map is not None and s.maps.map.blocked[12, :25].all()
    assert np.array_equal(s.route.planner.costs(), dijkstra_field(s.maps.map.blocked, GOAL))


def test_a_failure_that_is_not_the_devices_is_not_swallowed():
    s = navigator("update_and_path", IndexError("cell 901 is outside the map"))
    with pytest.raises(IndexError):
        walk(s)
    assert s.route.name == "cuda-stand-in" and s.route.fallback_reason is None


def test_a_failure_between_steps_that_is_not_the_devices_plans_afresh_at_the_next_step():
    """What the planner holds is unknown after it: raised to the runner (which logs it), and
    the next path is planned from the navigator's map, every change in it."""
    s = navigator("between_steps", RuntimeError("a bug between steps"))
    now = time.time()
    s.step(Inbox(deltas=[delta(0, [])], goal=Goal(target=GoalCell(row=3, col=15), stamp=now),
                 pose=pose((26, 15))), now)  # fmt: skip
    with pytest.raises(RuntimeError):
        s.between_steps()
    s.step(Inbox(deltas=[delta(1, WALL)], pose=pose((26, 15))), time.time())
    assert s.state == NavState.REROUTING and s.route.name == "cuda-stand-in"
    assert s.route.report.planned  # from scratch
    assert np.array_equal(s.route.planner.costs(), dijkstra_field(s.maps.map.blocked, GOAL))
