"""The daemon with ``workers = N``: the users shared among N worker processes (``workers.py``).

One Python process steps at most a core's worth of users: steps, the asyncio loop and zenoh's
callbacks share its GIL. Here the parent opens the daemon's zenoh session as a *router* on the
configured endpoints plus a private loopback one; each worker is a whole ``Daemon`` connected
to that private endpoint as a zenoh client, with its own GIL and its own subscriptions and
publishers, so the router sends each of its users' samples straight to it and nothing is
copied through a pipe. The parent keeps what is the daemon's as a whole: the liveliness
token (declared while every worker serves), the health answer (the workers' reports
together), systemd's READY and watchdog, and the workers' lives: a worker that dies (or
whose own token, ``WORKER_ALIVE``, goes while it lives: its session lost) is started again,
its users told STOP and ``internal``, and restored by the new worker from the state
database; the daemon's token goes meanwhile, so clients resend what it may not have written.
The parent hears every user's poses and deltas too (it routes them), but only hands a
worker the first sample of a user it does not serve yet, and each user's first delta.
Under ``[zenoh.tls]`` the private endpoint is ``tls/`` too and a worker presents the
daemon's certificate; the router's access rules give that identity the daemon's part of the
topic table for every user, from loopback only (``protocol.access.WORKER``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import subprocess
import threading
import time
from collections.abc import Sequence
from typing import Any

import zenoh

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Health, StatusCode

from .config import DaemonConfig
from .daemon import Observer
from .embedded import free_port
from .queries import say_who_may_connect
from .sdnotify import Notifier
from .state_db import StateDB
from .workers import Worker, owner_of, worker_config

log = logging.getLogger("guidebelt.supervisor")

START_S = 120.0
"""How long the workers may take to serve (each compiles or loads the planner's code)."""
RESTART_S = 1.0
"""A dead worker is started again after this (a worker that dies at once is not a busy loop)."""
STOP_S = 2.0
"""How long a worker may take to tell its users STOP and close after SIGTERM (the unit's
TimeoutStopSec is 3 s)."""
DISCOVER_S = 0.25
"""How often the parent looks for users no worker serves yet among the latest samples."""
DISCOVER_RING = 32
"""Latest poses (and deltas) kept for that look: a user sending 20 poses a second is among
them within a look or two however many others there are, and the parent's Python sees at most
this many samples a look, not each of them (a callback per sample cost the parent 0.05 of a
core at 25 users; dev VM)."""
DELTA_RING = 128
"""Latest deltas kept: every user's first delta may come at once (a map source starting with
50 users), and each one dropped is a snapshot its worker asks for later."""
HANDOVER_S = 0.5
"""A user no worker reported serving yet has at most one sample handed over this often."""
FORGET_FIRST = 10_000
"""Keys remembered for ``HANDOVER_S``: past this many the memory is cleared (junk names)."""


def private_endpoint(settings: wire.ZenohSettings) -> str:
    """Where the workers connect: loopback, on a free port, and under TLS when the daemon is
    (its links accept TLS only, and the workers must be known by certificate to its rules)."""
    scheme = "tls" if settings.tls is not None else "tcp"
    return f"{scheme}/127.0.0.1:{free_port()}"


class Supervisor:
    def __init__(
        self,
        config: DaemonConfig,
        notifier: Notifier | None = None,
        observers: Sequence[Observer] = (),
    ) -> None:
        self.config = config
        self.notifier = notifier if notifier is not None else Notifier()
        self.observers = list(observers)
        self.workers: list[Worker] = []
        self.ready = threading.Event()
        self.restarts = 0
        self.started = time.time()
        self._stop: asyncio.Event | None = None
        self._stopping = False
        self._zenoh: zenoh.Session | None = None
        self._known: frozenset[str] = frozenset()
        """Pose and delta keys of the users some worker serves: not handed over."""
        self._handed: dict[str, float] = {}
        self._deltas_seen: set[str] = set()  # delta keys whose first sample was looked at
        self._token: zenoh.LivelinessToken | None = None

    def stop(self) -> None:
        if self._stop is not None:
            self._stop.set()

    async def run(self, install_signals: bool = True) -> None:
        loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        self._loop = loop
        _prepare_state(self.config)
        say_who_may_connect(self.config.zenoh)
        endpoint = private_endpoint(self.config.zenoh)
        self._zenoh = wire.open_router(self.config.zenoh, endpoint)
        conf = worker_config(self.config, endpoint)
        n = self.config.workers
        self.workers = [Worker(i, n, conf) for i in range(n)]
        entities: list[Any] = [wire.watch_workers(self._zenoh, self._token_cb)]
        observing: list[Any] = []
        try:
            for w in self.workers:
                w.start(self._report_cb, self._exit_cb)
            await self._until_ready()
            rings = [
                wire.declare_subscriber(self._zenoh, t, zenoh.handlers.RingChannel(size))
                for t, size in ((T.POSE, DISCOVER_RING), (T.MAP_DELTA, DELTA_RING))
            ]
            entities += rings
            entities.append(wire.declare_queryable(self._zenoh, T.HEALTH, self._on_health))
            self._alive(True)
            observing = [observe(self._zenoh) for observe in self.observers]
            if install_signals:
                for sig in (signal.SIGTERM, signal.SIGINT):
                    loop.add_signal_handler(sig, self.stop)
            self.notifier.ready(f"serving with {n} workers, backend {self.config.backend}")
            self.ready.set()
            fields = {"workers": n, "zid": str(self._zenoh.zid()), "private": endpoint}
            log.info("ready", extra={"fields": fields})
            tasks = [loop.create_task(self._tick()), loop.create_task(self._discover(rings))]
            try:
                await self._stop.wait()
            finally:
                for task in tasks:
                    task.cancel()
        finally:
            await self._shutdown(entities, observing)
            if install_signals:
                for sig in (signal.SIGTERM, signal.SIGINT):
                    loop.remove_signal_handler(sig)

    async def _until_ready(self) -> None:
        deadline = time.monotonic() + START_S
        while not all(w.serving for w in self.workers):
            if time.monotonic() > deadline or any(
                w.proc and w.proc.poll() is not None for w in self.workers
            ):
                raise RuntimeError("the workers did not start (their log says why)")
            await asyncio.sleep(0.05)

    async def _tick(self) -> None:
        watchdog = self.notifier.watchdog_interval_s()
        period = min(self.config.tick_s, watchdog) if watchdog else self.config.tick_s
        hung_s = max(1.0, 4 * self.config.tick_s)
        while True:
            await asyncio.sleep(period)
            now = time.monotonic()
            # A worker whose loop stopped reporting stops the watchdog: systemd restarts the
            # whole daemon, as it would a daemon of one process whose loop hung.
            if not any(w.ready and now - w.reported_at > hung_s for w in self.workers):
                self.notifier.watchdog()

    async def _discover(self, rings: list[zenoh.Subscriber]) -> None:
        """Each look: the latest poses and deltas of users no worker serves yet go to the
        worker that will. Stamped as arrived at the previous look (they came since): older
        than they are, never fresher."""
        since = time.time()
        while True:
            await asyncio.sleep(DISCOVER_S)
            now = time.time()
            for ring in rings:
                while (sample := ring.try_recv()) is not None:
                    self._first(sample, since)
            since = now

    # -- the workers (their reader threads hand over to the loop) -------------------------

    def _report_cb(self, worker: Worker, proc: subprocess.Popen[bytes], msg: dict) -> None:
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(self._on_report, worker, proc, msg)

    def _exit_cb(self, worker: Worker, proc: subprocess.Popen[bytes]) -> None:
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(self._on_exit, worker, proc)

    def _token_cb(self, index: int, pid: int, alive: bool) -> None:
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(self._on_token, index, pid, alive)

    def _on_token(self, index: int, pid: int, alive: bool) -> None:
        """A worker's token came or went. Gone while its process lives (its session closed
        or its link to this router lost): its users would hear nothing more, so it is killed,
        and its exit (below) tells them STOP and ``internal`` and starts it again."""
        if not 0 <= index < len(self.workers):
            return
        worker = self.workers[index]
        proc = worker.proc
        if proc is None or proc.pid != pid:
            return  # a worker since replaced
        if alive:
            worker.token_pid = pid
            self._all_serving()
            return
        worker.token_pid = None
        if self._stopping or proc.poll() is not None:
            return  # stopping, or dead already: its exit is handled
        log.error(
            "worker's zenoh session gone; killed, its users are stopped",
            extra={"fields": {"worker": index, "pid": pid, "users": len(worker.users())}},
        )
        proc.kill()

    def _all_serving(self) -> None:
        if self.ready.is_set() and all(w.serving for w in self.workers):
            self._alive(True)  # a worker started again serves

    def _on_report(self, worker: Worker, proc: subprocess.Popen[bytes], msg: dict) -> None:
        if proc is not worker.proc:
            return  # from a worker since replaced
        if msg.get("ready"):
            worker.ready = True
            self._all_serving()
        worker.reported_at = time.monotonic()
        if isinstance(msg.get("health"), dict):
            worker.health = msg["health"]
            keys = {
                t.key(u) for w in self.workers for u in w.users() for t in (T.POSE, T.MAP_DELTA)
            }
            self._known = frozenset(keys)

    def _on_exit(self, worker: Worker, proc: subprocess.Popen[bytes]) -> None:
        if self._stopping or proc is not worker.proc:
            return
        users = worker.users()
        log.error(
            "worker died; its users are stopped and it is started again",
            extra={"fields": {"worker": worker.index, "rc": proc.returncode, "users": len(users)}},
        )
        self.restarts += 1
        worker.ready, worker.health = False, None
        # The token goes until the worker serves again: every belt stops, and every client
        # resends its goal when it comes back, as after a crash of the whole daemon. What the
        # worker had not yet written to the state database (up to a commit, 0.25 s) would
        # otherwise be lost without anyone knowing.
        self._alive(False)
        self._halt(users, f"worker {worker.index} died (exit {proc.returncode}); restarting")
        self._loop.call_later(RESTART_S, self._restart, worker)

    def _alive(self, alive: bool) -> None:
        assert self._zenoh is not None
        if alive and self._token is None and not self._stopping:
            self._token = wire.declare_token(self._zenoh, T.ALIVE)
        elif not alive and self._token is not None:
            with contextlib.suppress(zenoh.ZError):
                self._token.undeclare()
            self._token = None

    def _restart(self, worker: Worker) -> None:
        if not self._stopping:
            worker.start(self._report_cb, self._exit_cb)

    def _halt(self, users: list[str], reason: str) -> None:
        """STOP and ``internal`` to each of ``users``, said by the parent: their worker is
        gone and cannot say it. Navigator.halt builds the same words a failed step says."""
        from daemon.navigation import Navigator

        assert self._zenoh is not None
        settings = self.config.navigator_settings()
        now = time.time()
        for user in users:
            if not T.USER_RE.match(user):
                continue
            out = Navigator(user, settings).halt(now, StatusCode.INTERNAL, reason)
            for pattern in out.belt:
                wire.put(self._zenoh, T.BELT, user, codec.encode(pattern))
            for status in out.statuses:
                wire.put(self._zenoh, T.STATUS, user, codec.encode(status))

    def _first(self, sample: zenoh.Sample, arrived: float) -> None:
        """A pose or delta of a user no worker serves yet goes to the worker that will; so does
        a user's first delta, served or not: the worker may have subscribed (on the goal) after
        it went by, and would ask for a snapshot. A copy it has already is skipped in sequence."""
        key = str(sample.key_expr)
        if sample.kind != zenoh.SampleKind.PUT:
            return
        first_delta = key not in self._deltas_seen and T.MAP_DELTA.matches(key)
        if first_delta:
            if len(self._deltas_seen) > FORGET_FIRST:
                self._deltas_seen.clear()
            self._deltas_seen.add(key)
        elif key in self._known:
            return
        now = time.monotonic()
        if now - self._handed.get(key, -HANDOVER_S) < HANDOVER_S:
            return
        try:
            user = T.user_of(key)
        except ValueError:
            return  # the worker refuses and counts it, if it ever hears it: not ours to
        if len(self._handed) > FORGET_FIRST:
            self._handed.clear()
        self._handed[key] = now
        worker = self.workers[owner_of(user, len(self.workers))]
        worker.hand(key, sample.payload.to_bytes(), arrived)

    def _on_health(self, query: zenoh.Query) -> None:
        try:
            wire.reply(query, T.HEALTH, None, codec.encode(self.health()))
        except zenoh.ZError as exc:
            log.warning("health reply failed", extra={"fields": {"err": str(exc)}})
        finally:
            query.drop()

    def health(self) -> Health:
        """The workers' latest reports together (any thread)."""
        reports = [w.health for w in self.workers if w.health is not None]
        by_code: dict[str, int] = {}
        for r in reports:
            for code, count in r.get("rejected_by_code", {}).items():
                by_code[code] = by_code.get(code, 0) + int(count)
        return Health(
            daemon_id=self.config.daemon_id,
            uptime_s=time.time() - self.started,
            users=sorted(u for r in reports for u in r.get("users", [])),
            backend=self.config.backend,
            rejected=sum(int(r.get("rejected", 0)) for r in reports),
            rejected_by_code=by_code,
            log_lines_suppressed=sum(int(r.get("log_lines_suppressed", 0)) for r in reports),
            overloaded=sorted(u for r in reports for u in r.get("overloaded", [])),
            lag_p95_ms=max((float(r.get("lag_p95_ms", 0.0)) for r in reports), default=0.0),
            stamp=time.time(),
        )

    # -- the end --------------------------------------------------------------------------

    async def _shutdown(self, entities: list[Any], observing: list[Any]) -> None:
        """Every worker tells its users STOP (through this router, so it closes last)."""
        self._stopping = True
        self.notifier.stopping()
        for w in self.workers:
            w.stop()
        deadline = time.monotonic() + STOP_S
        for w in self.workers:
            while w.proc is not None and w.proc.poll() is None and time.monotonic() < deadline:
                await asyncio.sleep(0.02)
            if w.proc is not None and w.proc.poll() is None:
                log.error("worker did not stop; killed", extra={"fields": {"worker": w.index}})
                w.proc.kill()
                w.proc.wait()
        for observer in observing:
            with contextlib.suppress(Exception):
                observer.close()
        if self._token is not None:  # gone after the users' last words, as in one process
            self._alive(False)
        for ent in entities:
            with contextlib.suppress(zenoh.ZError):
                ent.undeclare()
        if self._zenoh is not None:
            self._zenoh.close()
        self.notifier.close()
        log.info("stopped", extra={"fields": {"restarts": self.restarts}})


def _prepare_state(config: DaemonConfig) -> None:
    """Open (create, or move aside if unusable) the state database once, so the workers do
    not race to: each then opens it as it is (SQLite's write-ahead log serves several)."""
    if config.state_dir is not None:
        opened = StateDB.open(config.state_dir, map_period_s=config.persist_map_s)
        if opened is not None:
            opened[0].close()


async def supervise(config: DaemonConfig, observers: Sequence[Observer] = ()) -> None:
    """Run until SIGTERM or SIGINT."""
    with contextlib.suppress(asyncio.CancelledError):
        await Supervisor(config, observers=observers).run()
