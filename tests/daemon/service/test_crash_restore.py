"""The fault test: ``guidebelt run`` is SIGKILLed mid-walk and started again; the simulated
user still arrives, with no client action, and the daemon's map ends equal to the truth.

And the client's side of a restart: a goal sender that sees the daemon's liveliness token
come back sends its goal again, so a daemon that kept nothing still gets it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from daemon.planning.grid import OCCUPIED
from daemon.service import embedded
from daemon.service.embedded import DaemonThread, free_port, open_peer
from drivers.belt.recorder import Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapSnapshot, NavPath, NavStatus
from sim.courtyard import make_courtyard
from sim.node import SimNode, SimResult

ROOT = Path(__file__).resolve().parents[3]
USER = "walker"


def start_daemon(config: Path, log: Path) -> subprocess.Popen:
    env = {**os.environ, "GUIDEBELT_CONFIG": str(config), "PYTHONPATH": str(ROOT)}
    env.pop("NOTIFY_SOCKET", None)
    with log.open("ab") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "cli.app", "run"], cwd=ROOT, env=env, stdout=out,
            stderr=subprocess.STDOUT,
        )  # fmt: skip


def wait_alive(peer, proc: subprocess.Popen, timeout_s: float) -> None:
    end = time.monotonic() + timeout_s
    while not wire.alive(peer, T.ALIVE, timeout=0.5):
        assert proc.poll() is None, "the daemon exited"
        assert time.monotonic() < end, "the daemon did not come up"
        time.sleep(0.1)


def daemon_map(peer) -> np.ndarray | None:
    for reply in wire.get(peer, T.MAP_SNAPSHOT, USER, timeout=2.0):
        if reply.ok is not None:
            return codec.decode(MapSnapshot, reply.ok.payload.to_bytes()).array()
    return None


def obstacle_ahead(node: SimNode, result: SimResult) -> None:
    """Something new stands within a metre ahead: the mapper sees and publishes it while the
    daemon is down, so only the restore's snapshot can bring it to the daemon."""
    world = node.world
    r, c = world.cell()
    seen = world.sensor.visible(world.shape, (r, c), world.walker.heading)
    rows, cols = np.unravel_index(seen, world.shape)
    near = (np.hypot(rows - r, cols - c) > 6) & (np.hypot(rows - r, cols - c) < 10)
    free = seen[near & (world.true.reshape(-1)[seen] != OCCUPIED)]
    world.true.reshape(-1)[free[:: max(1, len(free) // 4)][:4]] = OCCUPIED
    with node._map_lock:
        deltas = node.world.sense(time.time())
    for d in deltas:
        node._put_delta(d)
    result.actions["lost_deltas"] = len(deltas)


@pytest.mark.timeout(90)
def test_sigkill_mid_walk_restart_and_the_user_arrives_with_nothing_lost(tmp_path):
    port = free_port()
    config = tmp_path / "guidebelt.toml"
    config.write_text(
        'backend = "cpu"\n'
        f'state_dir = "{tmp_path / "state"}"\n'
        "persist_map_s = 0.5\n"
        "guide_hz = 100\n"  # a pose re-guides at once: the lock-step walk is not paced to 10 Hz
        "snapshot_timeout_s = 1.0\n"
        "[zenoh]\n"
        f'listen = ["tcp/127.0.0.1:{port}"]\n'
        "multicast_scouting = false\n"
    )
    log = tmp_path / "daemon.log"
    scenario = make_courtyard(100, 0.2, seed=1)
    procs = [start_daemon(config, log)]
    session = open_peer(port)
    node = SimNode(session, USER, scenario, pose_period_s=0.2)
    statuses: Recorder[NavStatus] = Recorder(session, T.STATUS, USER)
    paths: Recorder[NavPath] = Recorder(session, T.PATH, USER)
    stop = threading.Event()
    box: dict[str, SimResult] = {}
    walk = threading.Thread(target=lambda: box.update(r=node.run(stop, timeout_s=60)))
    try:
        wait_alive(session, procs[0], 40.0)
        time.sleep(0.2)  # the recorder's subscription reaches the daemon
        killed_at: list[int] = []
        kill_time: list[float] = []
        kill_clock: list[float] = []

        def crash(result: SimResult) -> None:
            if result.steps == 10 and not killed_at:
                procs[0].send_signal(signal.SIGKILL)
                procs[0].wait(5)
                killed_at.append(result.steps)
                kill_time.append(time.time())
                kill_clock.append(time.perf_counter())
                obstacle_ahead(node, result)
                procs.append(start_daemon(config, log))  # as systemd's Restart= would

        walk = threading.Thread(
            target=lambda: box.update(r=node.run(stop, timeout_s=60, on_step=crash))
        )
        walk.start()
        time.sleep(0.3)  # the map and the first pose before the goal
        # The goal is sent once, here: the node is no goal sender, so only the store has it
        # after the crash.
        goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=1.0)
        wire.put(session, T.GOAL, USER, codec.encode(goal))
        walk.join(70)
        assert not walk.is_alive()
        result = box["r"]
        assert killed_at == [10] and procs[0].returncode == -signal.SIGKILL
        assert result.arrived, (result.reason, result.steps, log.read_text()[-3000:])
        assert result.walked[-1] != result.walked[0] and result.actions["lost_deltas"] >= 1
        # Never guided on a pre-crash pose: every path after the crash is planned from a newer.
        after = [r.msg for r in paths.received if r.msg.stamp > kill_time[0]]
        assert after and all(p.pose_stamp > kill_time[0] for p in after)
        first = min(r.at for r in paths.received if r.msg.stamp > kill_time[0])
        print(f"SIGKILL to the first path of the restarted daemon: {first - kill_clock[0]:.2f} s")
        text = log.read_text()
        assert "guidebelt.state: session restored" in text and "user=walker" in text
        # The map the daemon ends with is what the mapper published, the lost deltas too.
        final = daemon_map(session)
        assert final is not None and np.array_equal(final, result.known)
    finally:
        stop.set()
        if walk.is_alive():
            walk.join(5)
        statuses.close()
        paths.close()
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait(5)
        session.close()
    assert all(p.poll() is not None for p in procs)


@pytest.mark.timeout(60)
def test_a_goal_sender_resends_its_goal_when_the_daemon_comes_back(monkeypatch):
    """A daemon that kept nothing (no state_dir) still gets the goal again from the client, and
    the map: the mapper's last delta sent again shows it a gap, and it asks for the snapshot."""
    port = free_port()
    monkeypatch.setattr(embedded, "free_port", lambda: port)  # both daemons on one port
    scenario = make_courtyard(100, 0.2, seed=2)
    goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=1.0)
    first = DaemonThread(backend="cpu", guide_hz=100).__enter__()
    session = open_peer(port)
    node = SimNode(session, USER, scenario, pose_period_s=0.2, goal=goal)
    stop = threading.Event()
    box: dict[str, SimResult] = {}
    restarted: list[DaemonThread] = []

    def restart(result: SimResult) -> None:
        if result.steps == 8 and not restarted:
            first.stop()
            restarted.append(DaemonThread(backend="cpu", guide_hz=100).__enter__())

    walk = threading.Thread(target=lambda: box.update(r=node.run(stop, 10**4, 40, restart)))
    try:
        walk.start()
        walk.join(45)
        assert not walk.is_alive()
        assert restarted and box["r"].arrived, (
            box["r"].reason,
            box["r"].steps,
            node.goals_sent,
            box["r"].last_status,
        )
        assert node.goals_sent >= 2  # once at the start, once when the new daemon appeared
    finally:
        stop.set()
        walk.join(5)
        session.close()
        first.stop()
        for d in restarted:
            d.stop()
