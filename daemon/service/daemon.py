"""The guidebelt service: one zenoh peer, one asyncio loop (uvloop), one runner per user.

Lifecycle: open the zenoh session → declare subscribers, queryables and the liveliness
token → READY=1 → tick (WATCHDOG=1, staleness) until SIGTERM/SIGINT → STOPPING=1 →
every user gets a STOP pattern and a final status → close the session. The whole stop
takes well under a second: nothing in it waits on the network.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import zenoh

from daemon.navigation import Navigator
from daemon.navigation.log_limit import LogLimiter
from daemon.navigation.warm import warm_up
from daemon.planning import resolve_backend
from daemon.runtime import gc_policy
from protocol import codec
from protocol import topics as T
from protocol.messages import Health, NavState, NavStatus, StatusCode
from protocol.session import open_session
from protocol.topics import Topic

from .admission import Admission, AdmissionSettings
from .bridge import Bridge
from .config import DaemonConfig
from .map_cells import MapCells
from .memory_budget import map_too_big
from .persistence import Persistence
from .queries import QueryAnswers, daemon_health, say_who_may_connect
from .runner import Pacing, UserRunner
from .sdnotify import Notifier
from .user_settings import SettingsStore
from .workers import WorkerRole

log = logging.getLogger("guidebelt.daemon")

ACTIVE = (NavState.PLANNING, NavState.GUIDING, NavState.REROUTING)
STOP_BUDGET_S = 0.6


Observer = Callable[[zenoh.Session], Any]
"""Started on the daemon's own session once it serves (``guidebelt run --record``): it hears
every input the daemon hears and every output it publishes, with no router in between. What
it returns is closed (``close()``) after the users' last patterns, before the session."""


class Daemon:
    def __init__(
        self,
        config: DaemonConfig,
        notifier: Notifier | None = None,
        observers: Sequence[Observer] = (),
        worker: WorkerRole | None = None,
    ) -> None:
        """``worker``: this daemon is one of the processes the users are shared among
        (``workers.py``): it serves only the users it owns."""
        self.config = config
        self.worker = worker
        self.observers = list(observers)
        self._observing: list[Any] = []
        self.notifier = notifier if notifier is not None else Notifier()
        self.runners: dict[str, UserRunner] = {}
        self.map_cells = MapCells()
        """Every session's map size, for the memory budget (``_map_too_big``)."""
        self.settings = SettingsStore(config.intensity)
        self.state: Persistence | None = None  # the state store, opened by ``run``
        self.rejected_unrouted = 0  # refused before reaching a user (bad key, too many users)
        self.log_limit = LogLimiter()
        self.started = time.time()
        self._stop: asyncio.Event | None = None
        self._bridge: Bridge | None = None
        self._zenoh: zenoh.Session | None = None
        self.ready = threading.Event()  # the daemon listens: for a starter on another thread
        self.admission = Admission(
            AdmissionSettings(
                lag_budget_ms=config.lag_budget_ms, cpu_budget_ms=config.step_cpu_budget_ms
            )
        )
        self._pacing: Pacing | None = None

    # -- lifecycle ------------------------------------------------------------------------

    def stop(self) -> None:
        if self._stop is not None:
            self._stop.set()

    async def run(self, install_signals: bool = True) -> None:
        loop = asyncio.get_running_loop()
        worker = self.worker
        self._stop = asyncio.Event()
        self.state = Persistence(self.config)
        self.settings = SettingsStore(
            self.config.intensity, self.state.stored_settings, self.state.save_settings
        )
        self._pacing = Pacing(
            slots=self.config.step_workers or os.cpu_count() or 1,
            guide_hz=self.config.guide_hz,
            shed_period_s=max(0.5, self.config.tick_s),
            record=self.admission.record,
        )
        self._warm_up()
        say_who_may_connect(self.config.zenoh)
        self._zenoh = open_session(self.config.zenoh)
        answers = QueryAnswers(self.runners, self.health)
        self._bridge = Bridge(
            self._zenoh, loop, self._on_sample, answers.on_query, worker=worker is not None
        )
        self._restore()  # before the bridge hears anyone: a goal sent now finds its session
        self._bridge.start()
        self._observing = [observe(self._zenoh) for observe in self.observers]
        if install_signals:
            for sig in (signal.SIGTERM, signal.SIGINT):
                loop.add_signal_handler(sig, self.stop)
        # What start-up built (modules, config, compiled kernels) leaves the collector's
        # generations, and collections wait for the gaps between steps (a gen-2 collection once
        # paused one walking step for 28 ms: 400² walk, dev VM).
        gc_policy.settle()
        self.notifier.ready(f"serving, backend {self.config.backend}")
        if worker is not None:
            worker.serving(self, loop, self._zenoh)
        self.ready.set()
        log.info(
            "ready",
            extra={"fields": {"zid": str(self._zenoh.zid()), "backend": self.config.backend}},
        )
        ticker = loop.create_task(self._tick())
        try:
            await self._stop.wait()
        finally:
            ticker.cancel()
            await self._shutdown()
            if install_signals:
                for sig in (signal.SIGTERM, signal.SIGINT):
                    loop.remove_signal_handler(sig)

    def _warm_up(self) -> None:
        """Compile (or load) the configured planner's code before READY, so the first user's
        first steps do not pay for it (``navigation/warm.py``). Best effort: a failure here is
        logged in one line and the users' planners meet it, and fall back, as they would."""
        try:
            backend = resolve_backend(self.config.backend)
            ms = warm_up(self.config.planner, backend, self.config.variant)
        except Exception as exc:  # a device that fails now fails for users too: said there
            log.warning("warm-up failed: %s: %s", type(exc).__name__, exc)
            return
        log.info(
            "warmed up",
            extra={"fields": {"planner": self.config.planner, "backend": backend, "ms": ms}},
        )

    def _restore(self) -> None:
        assert self.state is not None
        users = [u for u in self.state.users() if self.worker is None or self.worker.owns(u)]
        for user in users[: self.config.max_users]:
            runner = self._runner(user)
            assert runner is not None
            self.state.restore(runner, lambda cells, u=user: self._map_too_big(u, cells))
        if len(users) > self.config.max_users:
            log.warning("sessions not restored: past max_users",
                        extra={"fields": {"left": len(users) - self.config.max_users}})  # fmt: skip

    async def _shutdown(self) -> None:
        t0 = time.perf_counter()
        self.notifier.stopping()
        runners = list(self.runners.values())
        if runners:
            _done, pending = await asyncio.wait(
                [asyncio.ensure_future(r.close()) for r in runners], timeout=STOP_BUDGET_S
            )
            for fut in pending:
                fut.cancel()
        for observer in self._observing:
            try:
                observer.close()
            except Exception:  # an observer's failure must not keep the daemon from stopping
                log.exception("observer failed to close")
        if self._bridge is not None:
            self._bridge.close()
        if self._zenoh is not None:
            self._zenoh.close()
        if self.state is not None:
            self.state.close()
        self.notifier.close()
        log.info("stopped", extra={"fields": {"ms": round((time.perf_counter() - t0) * 1e3, 1)}})

    async def _tick(self) -> None:
        period = self.config.tick_s
        watchdog = self.notifier.watchdog_interval_s()
        if watchdog is not None:
            period = min(period, watchdog)
        loop = asyncio.get_running_loop()
        while True:
            due = loop.time() + period
            await asyncio.sleep(period)
            # How late the loop woke: every input waits that long before it reaches a user.
            late_ms = (loop.time() - due) * 1e3
            if self._pacing is not None:
                self._pacing.flush()  # the steps' records, before the loop's lateness is one
            self.admission.record_loop(late_ms, time.monotonic())
            if self._pacing is not None:
                self._pacing.behind = late_ms > self.config.lag_budget_ms
            self.notifier.watchdog()
            self._review_load()
            if self.worker is not None:
                self.worker.report(self)
            if self.state is not None:
                self.state.tick(self.runners)
            now = time.monotonic()  # runners stamp inputs on any thread with this clock
            for user, runner in list(self.runners.items()):
                active = runner.navigator.goal_cell is not None and runner.navigator.state in ACTIVE
                if active or runner.shed:
                    # Refreshes the belt; a pose gone stale stops the user; a shed user (whose
                    # poses are not even read) keeps hearing "overloaded", never silence.
                    runner.tick()
                elif now - runner.last_input > self.config.user_idle_s:
                    self._forget(user)

    def _review_load(self) -> None:
        """Admission control's decision for this tick, applied: shed users step rarely and
        hear ``overloaded``; readmitted ones are guided from their next input."""
        adm, waits = self.admission, self.admission.drain_waits
        shed, back = adm.review(time.monotonic())
        for user, flag in [(u, True) for u in shed] + [(u, False) for u in back]:
            runner = self.runners.get(user)
            if runner is not None:
                self._set_shed(runner, flag)
                runner.tick()  # told now, not at their next input
        if shed or back or adm.drain_waits != waits:  # a lag waited out is said once too
            worker = -1 if self.worker is None else self.worker.index
            fields = {"worker": worker, "shed": ",".join(shed), "guided_again": ",".join(back)}
            log.warning("load", extra={"fields": fields | adm.said()})

    def _forget(self, user: str) -> None:
        """A user silent for ``user_idle_s`` and not being guided: free the session."""
        runner = self.runners.pop(user)
        cleared = self.map_cells.close(user)
        self.admission.leave(user)
        log.info("idle user forgotten", extra={"fields": {"user": user}})
        if self.state is not None:
            self.state.forget(user)
        bridge = self._bridge
        task = asyncio.get_running_loop().create_task(
            runner.close(StatusCode.IDLE, f"nothing heard for {self.config.user_idle_s:g} s")
        )
        task.add_done_callback(lambda _t: cleared())  # its last step may have taken a map
        if bridge is not None:
            task.add_done_callback(lambda _t: bridge.forget_user(user))

    # -- inputs (loop thread) -------------------------------------------------------------

    def _runner(self, user: str) -> UserRunner | None:
        runner = self.runners.get(user)
        if runner is not None:
            return runner
        if len(self.runners) >= self.config.max_users:
            return None
        bridge = self._bridge
        assert bridge is not None
        stored = self.settings.load(user)
        nav_settings = self.config.navigator_settings()
        nav_settings = dataclasses.replace(
            nav_settings,
            intensity=nav_settings.intensity if stored.intensity is None else stored.intensity,
            voice=stored.voice or nav_settings.voice,
            wording=stored.wording or nav_settings.wording,
            units=stored.units or nav_settings.units,
        )
        navigator = Navigator(user, nav_settings, map_cells=self.map_cells.open(user))
        runner = UserRunner(
            navigator,
            bridge.publish,
            bridge.request,
            self.config.snapshot_timeout_s,
            store_settings=self.settings.save,
            map_too_big=lambda cells: self._map_too_big(user, cells),
            pacing=self._pacing,
            after_step=self.state.saver(user) if self.state is not None else None,
            pose_heard_at=lambda: bridge.pose_heard_at(user),
            listened=bridge.listened,
        )
        bridge.watch(user)
        bridge.route_poses(user, runner.take_pose)
        self._set_shed(runner, not self.admission.join(user, time.monotonic()))
        self.runners[user] = runner
        if runner.shed:
            runner.tick()  # told at once that the daemon is full, not at its first input
        # The belt driver may have started first: it learns the user's intensity now.
        bridge.publish(T.SETTINGS.key(user), codec.encode(stored))
        log.info("new user", extra={"fields": {"user": user, "backend": navigator.route.name}})
        return runner

    def _set_shed(self, runner: UserRunner, shed: bool) -> None:
        """A shed user's poses and deltas are not even sent to the daemon (``Bridge.mute``)."""
        if runner.shed and not shed:
            runner.readmitted_at = time.time()
        runner.shed = shed
        if self._bridge is not None:
            self._bridge.mute(runner.user, shed)

    def _on_sample(self, topic: Topic, key: str, payload: bytes, arrived: float) -> None:
        try:
            user = T.user_of(key)
        except ValueError as exc:
            self.rejected_unrouted += 1
            held = self.log_limit.allow("unrouted", time.monotonic())
            if held is not None:
                fields = {"key": key[:200], "reason": str(exc)[:200]}  # a peer's key: cut short
                if held:
                    fields["suppressed"] = held
                log.warning("rejected", extra={"fields": fields})
            return
        if self.worker is not None and not self.worker.owns(user):
            return  # another worker's user (every worker hears the rarer inputs of everyone)
        if topic is T.BELT_HEALTH and user not in self.runners:
            return  # a belt that is merely on starts no session (nor keeps an idle one alive)
        runner = self._runner(user)
        if runner is None:
            self._refuse_user(user)
            return
        assert topic.model is not None
        if runner.shed and topic in (T.POSE, T.MAP_DELTA):
            # Not even decoded (the bridge drops them before the loop; these were queued before
            # it knew): a shed user costs the loop nothing per pose. The deltas skipped leave a
            # sequence gap, so the map is brought back by a snapshot (the user WAITs) once the
            # user is guided again.
            runner.skipped += 1
            return
        if topic is T.POSE:
            runner.read_pose(arrived)
        if topic is T.MAP_DELTA:
            too_big = self._map_too_big(user, codec.map_cells(payload))
            if too_big is not None:  # before decoding: nothing allocated for it
                runner.reject(StatusCode.OVERSIZED, f"{topic.leaf}: {too_big}")
                return
        try:
            msg = codec.decode(topic.model, payload)
        except codec.DecodeError as exc:
            runner.reject(exc.code, f"{topic.leaf}: {exc.reason}")
            return
        if topic is T.MAP_DELTA:
            runner.put_delta(msg)
        elif topic is T.POSE:
            runner.put_pose(msg, arrived)
        elif topic is T.BELT_BUTTON:
            runner.put_button(msg)
        elif topic is T.SETTINGS_SET:
            # The user is the key's: a sample on guidebelt/ann/settings/set changes ann's
            # settings and no one else's (who may publish there is issue 24's ACL).
            runner.put_settings(msg)
        elif topic is T.BELT_HEALTH:
            runner.put_belt_health(msg)
        elif topic is T.PROXIMITY:
            runner.put_proximity(msg)
        else:
            runner.put_goal(msg)

    hear = _on_sample
    """A sample that came another way (a worker's: handed over by its parent)."""

    def _map_too_big(self, user: str, cells: int | None) -> str | None:
        """Why a map of ``cells`` cells may not be ``user``'s (None: it may)."""
        others = self.map_cells.others(user)
        return map_too_big(cells, others, self.config.max_map_cells, self.config.memory_budget_mb)

    def _refuse_user(self, user: str) -> None:
        self.rejected_unrouted += 1
        assert self._bridge is not None
        status = NavStatus(
            state=NavState.ERROR,
            code=StatusCode.TOO_MANY_USERS,
            reason=f"this daemon serves at most {self.config.max_users} users",
            stamp=time.time(),
        )
        self._bridge.publish(T.STATUS.key(user), codec.encode(status))
        self._bridge.forget_user(user)

    # -- queries (loop thread) ------------------------------------------------------------

    def health(self) -> Health:
        return daemon_health(self.config, self.started, self.runners, self.admission,
                             self.rejected_unrouted, self.log_limit.suppressed_total)  # fmt: skip


async def serve(config: DaemonConfig, observers: Sequence[Observer] = ()) -> None:
    """Run until SIGTERM or SIGINT."""
    daemon = Daemon(config, observers=observers)
    with contextlib.suppress(asyncio.CancelledError):
        await daemon.run()
