"""The daemon's one zenoh session, and the hand-over from zenoh's threads to the loop.

Every zenoh callback does the least it can: copy the payload out and
``loop.call_soon_threadsafe`` it. Nothing in a callback waits for a lock, the planner or
the loop. Queries are handed over the same way and answered from the loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
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
QUERIES = (T.HEALTH, T.MAP_SNAPSHOT, T.STATUS_QUERY, T.SETTINGS_QUERY)
"""What the daemon answers (every user's, for the per-user ones)."""

SampleSink = Callable[[Topic, str, bytes], None]
"""``(topic, key, payload)`` on the loop thread."""
QuerySink = Callable[[Topic, zenoh.Query], None]
"""``(topic, query)`` on the loop thread; the sink must reply and ``drop()`` it."""


class Bridge:
    def __init__(
        self,
        session: zenoh.Session,
        loop: asyncio.AbstractEventLoop,
        on_sample: SampleSink,
        on_query: QuerySink,
    ) -> None:
        self.session = session
        self._loop = loop
        self._on_sample = on_sample
        self._on_query = on_query
        self._subscribers: list[zenoh.Subscriber] = []
        self._queryables: list[zenoh.Queryable] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._token: zenoh.LivelinessToken | None = None
        self._lock = threading.Lock()

    def start(self) -> None:
        for topic in INPUTS:
            self._subscribers.append(
                wire.declare_subscriber(self.session, topic, self._sample_cb(topic))
            )
        for topic in QUERIES:
            self._queryables.append(
                wire.declare_queryable(self.session, topic, self._query_cb(topic))
            )
        # Declared last: drivers see the daemon alive only once it can hear them.
        self._token = wire.declare_token(self.session, T.ALIVE)

    def _sample_cb(self, topic: Topic) -> Callback:
        loop, sink = self._loop, self._on_sample

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return  # a delete carries no message
            # RuntimeError: the loop is closed, the daemon is stopping.
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(
                    sink, topic, str(sample.key_expr), sample.payload.to_bytes()
                )

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

    def publish(self, key: str, payload: bytes) -> None:
        """Any thread: the users' workers publish their own results, each on a publisher
        declared once per key with its topic's QoS (a key not in the table is refused)."""
        pub = self._publishers.get(key)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self._publishers[key] = wire.declare_publisher(
                        self.session, T.topic_of(key), T.user_of(key)
                    )
        pub.put(payload)

    def request(
        self, key: str, timeout_s: float, on_reply: Callable[[bytes | None], None]
    ) -> None:
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

    def close(self) -> None:
        if self._token is not None:
            self._token.undeclare()
            self._token = None
        with self._lock:
            publishers = list(self._publishers.values())
        for ent in (*self._subscribers, *self._queryables, *publishers):
            with contextlib.suppress(zenoh.ZError):
                ent.undeclare()
        self._subscribers.clear()
        self._queryables.clear()
        self._publishers.clear()
