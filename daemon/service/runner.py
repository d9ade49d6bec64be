"""The asyncio side of one user: an inbox filled on the loop, a worker that steps it.

Inputs only touch the inbox (on the loop, or zenoh's thread for poses). Each user's own
worker thread waits out its turn, takes the whole inbox and runs ``Navigator.step``, so
planning never blocks the loop, the loop does nothing per step, and a user's map and planner
are only ever touched by one thread; the worker publishes what the step produced. While a
step runs, new inputs pile up and are coalesced into the next one.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable

import zenoh

from daemon.navigation import Inbox, Navigator, Rejection, StepOutput
from daemon.runtime import gc_policy
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

from .pacing import BeltRefresh, Pacing
from .step_thread import StepThread

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
        pacing: Pacing | None = None,
        after_step: Callable[[Navigator], None] | None = None,
        pose_heard_at: Callable[[], float | None] | None = None,
        listened: Callable[[str], bool] | None = None,
    ) -> None:
        """``after_step(navigator)`` runs on the worker once a step's output is published
        (the state store takes what changed there). ``pose_heard_at()``: when the user's latest
        pose reached the daemon, read or not (the bridge's clock of arrivals). ``listened(key)``:
        whether anyone subscribes to ``key`` (the path is built only for someone)."""
        self.navigator = navigator
        self.pacing = pacing or Pacing()
        self._after_step = after_step
        self._map_too_big = map_too_big
        self._store_settings = store_settings
        self.user = navigator.user
        self._publish = publish
        self._request = request
        self._snapshot_timeout_s = snapshot_timeout_s
        self._inbox = Inbox()
        self._lock = threading.Lock()
        """The inbox is filled on the loop and taken by the worker when its turn comes."""
        self._pacing = False
        """The worker is waiting out its step period: an input that does not step the user at
        once need not wake it, the period's end will (under ``_lock``)."""
        self._snapshot_pending = False
        self._urgent_at: float | None = None
        """When the inbox's first urgent input arrived (monotonic): the step's lag starts."""
        self._next_step_at = 0.0
        self.shed = False
        """Set by the daemon's admission control: step rarely, guide nobody, say overloaded."""
        self.skipped = 0
        """Poses and deltas not even decoded while shed."""
        self.readmitted_at = 0.0
        """When admission control last guided the user again (``time.time()``): their poses
        were not even sent to the daemon while shed (``Bridge.mute``)."""
        self._closed = False
        self.last_status: bytes | None = None
        self._pose_heard_at = pose_heard_at
        self._listened = listened
        self._pose_read_at = 0.0
        """When the latest pose the loop read (taken or refused) had reached the daemon."""
        self._belt = BeltRefresh()
        self._path_bytes = codec.PathBytes()
        self._idle = False
        """The worker waits for any input at all (no step period running, inbox empty): any
        input wakes it (under ``_lock``)."""
        self._loop = asyncio.get_running_loop()
        self.last_input = time.monotonic()
        self._worker = StepThread(f"plan-{self.user}", self._serve)
        self._worker.start()

    @property
    def serving(self) -> bool:
        """The user's worker still waits for and steps their inputs."""
        return self._worker.alive and not self._closed

    # -- inputs (loop thread) -------------------------------------------------------------

    def reject(self, code: StatusCode, reason: str, counted: bool = True) -> None:
        with self._lock:
            self._inbox.rejections.append(Rejection(code, reason, counted))
            self._heard(urgent=True)

    def resync(self) -> None:
        """Ask the map source for a snapshot now (a map restored after a restart)."""
        self._ask_for_snapshot()

    def put_delta(self, delta: MapDelta) -> None:
        with self._lock:
            self._inbox.deltas.append(delta)
            self._heard(urgent=True)

    def read_pose(self, arrived: float) -> None:
        """The loop has read a pose that reached the daemon at ``arrived``, good or bad."""
        self._pose_read_at = max(self._pose_read_at, arrived)

    def put_pose(self, pose: Pose, arrived: float | None = None) -> None:
        """``arrived``: when it reached the daemon (staleness: on the daemon's clock, and
        never on how long the daemon's loop took to read it). None: now."""
        with self._lock:
            self._inbox.pose = pose  # the latest pose wins
            self._inbox.pose_received = time.time() if arrived is None else arrived
            self._heard()

    def take_pose(self, payload: bytes, arrived: float) -> None:
        """On zenoh's thread (``Bridge.route_poses``): decode a pose and leave it in the inbox,
        as ``put_pose`` does from the loop, without the hop to the loop. The worker is woken
        only if it waits for any input at all; while it waits out its step period, or steps,
        the pose is simply there when its turn comes. A pose that does not decode is refused
        on the loop, as every refused input is (it steps the user at once)."""
        if self._closed:
            return
        if self.shed:  # muted by now on the bridge; this one was on its way
            self.skipped += 1
            return
        try:
            pose = codec.decode(Pose, payload)
        except codec.DecodeError as exc:
            with contextlib.suppress(RuntimeError):  # the loop is closed: stopping
                self._loop.call_soon_threadsafe(self._refuse_pose, exc.code, exc.reason, arrived)
            return
        with self._lock:
            self._pose_read_at = max(self._pose_read_at, arrived)
            self._inbox.pose, self._inbox.pose_received = pose, arrived  # the latest wins
            self.last_input = time.monotonic()
            self._ring()

    def _refuse_pose(self, code: StatusCode, reason: str, arrived: float) -> None:
        self.read_pose(arrived)
        self.reject(code, f"{T.POSE.leaf}: {reason}")

    def put_goal(self, goal: Goal) -> None:
        with self._lock:
            self._inbox.goal = goal
            self._heard(urgent=True)

    def put_button(self, press: BeltButton) -> None:
        with self._lock:
            self._inbox.buttons.append(press)
            self._heard(urgent=True)

    def put_proximity(self, proximity: Proximity) -> None:
        with self._lock:
            self._inbox.proximity = proximity  # the latest frame's wins
            self._heard(urgent=True)  # the belt's safety input steps the user at once

    def put_settings(self, settings: UserSettings) -> None:
        with self._lock:
            self._inbox.settings = settings  # the latest wins
            self._heard(urgent=True)

    def put_belt_health(self, health: BeltHealth) -> None:
        """The belt's battery. Health comes twice a second and steps nobody by itself,
        except when the battery just went below the warning level."""
        if health.battery_v is None:
            return
        low = self.navigator.settings.battery.low_v
        known = self.navigator.controls.battery_v
        with self._lock:
            self._inbox.battery_v = health.battery_v
            if health.battery_v < low and (known is None or known >= low):
                self._ring()

    def settings(self, now: float) -> UserSettings:
        return self.navigator.controls.state(self.navigator.guidance, now)

    def _heard(self, urgent: bool = False) -> None:
        self.last_input = time.monotonic()
        if urgent and self._urgent_at is None:
            self._urgent_at = time.monotonic()
        self._ring(urgent)

    def _ring(self, urgent: bool = False) -> None:
        """Wake the worker if it waits for this input (under ``_lock``): any input when it
        has none, an urgent one while it waits out its period. A pose then would wake it only
        to wait again (20 a second a user); while it steps, it looks at the inbox after."""
        if self._idle or (urgent and self._pacing):
            self._idle = self._pacing = False
            self._worker.ring()

    def tick(self) -> None:
        with self._lock:
            self._inbox.tick = True
            self._ring()

    # -- the worker -----------------------------------------------------------------------

    def _serve(self) -> None:
        """The worker's life: wait for the user's turn, step, again; the loop's jobs (a
        snapshot to read, the last words) run between steps."""
        while self._worker.poll() and not self._closed and self._gather():
            period = self.pacing.shed_period_s if self.shed else self.pacing.guide_period_s
            self._next_step_at = time.monotonic() + period
            try:
                done = self._take_and_step()
            except Exception:  # even the error report failed: log it, keep serving
                log.exception("worker failed", extra={"fields": {"user": self.user}})
                continue
            if done is not None:
                self.pacing.record(self.user, *done)

    def _take_and_step(self) -> tuple[float, float, bool] | None:
        """On the worker: wait for a step slot (one per core, first come first served: fifty
        users' threads fighting over the GIL would make every step slow instead of a few
        late), take the inbox then, so the step has the freshest inputs, and step. Returns
        (lag ms from the first urgent input, or from the turn coming; CPU ms; whether an
        urgent input was answered), None if the inbox was empty."""
        gate = self.pacing.shed_gate if self.shed else contextlib.nullcontext()
        with gate, self.pacing.slots:
            with self._lock:
                inbox, self._inbox = self._inbox, Inbox()
                urgent_at, self._urgent_at = self._urgent_at, None
            if not inbox:
                return None
            started = time.monotonic()
            inbox.taken_at = time.time()
            inbox.overloaded = self.shed
            inbox.daemon_behind = self.pacing.behind
            heard = self._pose_heard_at() if self._pose_heard_at is not None else None
            # Until a pose that came after the readmission is read (for at most a pose's
            # staleness, so a localiser that died meanwhile is still said as stale), a missing
            # pose of a readmitted user's is the daemon's doing: it did not listen.
            back = self.readmitted_at > self._pose_read_at and (
                inbox.taken_at - self.readmitted_at < self.navigator.settings.stale_pose_s
            )
            inbox.pose_unread = back or (heard is not None and heard > self._pose_read_at)
            cpu_ms = self._step(inbox)
            lag_ms = (time.monotonic() - (urgent_at or started)) * 1e3  # the output is out
            cpu_ms += self._between_steps()
            gc_policy.after_step()  # collect between steps
        return lag_ms, cpu_ms, urgent_at is not None

    def _between_steps(self) -> float:
        """On the worker, the step's output out: the planner's work left for now. Returns its
        CPU milliseconds (the user's cost as much as the step's)."""
        cpu0 = time.thread_time()
        try:
            self.navigator.between_steps()
        except Exception:  # the route plans afresh at the next step (``Route.between_steps``)
            log.exception("planner failed between steps", extra={"fields": {"user": self.user}})
        return (time.thread_time() - cpu0) * 1e3

    def _gather(self) -> bool:
        """On the worker: wait for inputs. Urgent ones (map, goal, refusal, button) step at
        once; a pose alone waits for the user's guide period (later poses replace it
        meanwhile), and a shed user steps only once per shed period. Until the period is over
        only an urgent input wakes the worker, even with nothing in the inbox: a pose then
        would wake it only to wait out the rest of the period (two wakes a step). False:
        closing."""
        while not self._closed:
            with self._lock:
                wait = self._next_step_at - time.monotonic()
                if self._inbox and (wait <= 0 or (not self.shed and self._inbox.urgent())):
                    self._idle = self._pacing = False
                    return True
                self._idle, self._pacing = wait <= 0, wait > 0
            if not self._worker.wait(wait if wait > 0 else None):
                return False
        return False

    def _step(self, inbox: Inbox) -> float:
        """On the worker: step, then publish straight away (zenoh publishers are
        thread-safe), so the belt pattern does not wait for the loop to wake up. Returns the
        CPU milliseconds the worker spent (admission control's measure of the user's cost)."""
        cpu0 = time.thread_time()
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
        if self._after_step is not None:
            try:
                self._after_step(self.navigator)
            except Exception:  # the store is not worth a user's guidance
                log.exception("state not saved", extra={"fields": {"user": self.user}})
        return (time.thread_time() - cpu0) * 1e3

    def _emit(self, out: StepOutput, refresh_all: bool = False) -> None:
        """Publish ``out`` (on the worker thread). ``refresh_all``: put every belt pattern,
        even one equal to what the belt shows (the last words to a user)."""
        user = self.user
        # The path (the largest message a step makes) is for viewers and tests: a belt driver
        # and a phone do not subscribe to it, so most steps need not build it. Whoever does
        # pairs each step's path with its belt pattern (the simulated walker feels the pattern
        # stamped like the path), so then every pattern is put.
        key = T.PATH.key(user)
        paired = self._listened is None or self._listened(key)
        for pattern in out.belt:
            if self._belt.due(pattern, force=refresh_all or paired):
                self._publish(T.BELT.key(user), codec.encode(pattern))
        for cue in out.voice:
            self._publish(T.VOICE.key(user), codec.encode(cue))
        if out.path_cells is not None and paired:
            self._publish(key, self._path_bytes(out.path_cells, out.path_meta))
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
        snapshot, refusal = None, None
        if payload is None:
            log.warning("no snapshot from the map source", extra={"fields": {"user": self.user}})
        elif self._map_too_big is not None and (why := self._map_too_big(codec.map_cells(payload))):
            refusal = Rejection(StatusCode.OVERSIZED, f"snapshot: {why}")  # before decoding
        else:
            try:
                snapshot = codec.decode(MapSnapshot, payload)
            except codec.DecodeError as exc:
                refusal = Rejection(exc.code, f"snapshot: {exc.reason}")
        with self._lock:  # one step sees the snapshot, or its failure and why, whole
            if snapshot is not None:
                self._inbox.snapshot = snapshot
            else:
                self._inbox.snapshot_failed = True
                if refusal is not None:
                    self._inbox.rejections.append(refusal)
            self._ring(urgent=True)

    # -- queries --------------------------------------------------------------------------

    async def reply_snapshot(self, query: zenoh.Query, key: str) -> None:
        """Answer with this user's map, read on the worker thread between steps."""
        try:
            maps = self.navigator.maps
            snap = await self._worker.run(maps.snapshot, time.time())
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
        try:
            await self._worker.run(
                lambda: self._emit(self.navigator.halt(time.time(), code, reason), True)
            )
        finally:
            self._worker.close()
