"""The view's zenoh side: subscribe to every user's keys, read-only, and fold what comes.

The node declares subscribers, one liveliness subscriber and snapshot queries, all from the
topic table through ``protocol.session``; it declares no publisher and puts nothing, so a
view can never steer anyone. When the daemon's liveliness token comes back (a restart),
every user's map is asked for again: the daemon's copy is the one it plans on.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import MapSnapshot

from .state import ViewState

log = logging.getLogger("guidebelt.view")

WATCHED = (T.MAP_DELTA, T.POSE, T.GOAL, T.PATH, T.STATUS, T.BELT, T.VOICE)
"""Every per-user key the page draws from."""
SNAPSHOT_RETRY_S = 1.0


class ViewNode:
    """``with ViewNode(session, state):`` keeps ``state`` up to date until the block ends."""

    def __init__(self, session: zenoh.Session, state: ViewState) -> None:
        self.session = session
        self.state = state
        self.rejected = 0
        self._entities: list = []
        self._stop = threading.Event()
        self._asker = threading.Thread(target=self._ask_loop, name="view-snapshots", daemon=True)
        self._asked: dict[str, float] = {}

    def start(self) -> ViewNode:
        for topic in WATCHED:
            cb = Callback(self._on_sample(topic), indirect=False)
            self._entities.append(wire.declare_subscriber(self.session, topic, cb))
        self._entities.append(wire.watch_liveliness(self.session, T.ALIVE, self._on_alive))
        self._asker.start()
        return self

    def _on_sample(self, topic: T.Topic):
        model = topic.model
        assert model is not None

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            try:
                user = topic.user_of(sample.key_expr)
                msg = codec.decode(model, sample.payload.to_bytes())
            except (ValueError, codec.DecodeError):
                self.rejected += 1  # not ours to report: the daemon tells the sender
                return
            self.state.fold(user, msg)

        return on_sample

    def _on_alive(self, sample: zenoh.Sample) -> None:
        self.state.set_alive(sample.kind == zenoh.SampleKind.PUT)

    def _ask_loop(self) -> None:
        """Ask for the maps the view lacks, each at most once a ``SNAPSHOT_RETRY_S``."""
        while not self._stop.wait(0.1):
            now = time.monotonic()
            for user in self.state.wanting_snapshot():
                if now - self._asked.get(user, -1e9) < SNAPSHOT_RETRY_S:
                    continue
                self._asked[user] = now
                self._ask(user)

    def _ask(self, user: str) -> None:
        try:
            replies = wire.get(self.session, T.MAP_SNAPSHOT, user, timeout=SNAPSHOT_RETRY_S)
            for reply in replies:
                if reply.ok is None:
                    continue
                snap = codec.decode(MapSnapshot, reply.ok.payload.to_bytes())
                self.state.fold(user, snap)
        except (zenoh.ZError, codec.DecodeError) as exc:
            log.debug("snapshot of %s: %s", user, exc)

    def close(self) -> None:
        self._stop.set()
        if self._asker.is_alive():
            self._asker.join(3.0)
        for ent in self._entities:
            with contextlib.suppress(zenoh.ZError):
                ent.undeclare()
        self._entities = []

    def __enter__(self) -> ViewNode:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
