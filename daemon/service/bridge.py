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

from protocol import keys

from .config import ZenohSettings

log = logging.getLogger("guidebelt.bridge")

INPUT_LEAVES = ("map/delta", "pose", "goal")
QUERY_KEYS = (keys.HEALTH, keys.any_user("map/snapshot"), keys.any_user("status"))

SampleSink = Callable[[str, str, bytes], None]
"""``(leaf, key, payload)`` on the loop thread."""
QuerySink = Callable[[str, zenoh.Query], None]
"""``(queryable key, query)`` on the loop thread; the sink must reply and ``drop()`` it."""


def open_session(settings: ZenohSettings) -> zenoh.Session:
    return zenoh.open(zenoh.Config.from_json5(settings.to_json5()))


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
        for leaf in INPUT_LEAVES:
            self._subscribers.append(
                self.session.declare_subscriber(keys.any_user(leaf), self._sample_cb(leaf))
            )
        for key in QUERY_KEYS:
            self._queryables.append(self.session.declare_queryable(key, self._query_cb(key)))
        # Declared last: drivers see the daemon alive only once it can hear them.
        self._token = self.session.liveliness().declare_token(keys.ALIVE)

    def _sample_cb(self, leaf: str) -> Callback:
        loop, sink = self._loop, self._on_sample

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return  # a delete carries no message
            # RuntimeError: the loop is closed, the daemon is stopping.
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(
                    sink, leaf, str(sample.key_expr), sample.payload.to_bytes()
                )

        # Run on zenoh's own thread: the callback only queues, so no extra hop is needed.
        return Callback(on_sample, indirect=False)

    def _query_cb(self, key: str) -> Callback:
        loop, sink = self._loop, self._on_query

        def on_query(query: zenoh.Query) -> None:
            try:
                loop.call_soon_threadsafe(sink, key, query)
            except RuntimeError:
                query.drop()

        return Callback(on_query, indirect=False)

    def publish(self, key: str, payload: bytes) -> None:
        """Any thread: the users' workers publish their own results."""
        pub = self._publishers.get(key)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key)
                if pub is None:
                    # A path is superseded by the next one; a STOP pattern or a status is
                    # not, and must never be dropped on a busy link.
                    drop = key.endswith("/path")
                    pub = self._publishers[key] = self.session.declare_publisher(
                        key,
                        congestion_control=zenoh.CongestionControl.DROP
                        if drop
                        else zenoh.CongestionControl.BLOCK,
                        express=True,
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

        self.session.get(key, Callback(on_answer, on_end), timeout=timeout_s)

    def forget_user(self, user: str) -> None:
        prefix = f"{keys.ROOT}/{user}/"
        with self._lock:
            for key in [k for k in self._publishers if k.startswith(prefix)]:
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
