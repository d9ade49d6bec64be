"""The daemon's worker processes: a whole ``Daemon`` that serves only the users it owns
(``WorkerRole``), and the parent's handle on one (``Worker``).

With ``workers = N`` the users are shared among N processes, each with its own GIL, asyncio
loop and zenoh session (``supervisor.py`` starts them). A user belongs to worker
``crc32(user) % N``: the same worker after a restart, so it finds the user's session in the
state database. A worker subscribes to its own users' poses and map deltas only (no sample
of another worker's user is sent to it, nor crosses a pipe), and to every user's rarer inputs
(goals, buttons, settings, belt health, proximity), keeping its own. The parent hands it the
first sample of a user it has not heard yet (a user whose first input is a pose) on its stdin;
the worker tells the parent which users it serves, with their health, every tick, on a pipe.

A worker stops on SIGTERM, when its stdin closes, or when its parent dies (PDEATHSIG).
Its process starts in ``worker_main.py``.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import ctypes
import fcntl
import json
import logging
import os
import signal
import subprocess
import sys
import threading
import zlib
from typing import Any, Protocol

from protocol import session as wire
from protocol import topics as T
from protocol.messages import Health
from protocol.topics import Topic

from .config import DaemonConfig


class Served(Protocol):
    """The daemon, as its role sees it (the daemon imports this module, not the reverse)."""

    def health(self) -> Health: ...
    def hear(self, topic: Topic, key: str, payload: bytes, arrived: float) -> None: ...
    def stop(self) -> None: ...


log = logging.getLogger("guidebelt.worker")

PR_SET_PDEATHSIG = 1
PIPE_BYTES = 1 << 20
"""A worker's stdin pipe (the samples handed over): Linux's default largest unprivileged size."""


def owner_of(user: str, workers: int) -> int:
    """The worker that serves ``user`` (stable across restarts, for the same ``workers``)."""
    return zlib.crc32(user.encode()) % workers


def encode_sample(key: str, payload: bytes, arrived: float) -> bytes:
    """One line on a worker's stdin: a sample the parent heard for one of its users."""
    text = base64.b64encode(payload).decode()
    return json.dumps({"key": key, "payload": text, "arrived": arrived}).encode() + b"\n"


class WorkerRole:
    """What makes a ``Daemon`` one worker among several (its ``worker`` argument)."""

    def __init__(self, index: int, count: int, report_fd: int) -> None:
        self.index = index
        self.count = count
        self._out = os.fdopen(report_fd, "wb", buffering=0)

    def owns(self, user: str) -> bool:
        return owner_of(user, self.count) == self.index

    def serving(self, daemon: Served, loop: asyncio.AbstractEventLoop, session: Any) -> None:
        """The daemon listens: hold this worker's token on its zenoh session (the parent
        watches it: a worker whose session is gone is a dead worker, even if its process
        lives), tell the parent, and take the samples it hands over."""
        self._token = wire.declare_worker_token(session, self.index, os.getpid())
        self._send({"ready": True})
        threading.Thread(
            target=self._read_parent, args=(daemon, loop), name="parent", daemon=True
        ).start()

    def report(self, daemon: Served) -> None:
        """Each tick: the users served here and their health, for the parent's health answer
        and its routing of new users."""
        self._send({"health": daemon.health().model_dump(mode="json")})

    def _send(self, message: dict[str, Any]) -> None:
        # The parent gone: its end of stdin stops this worker.
        with contextlib.suppress(BrokenPipeError, ValueError):
            self._out.write(json.dumps(message).encode() + b"\n")

    def _read_parent(self, daemon: Served, loop: asyncio.AbstractEventLoop) -> None:
        for line in sys.stdin.buffer:
            try:
                msg = json.loads(line)
                key, arrived = str(msg["key"]), float(msg["arrived"])
                topic, payload = T.topic_of(key), base64.b64decode(msg["payload"])
            except (ValueError, KeyError, TypeError) as exc:  # the parent's bug: say it, go on
                log.error("bad line from the parent", extra={"fields": {"err": str(exc)[:200]}})
                continue
            with contextlib.suppress(RuntimeError):  # the loop closed: stopping
                loop.call_soon_threadsafe(daemon.hear, topic, key, payload, arrived)
        # stdin closed: the parent is gone or wants us gone; stop as on SIGTERM.
        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(daemon.stop)


def die_with(parent: int) -> None:
    """SIGTERM this process when its parent dies (Linux), even by SIGKILL: a worker never
    outlives the daemon. Checked once after: the parent may have died before the call."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:
        os._exit(1)


SYSTEMD_ENV = ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID")
"""Only the parent speaks to systemd (``NotifyAccess=main``)."""


class Worker:
    """One worker process: started, heard, and started again by the supervisor."""

    def __init__(self, index: int, count: int, config_json: str) -> None:
        self.index, self.count = index, count
        self._config_json = config_json
        self.proc: subprocess.Popen[bytes] | None = None
        self.health: dict[str, Any] | None = None
        """Its latest report (``Health`` as JSON); None until its first."""
        self.ready = False
        """It said it serves (on its report pipe)."""
        self.token_pid: int | None = None
        """The process whose token the parent sees now (``WORKER_ALIVE``)."""
        self.reported_at = 0.0
        """When its latest report came (monotonic)."""

    @property
    def serving(self) -> bool:
        """Ready, and its token seen: its session reaches the router (under the access rules
        too), so its users' samples reach it."""
        return self.ready and self.proc is not None and self.token_pid == self.proc.pid

    def start(self, on_report: Any, on_exit: Any) -> None:
        read, write = os.pipe()
        env = {k: v for k, v in os.environ.items() if k not in SYSTEMD_ENV}
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
        argv = [sys.executable, "-m", "daemon.service.worker_main"]
        argv += [str(self.index), str(self.count), str(write), str(os.getpid())]
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, pass_fds=(write,), env=env)
        os.close(write)
        self.ready, self.health = False, None
        assert self.proc.stdin is not None
        self.proc.stdin.write(self._config_json.encode() + b"\n")
        self.proc.stdin.flush()
        os.set_blocking(self.proc.stdin.fileno(), False)  # the loop never waits on a worker
        # Room for every user's first delta at a start (50 walls deltas of 4 KB, base64 in
        # JSON: ~275 KB) where the default 64 KB dropped half of them (Linux; best effort).
        with contextlib.suppress(OSError, AttributeError):
            fcntl.fcntl(self.proc.stdin.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
        proc = self.proc
        threading.Thread(
            target=self._listen, args=(read, proc, on_report, on_exit), daemon=True,
            name=f"worker-{self.index}",
        ).start()  # fmt: skip

    def _listen(self, fd: int, proc: subprocess.Popen[bytes], on_report: Any, on_exit: Any) -> None:
        with os.fdopen(fd, "rb") as reports:
            for line in reports:
                with contextlib.suppress(ValueError):
                    on_report(self, proc, json.loads(line))
        proc.wait()
        if proc.stdin is not None:
            with contextlib.suppress(OSError):
                proc.stdin.close()
        on_exit(self, proc)

    def hand(self, key: str, payload: bytes, arrived: float) -> None:
        """Give the worker a sample it was not subscribed to (dropped if its pipe is full: a
        pose comes again in 50 ms, a delta's gap brings a snapshot)."""
        proc = self.proc
        if proc is None or proc.stdin is None:
            return
        with contextlib.suppress(OSError, ValueError):
            proc.stdin.write(encode_sample(key, payload, arrived))
            proc.stdin.flush()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(signal.SIGTERM)

    def users(self) -> list[str]:
        return list(self.health.get("users", [])) if self.health else []


def worker_config(config: DaemonConfig, endpoint: str) -> str:
    """A worker's config: the daemon's, connected to the parent's private endpoint; its step
    slots and its maps' memory its share of the daemon's. ``max_users`` stays each worker's
    (users are not spread evenly by name): at most ``workers`` × as many sessions."""
    share = max(1, (os.cpu_count() or 1) // config.workers)
    # Under TLS the worker presents the daemon's certificate: the router's rules for it
    # (``protocol.access.WORKER``) are what it may do there. It enforces nothing itself.
    zenoh_cfg = wire.ZenohSettings(mode="client", connect=[endpoint], tls=config.zenoh.tls)
    update = {
        "zenoh": zenoh_cfg,
        "workers": 0,
        "step_workers": config.step_workers or share,
        "memory_budget_mb": config.memory_budget_mb / config.workers,
    }
    return config.model_copy(update=update).model_dump_json()
