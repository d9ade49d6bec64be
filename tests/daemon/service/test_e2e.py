"""Goals over zenoh from a separate session; simulated users walk until the daemon says
they arrived."""

from __future__ import annotations

import math
import threading
import time

import pytest

from drivers.belt.recorder import BeltRecorder
from drivers.voice.recorder import VoiceRecorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, GoalMetres, Health, NavState, NavStatus
from sim.courtyard import connected, dilate, make_courtyard
from sim.node import SimNode


def settle() -> None:
    time.sleep(0.15)  # a new subscriber's declaration reaches the daemon


def walk_users(daemon, scenario, goals: dict[str, Goal], client):
    """One SimNode per user on its own session and thread; goals sent by ``client``."""
    sessions = {u: daemon.peer() for u in goals}
    nodes = {u: SimNode(sessions[u], u, scenario) for u in goals}
    results: dict = {}
    stop = threading.Event()
    threads = [
        threading.Thread(target=lambda u=u: results.__setitem__(u, nodes[u].run(stop, 10**4, 40)))
        for u in goals
    ]
    try:
        for t in threads:
            t.start()
        time.sleep(0.3)  # the map and the first poses reach the daemon before the goals
        for user, goal in goals.items():
            wire.put(client, T.GOAL, user, codec.encode(goal))
        for t in threads:
            t.join(45)
    finally:
        stop.set()
        for t in threads:
            t.join(5)
        for s in sessions.values():
            s.close()
    assert not any(t.is_alive() for t in threads)
    return results


def distance_m(scenario, cell, goal) -> float:
    return math.hypot(cell[0] - goal[0], cell[1] - goal[1]) * scenario.cell_m


@pytest.mark.timeout(120)
def test_goal_from_another_session_guides_the_user_to_arrival(daemon, peer):
    scenario = make_courtyard(100, 0.4, seed=0)
    belt, voice = BeltRecorder(peer, "alice"), VoiceRecorder(peer, "alice")
    settle()
    goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=time.time())
    result = walk_users(daemon, scenario, {"alice": goal}, peer)["alice"]
    assert result.arrived, result.reason
    assert result.last_status.state == NavState.ARRIVED
    assert distance_m(scenario, result.walked[-1], scenario.goal) <= 0.5
    assert result.steps > 80  # the garden forces a detour: no straight 8.7 m dash
    assert belt.wait_for(lambda r: r.msg.kind == "arrived", 2.0) is not None
    assert "guide" in belt.kinds()
    assert voice.texts(), "guidance spoke no cue at all"
    # The daemon's health and the liveliness token are there for drivers.
    health = [r.ok for r in wire.get(peer, T.HEALTH) if r.ok is not None]
    assert "alice" in codec.decode(Health, health[0].payload.to_bytes()).users
    alive = wire.alive(peer, T.ALIVE)
    assert any(r.ok is not None for r in alive)
    belt.close()
    voice.close()


@pytest.mark.timeout(120)
def test_two_users_with_different_goals_both_arrive(daemon, peer):
    scenario = make_courtyard(100, 0.4, seed=1)
    blocked = dilate(scenario.true == 1, scenario.radius_cells)
    # A second goal half-way up, reachable through the dense 40 % courtyard.
    reachable = [
        (r, c)
        for r in range(20, 45, 2)
        for c in range(4, 96, 2)
        if not blocked[r, c] and connected(blocked, scenario.start, (r, c))
    ]
    other = max(reachable, key=lambda rc: abs(rc[1] - scenario.goal[1]))
    x, y = (other[1] + 0.5) * scenario.cell_m, (100 - other[0] - 0.5) * scenario.cell_m
    goals = {
        "bob": Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=time.time()),
        "carol": Goal(target=GoalMetres(x=x, y=y), stamp=time.time()),
    }
    results = walk_users(daemon, scenario, goals, peer)
    for user, target in (("bob", scenario.goal), ("carol", other)):
        assert results[user].arrived, (user, results[user].reason)
        assert distance_m(scenario, results[user].walked[-1], target) <= 0.5
    # Different goals, different walks.
    assert results["bob"].walked[-1] != results["carol"].walked[-1]
    replies = [r.ok for r in wire.get(peer, T.STATUS_QUERY) if r.ok is not None]
    states = {
        T.user_of(r.key_expr): codec.decode(NavStatus, r.payload.to_bytes())
        for r in replies
    }
    assert states["bob"].state == states["carol"].state == NavState.ARRIVED
