"""The walk in one process and the walk through the daemon over zenoh are the same walk.

Both drive the daemon's ``Navigator`` with the same world: in process directly, over zenoh
through a real daemon on loopback with the sim node publishing the world's deltas and poses.
On one seeded courtyard they must stand on the same cells and feel the same belt patterns,
the node acting only on paths that reflect every delta it has sent (``LockStepNode``).
The daemon's clock tick is pushed out of the walk (it would add guidance steps at times of
its own choosing), and the world is one where the hold-instead-of-detour timer (real time on
the daemon, simulated in process) never starts.
"""

from __future__ import annotations

import threading
import time

import pytest

from daemon.navigation import Navigator
from daemon.service.config import DaemonConfig
from daemon.service.embedded import DaemonThread
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell
from sim.closed_loop import run_walk
from sim.courtyard import USER_RADIUS_M, make_courtyard
from sim.node import SimNode
from sim.world import World

pytestmark = pytest.mark.timeout(120)


class LockStepNode(SimNode):
    """A sim node that acts only on a path reflecting every delta it has sent: asked again,
    the same pose meets them. The node sends its first deltas and first pose on two keys
    without waiting between them (later deltas wait for their path, ``SimNode._sense``), and
    the daemon may plan that pose first: a step order the in-process walk never takes. So
    before the walk it asks from the start until the daemon has the first map, and its
    guidance starts from that path: a path planned on part of the map, then replaced, would
    make the walk's first pattern a reroute."""

    ASKS = 50
    sent = -1
    """The last delta this node published (its seq)."""

    def _put_delta(self, delta) -> None:
        self.sent = delta.seq
        super()._put_delta(delta)

    def _start_map(self) -> None:
        super()._start_map()
        stop = threading.Event()
        path = self._wait_for_path(self._send_pose(), stop)
        assert path is not None and path.map_seq >= self.sent, "the daemon never had the map"
        self._wait_for_belt(path.stamp, stop)

    def _wait_for_path(self, stamp, stop):
        path = super()._wait_for_path(stamp, stop)
        for _ in range(self.ASKS):
            if path is None or path.map_seq >= self.sent:
                break
            path = super()._wait_for_path(self._send_pose(), stop)
        return path


def felt(pattern) -> tuple:
    return (str(pattern.kind), tuple(pattern.motors), pattern.period_ms)


def test_the_in_process_walk_and_the_daemon_walk_the_same_cells_with_the_same_belt():
    scenario = make_courtyard(grid=100, unknown=0.3, seed=3)
    config = DaemonConfig(backend="cpu", cell_m=scenario.cell_m, user_radius_m=USER_RADIUS_M,
                          tick_s=60.0, stale_pose_s=5.0, guide_hz=100)  # fmt: skip

    nav = Navigator("same", config.navigator_settings())
    here = run_walk(World(scenario, "path"), nav, max_actions=600, step_s=0.05, map_first=True)
    assert here.arrived and nav.guidance.hold.holds == 0
    assert nav.replans > 0  # newly seen obstacles cut the path on the way

    with DaemonThread(config) as daemon:
        client, session = daemon.peer(), daemon.peer()
        try:
            goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]),
                        stamp=time.time())  # fmt: skip
            wire.put(client, T.GOAL, "same", codec.encode(goal))
            time.sleep(0.2)  # the goal is the daemon's before the world's first delta
            there = LockStepNode(session, "same", scenario, walker="path").run(
                stop=threading.Event(), timeout_s=90.0
            )
        finally:
            session.close()
            client.close()

    assert there.arrived
    assert there.walked == here.walked
    # The last pattern in process is ARRIVED, which the sim node stops on before acting.
    assert [felt(b) for b in there.belts] == [felt(b) for b in here.belts[: len(there.belts)]]
    assert len(there.belts) >= len(here.walked) - 1
