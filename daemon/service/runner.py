"""The asyncio side of one user: an inbox filled on the loop, a worker that steps it.

Inputs only touch the inbox (loop thread). One task per user takes the whole inbox and
runs ``Navigator.step`` on the user's own worker thread, so planning never blocks the
loop and a user's map and planner are only ever touched by one thread; the worker
publishes what the step produced. While a step runs, new inputs pile up and are
coalesced into the next one.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import zenoh

from daemon.navigation import Inbox, Navigator, Rejection, StepOutput
from protocol import codec
from protocol import topics as T
from protocol.messages import (
    BeltButton,
    BeltHealth,
    Goal,
    MapDelta,
    MapSnapshot,
    Pose,
    Proximity,
    StatusCode,
    UserSettings,
)

log = logging.getLogger("guidebelt.runner")


class UserRunner:
    def __init__(
        self,
        navigator: Navigator,
        publish: Callable[[str, bytes], None],
        request: Callable[[str, float, Callable[[bytes | None], None]], None],
        snapshot_timeout_s: float,
        store_settings: Callable[[str, UserSettings], None] | None = None,
        map_too_big: Callable[[int | None], str | None] | None = None,
    ) -> None:
        self.navigator = navigator
        self._map_too_big = map_too_big
        self._store_settings = store_settings
        self.user = navigator.user
        self._publish = publish
        self._request = request
        self._snapshot_timeout_s = snapshot_timeout_s
        self._executor = ThreadPoolExecutor(1, thread_name_prefix=f"plan-{self.user}")
        self._inbox = Inbox()
        self._wake = asyncio.Event()
        self._snapshot_pending = False
        self._closed = False
        self.last_status: bytes | None = None
        self._loop = asyncio.get_running_loop()
        self.last_input = self._loop.time()
        self._task = self._loop.create_task(self._run(), name=f"user-{self.user}")

    # -- inputs (loop thread) -------------------------------------------------------------

    def reject(self, code: StatusCode, reason: str) -> None:
        self._inbox.rejections.append(Rejection(code, reason))
        self._heard()

    def put_delta(self, delta: MapDelta) -> None:
        self._inbox.deltas.append(delta)
        self._heard()

    def put_pose(self, pose: Pose) -> None:
        self._inbox.pose = pose  # the latest pose wins
        self._heard()

    def put_goal(self, goal: Goal) -> None:
        self._inbox.goal = goal
        self._heard()

    def put_button(self, press: BeltButton) -> None:
        self._inbox.buttons.append(press)
        self._heard()

    def put_proximity(self, proximity: Proximity) -> None:
        self._inbox.proximity = proximity  # the latest frame's wins
        self._heard()

    def put_settings(self, settings: UserSettings) -> None:
        self._inbox.settings = settings  # the latest wins
        self._heard()

    def put_belt_health(self, health: BeltHealth) -> None:
        """The belt's battery. Health comes twice a second and steps nobody by itself,
        except when the battery just went below the warning level."""
        if health.battery_v is None:
            return
        low = self.navigator.settings.battery.low_v
        known = self.navigator.controls.battery_v
        self._inbox.battery_v = health.battery_v
        if health.battery_v < low and (known is None or known >= low):
            self._wake.set()

    def settings(self, now: float) -> UserSettings:
        return self.navigator.controls.state(self.navigator.guidance, now)

    def _heard(self) -> None:
        self.last_input = self._loop.time()
        self._wake.set()

    def tick(self) -> None:
        self._inbox.tick = True
        self._wake.set()

    # -- the worker -----------------------------------------------------------------------

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while not self._closed:
            await self._wake.wait()
            self._wake.clear()
            inbox, self._inbox = self._inbox, Inbox()
            if not inbox:
                continue
            try:
                await loop.run_in_executor(self._executor, self._step, inbox)
            except asyncio.CancelledError:
                raise
            except Exception:  # even the error report failed: log it, keep serving
                log.exception("worker failed", extra={"fields": {"user": self.user}})

    def _step(self, inbox: Inbox) -> None:
        """On the worker: step, then publish straight away (zenoh publishers are
        thread-safe), so the belt pattern does not wait for the loop to wake up."""
        try:
            out = self.navigator.step(inbox, time.time())
        except Exception as exc:  # a bug must not take every user down with it
            log.exception("step failed", extra={"fields": {"user": self.user}})
            # Not another step: whatever failed may fail again. The user is stopped and told.
            why = f"{type(exc).__name__}: {exc}"
            out = self.navigator.halt(time.time(), StatusCode.INTERNAL, why)
        try:
            self._emit(out)
        except zenoh.ZError as exc:  # the session is closing under us: nothing to tell
            log.warning("publish failed", extra={"fields": {"user": self.user, "err": str(exc)}})

    def _emit(self, out: StepOutput) -> None:
        """Publish ``out`` (on the worker thread)."""
        user = self.user
        for pattern in out.belt:
            self._publish(T.BELT.key(user), codec.encode(pattern))
        for cue in out.voice:
            self._publish(T.VOICE.key(user), codec.encode(cue))
        path = out.path()
        if path is not None:
            self._publish(T.PATH.key(user), codec.encode(path))
        for status in out.statuses:
            self.last_status = codec.encode(status)
            self._publish(T.STATUS.key(user), self.last_status)
        if out.settings is not None:
            self._publish(T.SETTINGS.key(user), codec.encode(out.settings))
            if self._store_settings is not None:
                self._store_settings(user, out.settings)
        if out.want_snapshot:
            self._loop.call_soon_threadsafe(self._ask_for_snapshot)

    def _ask_for_snapshot(self) -> None:
        if not self._snapshot_pending and not self._closed:
            self._snapshot_pending = True
            self._request(T.MAP_SOURCE.key(self.user), self._snapshot_timeout_s, self._on_snapshot)

    def _on_snapshot(self, payload: bytes | None) -> None:
        self._snapshot_pending = False
        if payload is None:
            log.warning("no snapshot from the map source", extra={"fields": {"user": self.user}})
            self._inbox.snapshot_failed = True
        elif self._map_too_big is not None and (why := self._map_too_big(codec.map_cells(payload))):
            rej = Rejection(StatusCode.OVERSIZED, f"snapshot: {why}")  # refused before decoding
            self._inbox.rejections.append(rej)
            self._inbox.snapshot_failed = True
        else:
            try:
                self._inbox.snapshot = codec.decode(MapSnapshot, payload)
            except codec.DecodeError as exc:
                self._inbox.rejections.append(Rejection(exc.code, f"snapshot: {exc.reason}"))
                self._inbox.snapshot_failed = True
        self._wake.set()

    # -- queries --------------------------------------------------------------------------

    async def reply_snapshot(self, query: zenoh.Query, key: str) -> None:
        """Answer with this user's map, read on the worker thread between steps."""
        loop = asyncio.get_running_loop()
        try:
            snap = await loop.run_in_executor(self._executor, self.navigator.snapshot, time.time())
            if snap is None:
                query.reply_err(b"no map yet")
            else:
                query.reply(key, codec.encode(snap))
        finally:
            query.drop()

    # -- the end --------------------------------------------------------------------------

    async def close(
        self, code: StatusCode = StatusCode.SHUTDOWN, reason: str = "daemon stopping"
    ) -> None:
        """Publish the last pattern and the final status, then stop the worker."""
        if self._closed:
            return
        self._closed = True
        self._task.cancel()
        loop = asyncio.get_running_loop()
        try:
            await loop.run_in_executor(
                self._executor,
                lambda: self._emit(self.navigator.halt(time.time(), code, reason)),
            )
        finally:
            self._executor.shutdown(wait=False, cancel_futures=True)
