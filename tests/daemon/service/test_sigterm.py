"""``guidebelt run`` as a real subprocess: systemd's notify protocol, and SIGTERM."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from daemon.service.embedded import free_port, open_peer
from drivers.belt.recorder import BeltRecorder, Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapDelta, NavStatus, Pose

ROOT = Path(__file__).resolve().parents[3]


def read_notify(sock: socket.socket, want: str, timeout_s: float) -> list[str]:
    """Datagrams from the daemon until one contains ``want``."""
    got: list[str] = []
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        sock.settimeout(max(0.01, end - time.monotonic()))
        try:
            got.append(sock.recv(4096).decode())
        except TimeoutError:
            break
        if any(want in g for g in got):
            return got
    raise AssertionError(f"no {want} from the daemon; got {got}")


@pytest.mark.timeout(120)
def test_sigterm_stops_the_belt_publishes_a_final_status_and_exits_fast(tmp_path):
    port = free_port()
    notify_path = tmp_path / "notify.sock"
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(notify_path))
    env = {
        **os.environ,
        "NOTIFY_SOCKET": str(notify_path),
        "GUIDEBELT_ZENOH__LISTEN": json.dumps([f"tcp/127.0.0.1:{port}"]),
        "GUIDEBELT_ZENOH__MULTICAST_SCOUTING": "false",
        "GUIDEBELT_BACKEND": "cpu",
        "GUIDEBELT_CONFIG": "",
        "GUIDEBELT_STATE_DIR": str(tmp_path / "state"),  # never the system's /var/lib/guidebelt
        "PYTHONPATH": str(ROOT),
    }
    proc = subprocess.Popen(
        [sys.executable, "-m", "cli.app", "run"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    peer = None
    try:
        read_notify(notify, "READY=1", 30.0)
        peer = open_peer(port)
        belt = BeltRecorder(peer, "term")
        status: Recorder[NavStatus] = Recorder(peer, T.STATUS, "term")
        # The daemon declares its subscribers before its liveliness token: once the token is
        # seen here, a put reaches them (a put sent earlier could be dropped: 1 run in ~8).
        deadline = time.monotonic() + 10.0
        while not wire.alive(peer, T.ALIVE, timeout=0.5) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.2)  # the recorders' own subscriptions, declared just now, to the daemon
        walls = np.flatnonzero(np.pad(np.zeros((18, 18), bool), 1, constant_values=True))
        delta = MapDelta.from_arrays(0, (20, 20), walls, np.ones(walls.size), time.time())
        goal = Goal(target=GoalCell(row=6, col=10), stamp=1)
        pose = Pose(x=1.0, y=0.6, heading=0, stamp=time.time())
        wire.put(peer, T.MAP_DELTA, "term", codec.encode(delta))
        wire.put(peer, T.GOAL, "term", codec.encode(goal))
        wire.put(peer, T.POSE, "term", codec.encode(pose))
        # A cold numba cache makes the first step compile: allow for it on a slow machine.
        assert status.wait_for(lambda r: r.msg.state == "guiding", 60.0) is not None

        t0 = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=5.0)
        elapsed = time.perf_counter() - t0
        assert rc == 0
        print(f"exit took {elapsed:.3f} s")
        assert elapsed < 1.0, f"took {elapsed:.2f} s to exit"
        stop = belt.wait_for(lambda r: r.msg.kind == "stop" and r.at > t0, 1.0)
        assert stop is not None, belt.kinds()
        final = status.wait_for(lambda r: r.msg.code == "shutdown", 1.0)
        assert final is not None
        assert final.msg.state == "idle" and final.at > t0
        assert any("STOPPING=1" in d for d in read_notify(notify, "STOPPING=1", 1.0))
        log = proc.stdout.read().decode()
        assert "<6>guidebelt.daemon: ready" in log and "<6>guidebelt.daemon: stopped" in log
        belt.close()
        status.close()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()
        if peer is not None:
            peer.close()
        notify.close()
