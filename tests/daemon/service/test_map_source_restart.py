"""Over zenoh: the sim's mapper restarts mid-walk (a new epoch, sequence 0 again) as a new
obstacle appears; the daemon resynchronises from its snapshot, and the obstacle reaches the map."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from daemon.planning.grid import OCCUPIED
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapSnapshot
from sim.courtyard import make_courtyard
from sim.node import SimNode, SimResult


@pytest.fixture
def daemon():
    """Its own daemon: a pose re-guides at once (the lock-step walk is not paced to 10 Hz)."""
    from daemon.service.embedded import DaemonThread

    with DaemonThread(backend="cpu", guide_hz=100) as d:
        yield d


@pytest.fixture
def peer(daemon):
    session = daemon.peer()
    yield session
    session.close()


@pytest.mark.timeout(90)
def test_a_mapper_restarted_mid_walk_at_sequence_0_still_reaches_the_map(daemon, peer):
    scenario = make_courtyard(100, 0.2, seed=4)
    goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=1.0)
    session = daemon.peer()
    node = SimNode(session, "remap", scenario, pose_period_s=0.2, goal=goal)
    epochs: list[int] = []
    wall = np.zeros(scenario.shape, bool)

    def restart(result: SimResult) -> None:
        if result.steps == 10 and not epochs:
            world = node.world
            epochs.append(world.epoch)
            r, c = world.cell()
            wall[r - 9 : r - 7, c - 1 : c + 1] = True  # ahead, on the way north
            world.true[wall] = OCCUPIED
            node.restart_mapper()
            epochs.append(world.epoch)

    stop = threading.Event()
    try:
        result = node.run(stop, timeout_s=60, on_step=restart)
    finally:
        session.close()
    assert result.arrived, result.reason
    assert len(epochs) == 2 and epochs[0] != epochs[1]
    snap = next(r.ok for r in wire.get(peer, T.MAP_SNAPSHOT, "remap") if r.ok is not None)
    final = codec.decode(MapSnapshot, snap.payload.to_bytes())
    assert final.epoch == epochs[1]
    assert (result.known[wall] == OCCUPIED).any()  # the new epoch's sensor saw the obstacle
    assert np.array_equal(final.array(), result.known)  # nothing the new epoch sent was dropped
    health = next(r.ok for r in wire.get(peer, T.HEALTH) if r.ok is not None).payload.to_bytes()
    assert b"sequence_gap" not in health  # a restart is not taken for lost deltas
