"""``workers = N``: the users shared among worker processes behind one router — the
pieces: who owns a user, a worker's config and endpoint, its liveliness token, the first
samples handed over, a worker that dies with its parent. The whole daemon under TLS with a
walk through a worker's crash: ``test_workers_tls_walk.py``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import zenoh

from daemon.service.config import DaemonConfig
from daemon.service.embedded import free_port
from daemon.service.supervisor import Supervisor, private_endpoint
from daemon.service.workers import Worker, owner_of, worker_config
from protocol import session as wire
from protocol import topics as T

ROOT = Path(__file__).resolve().parents[3]
USER = "walker"


def test_a_user_belongs_to_one_worker_the_same_after_a_restart_and_users_spread():
    assert owner_of(USER, 2) == owner_of(USER, 2)
    counts = [0, 0, 0]
    for i in range(300):
        counts[owner_of(f"load{i:03d}", 3)] += 1
    assert all(70 <= c <= 130 for c in counts), counts


def test_a_worker_is_a_client_of_the_parents_private_endpoint_with_its_share_of_the_daemon():
    config = DaemonConfig(workers=2, backend="cpu", state_dir=None)
    assert private_endpoint(config.zenoh).startswith("tcp/127.0.0.1:")
    worker = DaemonConfig(**json.loads(worker_config(config, "tcp/127.0.0.1:9")))
    assert worker.workers == 0 and worker.zenoh.mode == "client"
    assert worker.zenoh.connect == ["tcp/127.0.0.1:9"] and worker.zenoh.listen == []
    assert worker.step_workers == max(1, (os.cpu_count() or 1) // 2)
    assert worker.backend == "cpu" and worker.memory_budget_mb == config.memory_budget_mb / 2


def test_under_tls_a_worker_dials_tls_with_the_daemons_certificate_and_enforces_nothing():
    tls = {"root_ca": "ca.pem", "certificate": "daemon.pem", "private_key": "daemon.key"}
    zenoh_table = {"listen": ["tls/127.0.0.1:7447"], "tls": tls, "access": {"users": ["ann"]}}
    config = DaemonConfig(workers=2, zenoh=zenoh_table, state_dir=None)  # no longer refused
    endpoint = private_endpoint(config.zenoh)
    assert endpoint.startswith("tls/127.0.0.1:")
    worker = DaemonConfig(**json.loads(worker_config(config, endpoint)))
    assert worker.zenoh.connect == [endpoint] and worker.zenoh.tls == config.zenoh.tls
    assert worker.zenoh.access is None  # the router's rules are the ones that hold


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"  # a zombie no one reaped yet
    except FileNotFoundError:
        return True


def _wait_gone(pids: list[int], timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while not all(_gone(p) for p in pids):
        if time.monotonic() > end:
            return False
        time.sleep(0.05)
    return True


def _wait_for(seen: list, item: tuple, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while item not in seen and time.monotonic() < deadline:
        time.sleep(0.02)
    assert item in seen, seen


@pytest.mark.timeout(30)
def test_a_worker_whose_token_goes_while_its_process_lives_is_killed():
    """The per-worker token: a worker whose session is gone would leave its users in silence;
    the parent kills it, so its exit tells them STOP and ``internal`` and starts it again. A
    token of a process since replaced, or one going while the daemon stops, changes nothing."""
    port = free_port()
    parent = wire.open_session(wire.loopback(listen_port=port))
    worker_side = wire.open_session(wire.loopback(connect_port=port))
    sleeper = [sys.executable, "-c", "import time; time.sleep(30)"]
    procs = [subprocess.Popen(sleeper), subprocess.Popen(sleeper)]
    seen: list[tuple[int, int, bool]] = []
    watch = wire.watch_workers(parent, lambda *change: seen.append(change))
    try:
        sup = Supervisor(DaemonConfig(workers=2, backend="cpu", state_dir=None))
        sup.workers = [Worker(i, 2, "{}") for i in range(2)]
        for w, proc in zip(sup.workers, procs, strict=True):
            w.proc, w.ready = proc, True
        tokens = [wire.declare_worker_token(worker_side, i, p.pid) for i, p in enumerate(procs)]
        stale = wire.declare_worker_token(worker_side, 0, 4_000_000)  # no such process now
        for i, p in enumerate(procs):
            _wait_for(seen, (i, p.pid, True))
            sup._on_token(i, p.pid, True)
        assert all(w.serving for w in sup.workers)
        stale.undeclare()
        _wait_for(seen, (0, 4_000_000, False))
        sup._on_token(0, 4_000_000, False)
        assert procs[0].poll() is None and sup.workers[0].serving
        tokens[0].undeclare()
        _wait_for(seen, (0, procs[0].pid, False))
        sup._on_token(0, procs[0].pid, False)
        assert procs[0].wait(5) == -signal.SIGKILL and not sup.workers[0].serving
        sup._stopping = True  # SIGTERM: the workers' tokens go as they close, as asked
        tokens[1].undeclare()
        _wait_for(seen, (1, procs[1].pid, False))
        sup._on_token(1, procs[1].pid, False)
        assert procs[1].poll() is None
    finally:
        watch.undeclare()
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait(5)
        worker_side.close()
        parent.close()


class _Sample:
    def __init__(self, key: str, payload: bytes) -> None:
        self.key_expr, self.kind = key, zenoh.SampleKind.PUT
        self.payload = zenoh.ZBytes(payload)


def test_the_first_delta_of_a_user_is_handed_over_even_once_a_worker_serves_the_user():
    """A worker that met the user by the goal subscribed to its deltas after the first one
    went by; without it, it would ask for a snapshot. Later deltas of a served user, and
    poses, are not handed over (the worker hears them itself)."""
    sup = Supervisor(DaemonConfig(workers=2, backend="cpu", state_dir=None))
    sup.workers = [Worker(i, 2, "{}") for i in range(2)]
    handed: list[tuple[int, str, bytes]] = []
    for w in sup.workers:
        w.hand = lambda key, payload, arrived, i=w.index: handed.append((i, key, payload))  # type: ignore[method-assign]
    owner = owner_of(USER, 2)
    delta, pose = T.MAP_DELTA.key(USER), T.POSE.key(USER)
    sup._known = frozenset({delta, pose})  # the worker reported serving the user
    sup._first(_Sample(delta, b"seq 0"), 1.0)
    sup._first(_Sample(delta, b"seq 1"), 1.0)
    sup._first(_Sample(pose, b"pose"), 1.0)
    assert handed == [(owner, delta, b"seq 0")]
    other = "nobody"  # not served yet: its first pose is handed over, as before
    sup._first(_Sample(T.POSE.key(other), b"pose"), 1.0)
    assert handed[-1] == (owner_of(other, 2), T.POSE.key(other), b"pose")


@pytest.mark.timeout(30)
def test_a_workers_stdin_holds_every_users_first_delta_of_a_start():
    """50 walls deltas of 4 KB, base64 in JSON lines, are ~275 KB: the default 64 KB pipe
    dropped half of them (``Worker.hand`` never blocks the loop)."""
    import fcntl

    from daemon.service.workers import PIPE_BYTES

    worker = Worker(0, 1, "not a config: the worker exits at once")
    worker.start(lambda *_: None, lambda *_: None)
    try:
        assert worker.proc is not None and worker.proc.stdin is not None
        assert PIPE_BYTES >= 50 * 6000
        assert fcntl.fcntl(worker.proc.stdin.fileno(), fcntl.F_GETPIPE_SZ) >= PIPE_BYTES
    finally:
        assert worker.proc is not None
        worker.proc.kill()
        worker.proc.wait(10)


@pytest.mark.timeout(30)
def test_a_worker_dies_with_its_parent_even_a_sigkilled_one(tmp_path):
    """PDEATHSIG: the parent cannot stop its workers when it is SIGKILLed; the kernel does."""
    script = textwrap.dedent(f"""
        import subprocess, sys, time
        code = ("import os, sys, time; sys.path.insert(0, {str(ROOT)!r}); "
                "from daemon.service.workers import die_with; die_with(int(sys.argv[1])); "
                "print(os.getpid(), flush=True); time.sleep(60)")
        child = subprocess.Popen([sys.executable, "-c", code, str(__import__("os").getpid())])
        time.sleep(60)
    """)
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE)
    try:
        assert parent.stdout is not None
        worker = int(parent.stdout.readline())
        assert not _gone(worker)
        parent.kill()
        parent.wait(5)
        assert _wait_gone([worker], 10.0)
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait(5)
