"""Through the daemon over zenoh: the user guided by RFID poses still reaches the goal.

A real daemon (cpu backend) on a thread, listening on a free loopback port; the simulated
world on its own session, publishing RFID poses (reads in the reader's line protocol →
filter → localiser) instead of the true pose; the goal sent from a third session.
"""

from __future__ import annotations

import threading
import time

import pytest

from daemon.service.embedded import DaemonThread
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, NavState
from sim.courtyard import make_courtyard
from sim.rfid_eval import tags_for
from sim.rfid_node import RfidSimNode


@pytest.mark.timeout(90)
def test_daemon_guides_the_user_to_the_goal_from_rfid_poses() -> None:
    scenario = make_courtyard(100, 0.4, seed=0)
    tag_map = tags_for(scenario, "floor", seed=0)
    with DaemonThread(backend="cpu", guide_hz=100) as daemon:  # not paced to 10 Hz
        world_session, client = daemon.peer(), daemon.peer()
        try:
            node = RfidSimNode(world_session, "rfid-user", scenario, tag_map, seed=0,
                               offset_m=(0.03, -0.045))
            box: dict = {}
            stop = threading.Event()
            thread = threading.Thread(target=lambda: box.update(r=node.run(stop, 2000, 60)))
            thread.start()
            try:
                time.sleep(0.3)  # map and first poses reach the daemon before the goal
                goal = GoalCell(row=scenario.goal[0], col=scenario.goal[1])
                wire.put(client, T.GOAL, "rfid-user",
                         codec.encode(Goal(target=goal, stamp=time.time())))
                thread.join(75)
            finally:
                stop.set()
                thread.join(5)
            assert not thread.is_alive()
        finally:
            world_session.close()
            client.close()
    result = box["r"]
    assert result.arrived, result.reason
    assert result.last_status is not None and result.last_status.state == NavState.ARRIVED
    assert node.true_error_to(scenario.goal) <= 0.5  # where the user truly stands
    assert node.walker.collisions == 0
    assert node.filter.accepted > 0 and sum(node.filter.rejected.values()) == 0
    errors = sorted(node.pose_errors)
    assert 0.0 < errors[len(errors) // 2] <= 0.15  # guided by noisy poses, not the truth
    assert result.steps > 80  # the garden forces a detour
    print(f"steps {result.steps}, pose error median {errors[len(errors) // 2]:.3f} m, "
          f"true distance to goal {node.true_error_to(scenario.goal):.2f} m")
