"""``workers = N``: the users shared among worker processes behind one router.

One ``guidebelt run`` with two workers, under mutual TLS and access rules as shipped: the
workers' private endpoint lets in no one without a certificate; a user who sends only poses
is found through the parent; in a simulated walk the user's worker is SIGKILLed, the user
hears STOP and ``internal``, the token goes (clients learn of the restart), the worker comes
back, restores the session from the state database and the user arrives with no client
action; another user's certificate, by either endpoint, neither sets the walker's goal nor
drives the belt; health lists the users; SIGTERM stops every process.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import sqlite3
import threading
import time
from pathlib import Path

import pytest
import zenoh

from daemon.service.embedded import free_port
from daemon.service.workers import owner_of
from drivers.belt.recorder import Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.deployment import certify, to_toml
from protocol.messages import (
    BeltPattern,
    Goal,
    GoalCell,
    Health,
    NavStatus,
    PatternKind,
    Pose,
)
from protocol.settings import ZenohSettings, load_node_settings
from protocol.topics import Role
from sim.courtyard import make_courtyard
from sim.node import SimNode, SimResult

from .test_crash_restore import start_daemon, wait_alive
from .test_workers import _wait_gone

USER = "walker"


def _workers_of(pid: int) -> dict[int, int]:
    """Worker index → pid, of the daemon ``pid``'s live workers."""
    out = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            argv = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
            stat = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(stat[1]) == pid and b"daemon.service.worker_main" in argv and stat[0] != "Z":
            out[int(argv[argv.index(b"daemon.service.worker_main") + 1])] = int(entry)
    return out


def _goal_stored(state_dir: Path, user: str) -> bool:
    with contextlib.closing(sqlite3.connect(state_dir / "state.db", timeout=1.0)) as db:
        row = db.execute("SELECT goal FROM sessions WHERE user = ?", (user,)).fetchone()
    return row is not None and row[0] is not None


def _users_after_poses_alone(session, user: str, timeout_s: float) -> list[str]:
    """Send ``user``'s poses, nothing else (no worker subscribes to them yet: the parent
    hands one over), until health lists the user; the users health lists then."""
    end = time.monotonic() + timeout_s
    users: list[str] = []
    while time.monotonic() < end and user not in users:
        pose = Pose(x=1.0, y=1.0, heading=0.0, stamp=time.time())
        wire.put(session, T.POSE, user, codec.encode(pose))
        for reply in wire.get(session, T.HEALTH, timeout=1.0):
            if reply.ok is not None:
                users = codec.decode(Health, reply.ok.payload.to_bytes()).users
        time.sleep(0.05)
    return users


def _private_endpoint(log: Path) -> str:
    found = re.search(r"private=(tls/127\.0\.0\.1:\d+)", log.read_text())
    assert found, log.read_text()[-2000:]
    return found.group(1)


def _cannot_connect(root: Path, endpoint: str) -> None:
    """Plain TCP, and TLS offering no certificate (the CA trusted): the workers' endpoint
    lets in no one the deployment did not certify."""
    plain = ZenohSettings(mode="client", connect=[endpoint.replace("tls/", "tcp/")])
    with pytest.raises(zenoh.ZError):
        wire.open_session(plain).close()
    no_cert = {
        "mode": "client",
        "connect": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}},
        "transport": {"link": {"tls": {"root_ca_certificate": str(root / "ca.pem")}}},
    }
    with pytest.raises(zenoh.ZError):
        zenoh.open(zenoh.Config.from_json5(json.dumps(no_cert))).close()


def _attack(ann: zenoh.Session, back: tuple[int, int]) -> BeltPattern:
    """ann's phone puts the walker's goal (back where the walk started) and drives the
    walker's belt: the forged pattern, to look for on the belt (no step of the daemon's
    sends this sequence number)."""
    far = Goal(target=GoalCell(row=back[0], col=back[1]), stamp=time.time())
    wire.put(ann, T.GOAL, USER, codec.encode(far))
    forged = BeltPattern(
        seq=987_654, map_seq=0, kind=PatternKind.GUIDE, motors=(201, 0, 201, 0), ttl_ms=5000,
        stamp=time.time(),
    )
    wire.put(ann, T.BELT, USER, codec.encode(forged))
    return forged


@pytest.mark.timeout(120)
def test_two_workers_under_tls_guide_a_walk_through_a_worker_crash_and_stop_on_sigterm(tmp_path):
    """The shipped config's way: mutual TLS and access rules, the workers on a private
    tls/ endpoint with the daemon's certificate. ann (a user's certificate) tries to take
    the walker's goal and belt through the public endpoint and the private one."""
    port = free_port()
    certs = tmp_path / "tls"
    nodes = {n.common_name: n for n in certify(certs, [USER, "poser", "ann"], [Role.SIM])}
    table = load_node_settings(nodes["daemon"].toml)
    table = table.model_copy(update={"listen": [f"tls/127.0.0.1:{port}"]})
    config = tmp_path / "guidebelt.toml"
    config.write_text(
        'backend = "cpu"\n'
        "workers = 2\n"
        f'state_dir = "{tmp_path / "state"}"\n'
        "persist_map_s = 0.5\n"
        "cell_m = 0.2\n"  # the 10 m courtyard on 50² cells
        "guide_hz = 100\n" + to_toml(table)
    )
    log = tmp_path / "daemon.log"
    scenario = make_courtyard(50, 0.2, seed=3)
    proc = start_daemon(config, log)

    opened: list[zenoh.Session] = []

    def client(cn: str, endpoint: str) -> zenoh.Session:
        # Clients, so the router carries everything between them: what it does not forward
        # is what its rules refused, not a quirk of peers that never met (test_tls_access).
        node = load_node_settings(nodes[cn].toml)
        update = {"mode": "client", "connect": [endpoint]}
        opened.append(wire.open_session(node.model_copy(update=update)))
        return opened[-1]

    public = f"tls/127.0.0.1:{port}"
    end = time.monotonic() + 60.0
    while True:  # a client does not wait for the router to listen: try until it does
        try:
            session = client("sim", public)  # the walker's phone, RFID node and belt
            break
        except zenoh.ZError:
            assert proc.poll() is None and time.monotonic() < end, "the daemon did not listen"
            time.sleep(0.2)
    node = SimNode(session, USER, scenario, pose_period_s=0.2)
    statuses: Recorder[NavStatus] = Recorder(session, T.STATUS, USER)
    belts: Recorder[BeltPattern] = Recorder(session, T.BELT, USER)
    stop = threading.Event()
    box: dict[str, SimResult] = {}
    killed: list[float] = []
    health: list[Health] = []
    try:
        wait_alive(session, proc, 60.0)
        tokens_gone: list[float] = []

        def on_token(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.DELETE:
                tokens_gone.append(time.time())

        watch = wire.watch_liveliness(session, T.ALIVE, on_token)
        workers = _workers_of(proc.pid)
        assert sorted(workers) == [0, 1]
        mine = workers[owner_of(USER, 2)]
        private = _private_endpoint(log)
        _cannot_connect(certs, private)
        assert "poser" in _users_after_poses_alone(session, "poser", 5.0)
        anns = [client("user:ann", at) for at in (public, private)]  # by either endpoint

        def crash(result: SimResult) -> None:
            # Once the store has the goal (no client here resends it): a kill before the
            # commit (0.25 s) would test the clients' resend, which this walker does not do.
            if result.steps >= 10 and not killed and _goal_stored(tmp_path / "state", USER):
                for reply in wire.get(session, T.HEALTH, timeout=2.0):
                    if reply.ok is not None:
                        health.append(codec.decode(Health, reply.ok.payload.to_bytes()))
                os.kill(mine, signal.SIGKILL)
                killed.append(time.time())

        walk = threading.Thread(
            target=lambda: box.update(r=node.run(stop, timeout_s=60, on_step=crash))
        )
        walk.start()
        time.sleep(0.3)  # the map and the first pose first: the parent hands them over
        goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=1.0)
        wire.put(session, T.GOAL, USER, codec.encode(goal))  # once: after the crash, the store
        walk.join(80)
        assert not walk.is_alive()
        result = box["r"]
        text = log.read_text()
        assert killed and result.arrived, (result.reason, result.steps, text[-3000:])
        # After the restart ann sends the walker a goal back at the start, and a pattern.
        attacked = time.time()
        forged = [_attack(ann, scenario.start) for ann in anns]
        time.sleep(1.0)  # her goal would have been planned for, her pattern played, by now
        assert [
            (r.msg.state, r.msg.code) for r in statuses.received if r.msg.stamp > attacked
        ] == []
        assert [r for r in belts.received if r.msg.seq == forged[0].seq] == []
        assert health and health[0].users == sorted(["poser", USER])
        after = [r.msg for r in statuses.received if r.msg.stamp > killed[0]]
        assert any(s.code == "internal" for s in after), [s.code for s in after]
        stops = [r.msg for r in belts.received if r.msg.stamp > killed[0]]
        assert stops and stops[0].kind is PatternKind.STOP
        assert "worker died" in text and "session restored" in text
        assert tokens_gone and tokens_gone[0] > killed[0]  # the clients learn of the restart
        workers = _workers_of(proc.pid)
        assert sorted(workers) == [0, 1] and workers[owner_of(USER, 2)] != mine
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(10) == 0
        assert _wait_gone(list(workers.values()), 5.0)
    finally:
        stop.set()
        statuses.close()
        belts.close()
        if "watch" in locals():
            watch.undeclare()
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        for s in opened:
            s.close()
