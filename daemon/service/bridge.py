"""The daemon's one zenoh session, and the hand-over from zenoh's threads to the loop.

Every zenoh callback does the least it can: stamp when the sample arrived, copy the payload
out and ``loop.call_soon_threadsafe`` it. Nothing in a callback waits for a lock, the planner
or the loop. Queries are handed over the same way and answered from the loop.

Two things are settled on zenoh's thread, before the loop: the poses and map deltas of a user
admission control has shed are dropped there (``mute``: not even a hop to the loop, so a
hundred shed users cost the loop nothing), and when each watched user's latest pose reached
the daemon is kept (``pose_heard_at``), so a step can tell a localiser gone silent from a
pose still queued in, or dropped by, the daemon itself.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable

import zenoh
from zenoh.handlers import Callback

from protocol import session as wire
from protocol import topics as T
from protocol.topics import Topic

log = logging.getLogger("guidebelt.bridge")

INPUTS = (
    T.MAP_DELTA, T.POSE, T.GOAL, T.BELT_BUTTON, T.SETTINGS_SET, T.BELT_HEALTH, T.PROXIMITY,
)  # fmt: skip
"""What the daemon subscribes to, for every user."""
STREAMS = (T.POSE, T.MAP_DELTA)
"""The two streams (20 Hz poses, 10 Hz deltas a user): heard through one subscriber each for
every user while nobody is shed; while anyone is, through each guided user's own, so a shed
user's stream is not even sent to the daemon (zenoh sends a put only to matching
subscribers)."""
QUERIES = (T.HEALTH, T.MAP_SNAPSHOT, T.STATUS_QUERY, T.SETTINGS_QUERY)
"""What the daemon answers (every user's, for the per-user ones)."""

SampleSink = Callable[[Topic, str, bytes, float], None]
"""``(topic, key, payload, arrived)`` on the loop thread; ``arrived``: when zenoh handed the
sample to the daemon (``time.time()``), however long the loop took to get to it."""
PoseSink = Callable[[bytes, float], None]
"""``(payload, arrived)`` on zenoh's thread: a user's own taker of poses (``route_poses``)."""
QuerySink = Callable[[Topic, zenoh.Query], None]
"""``(topic, query)`` on the loop thread; the sink must reply and ``drop()`` it."""


class Bridge:
    def __init__(
        self,
        session: zenoh.Session,
        loop: asyncio.AbstractEventLoop,
        on_sample: SampleSink,
        on_query: QuerySink,
        worker: bool = False,
    ) -> None:
        """``worker``: one of several processes sharing the users (``daemon.service.workers``):
        poses and deltas are always subscribed to per user (every user's would reach every
        worker), and the daemon-wide health query and liveliness token are the parent's."""
        self.session = session
        self._worker = worker
        self._loop = loop
        self._on_sample = on_sample
        self._on_query = on_query
        self._subscribers: list[zenoh.Subscriber] = []
        self._queryables: list[zenoh.Queryable] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._token: zenoh.LivelinessToken | None = None
        self._lock = threading.Lock()
        self._muted: frozenset[str] = frozenset()
        """Pose and delta keys of shed users (replaced whole: zenoh's threads read it)."""
        self._watched: frozenset[str] = frozenset()
        """Pose keys of the users the daemon has a session for: only theirs are timed, so a
        peer inventing names cannot grow ``_pose_heard``."""
        self._pose_heard: dict[str, float] = {}
        self._pose_sinks: dict[str, PoseSink] = {}
        """Pose key → the user's runner, which takes its poses on zenoh's thread (replaced
        whole, like ``_muted``)."""
        self._users: set[str] = set()
        self._shed: set[str] = set()
        self._every: dict[Topic, zenoh.Subscriber] = {}
        """``STREAMS``' subscribers for every user, while nobody is shed."""
        self._own: dict[str, list[zenoh.Subscriber]] = {}
        """Each guided user's own ``STREAMS`` subscribers, while somebody is shed."""
        self._closed = False
        self._last: dict[str, bytes] = {}
        self._once_until = 0.0
        """While subscriptions change over (the new ones are declared before the old ones go,
        so nothing is missed) a sample can come twice: passed on once (``_last``)."""

    def start(self) -> None:
        for topic in INPUTS:
            if topic not in STREAMS:
                self._subscribers.append(
                    wire.declare_subscriber(self.session, topic, self._sample_cb(topic))
                )
        self._restream()
        for topic in QUERIES:
            if not (self._worker and topic is T.HEALTH):
                self._queryables.append(
                    wire.declare_queryable(self.session, topic, self._query_cb(topic))
                )
        if not self._worker:
            # Declared last: drivers see the daemon alive only once it can hear them.
            self._token = wire.declare_token(self.session, T.ALIVE)

    def _sample_cb(self, topic: Topic) -> Callback:
        loop, sink = self._loop, self._on_sample
        heard = self._pose_heard if topic is T.POSE else None
        mutable = topic in (T.POSE, T.MAP_DELTA)

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return  # a delete carries no message
            arrived = time.time()
            key = str(sample.key_expr)
            if heard is not None and key in self._watched and arrived > heard.get(key, 0.0):
                heard[key] = arrived
            if mutable and key in self._muted:
                return
            if mutable and time.monotonic() < self._once_until:
                payload = sample.payload.to_bytes()
                if self._last.get(key) == payload:
                    return  # the same sample through the old and the new subscriber
                self._last[key] = payload
            if heard is not None and (take := self._pose_sinks.get(key)) is not None:
                take(sample.payload.to_bytes(), arrived)  # no hop: see route_poses
                return
            # RuntimeError: the loop is closed, the daemon is stopping.
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(sink, topic, key, sample.payload.to_bytes(), arrived)

        # Run on zenoh's own thread: the callback only queues, so no extra hop is needed.
        return Callback(on_sample, indirect=False)

    def _query_cb(self, topic: Topic) -> Callback:
        loop, sink = self._loop, self._on_query

        def on_query(query: zenoh.Query) -> None:
            try:
                loop.call_soon_threadsafe(sink, topic, query)
            except RuntimeError:
                query.drop()

        return Callback(on_query, indirect=False)

    def watch(self, user: str) -> None:
        """Time ``user``'s poses as they arrive (``pose_heard_at``)."""
        with self._lock:
            self._watched = self._watched | {T.POSE.key(user)}
            self._users.add(user)
        self._restream()

    def route_poses(self, user: str, take: PoseSink | None) -> None:
        """Hand ``user``'s poses to ``take`` on zenoh's thread instead of the loop (None: to
        the loop again). Poses are two of every three samples at 20 Hz poses and 10 Hz
        deltas, and the loop hop (a wake-up, a callback, the worker woken to wait again) cost
        more than the step they feed; the taker only stores the latest under its lock."""
        key = T.POSE.key(user)
        with self._lock:
            sinks = dict(self._pose_sinks)
            if take is None:
                sinks.pop(key, None)
            else:
                sinks[key] = take
            self._pose_sinks = sinks

    def mute(self, user: str, muted: bool) -> None:
        """Stop hearing (or hear again) ``user``'s poses and map deltas: not sent to the
        daemon at all once the subscriptions change over, dropped on zenoh's thread till then."""
        keys = {T.POSE.key(user), T.MAP_DELTA.key(user)}
        with self._lock:
            self._muted = self._muted | keys if muted else self._muted - keys
            (self._shed.add if muted else self._shed.discard)(user)
        self._restream()

    def _restream(self) -> None:
        """Subscribe to ``STREAMS`` as the shed users require (loop thread): for everyone when
        nobody is shed, else each guided user's own. New subscribers are declared before the
        old ones go. At 100 users with 94 shed, zenoh's threads took 0.22 of a core handing
        the shed users' 2,800 samples a second to a callback only to drop them."""
        per_user = self._worker or bool(self._shed)
        wanted = self._users - self._shed if per_user else set()
        if self._closed or ((not per_user) == bool(self._every) and wanted == set(self._own)):
            return  # closed: a user forgotten while the daemon stops subscribes to nothing
        self._last.clear()
        self._once_until = time.monotonic() + 1.0
        if per_user:
            for user in sorted(wanted - set(self._own)):
                self._own[user] = [
                    wire.declare_subscriber(self.session, t, self._sample_cb(t), user)
                    for t in STREAMS
                ]
            gone = [*self._every.values()]
            self._every.clear()
        else:
            for topic in STREAMS:
                if topic not in self._every:
                    self._every[topic] = wire.declare_subscriber(
                        self.session, topic, self._sample_cb(topic)
                    )
            gone = []
        for user in [u for u in self._own if u not in wanted]:
            gone += self._own.pop(user)
        for sub in gone:
            with contextlib.suppress(zenoh.ZError):
                sub.undeclare()

    def pose_heard_at(self, user: str) -> float | None:
        """When ``user``'s latest pose reached the daemon (``time.time()``), read or not."""
        return self._pose_heard.get(T.POSE.key(user))

    def publish(self, key: str, payload: bytes) -> None:
        """Any thread: the users' workers publish their own results, each on a publisher
        declared once per key with its topic's QoS (a key not in the table is refused)."""
        self._publisher(key).put(payload)

    def listened(self, key: str) -> bool:
        """Whether any subscriber (this session's own included) matches ``key`` now: a
        message nobody hears need not be built (zenoh's matching status, ~1 µs to read)."""
        return self._publisher(key).matching_status.matching

    def _publisher(self, key: str) -> zenoh.Publisher:
        pub = self._publishers.get(key)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self._publishers[key] = wire.declare_publisher(
                        self.session, T.topic_of(key), T.user_of(key)
                    )
        return pub

    def request(self, key: str, timeout_s: float, on_reply: Callable[[bytes | None], None]) -> None:
        """Ask ``key``'s queryable; ``on_reply(payload)`` runs on the loop with the first
        good reply, or with None if none came within ``timeout_s``."""
        loop = self._loop
        state = {"done": False}

        def deliver(payload: bytes | None) -> None:
            if not state["done"]:
                state["done"] = True
                on_reply(payload)

        def on_answer(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                payload = reply.ok.payload.to_bytes()
                loop.call_soon_threadsafe(deliver, payload)

        def on_end() -> None:
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(deliver, None)

        topic = T.topic_of(key, T.Kind.QUERYABLE)
        wire.get(self.session, topic, T.user_of(key), Callback(on_answer, on_end), timeout_s)

    def forget_user(self, user: str) -> None:
        with self._lock:
            for key in [k for k in self._publishers if T.user_of(k) == user]:
                self._publishers.pop(key).undeclare()
            pose = T.POSE.key(user)
            self._watched = self._watched - {pose}
            self._pose_sinks = {k: v for k, v in self._pose_sinks.items() if k != pose}
            self._muted = self._muted - {pose, T.MAP_DELTA.key(user)}
            self._users.discard(user)
            self._shed.discard(user)
        self._pose_heard.pop(pose, None)
        self._restream()

    def close(self) -> None:
        self._closed = True
        if self._token is not None:
            self._token.undeclare()
            self._token = None
        with self._lock:
            publishers = list(self._publishers.values())
        streams = [*self._every.values(), *(s for subs in self._own.values() for s in subs)]
        self._every.clear()
        self._own.clear()
        self._users.clear()
        self._shed.clear()
        for ent in (*self._subscribers, *streams, *self._queryables, *publishers):
            with contextlib.suppress(zenoh.ZError):
                ent.undeclare()
        self._subscribers.clear()
        self._queryables.clear()
        self._publishers.clear()
