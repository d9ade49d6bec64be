"""``guidebelt replay``: a recording published back over zenoh, at its pace or faster.

Every message is re-stamped as if it happened now (``stamp`` and a path's ``pose_stamp``
moved by the same offset, divided by the speed-up), so a daemon fed a walk recorded last
week does not find its poses a week stale. Each key is published on a publisher declared
from the topic table, with its QoS.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import zenoh
from mcap.reader import make_reader

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Message

from .channels import INPUTS, from_json

STAMPED = ("stamp", "pose_stamp")


@dataclass(frozen=True)
class Recorded:
    key: str
    topic: T.Topic
    msg: Message
    log_time: float
    """When the recorder heard it, seconds since the epoch."""
    sequence: int


def read(path: Path) -> Iterator[Recorded]:
    """Every message of a recording in log-time order, each validated as its key's message."""
    with path.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.message_encoding != "json" or schema is None:
                raise ValueError(f"{path}: channel {channel.topic} is not guidebelt's JSON")
            topic = T.topic_of(channel.topic)
            assert topic.model is not None
            msg = from_json(topic.model, message.data)
            yield Recorded(channel.topic, topic, msg, message.log_time / 1e9, message.sequence)


def metadata(path: Path) -> dict[str, str]:
    with path.open("rb") as f:
        out: dict[str, str] = {}
        for record in make_reader(f).iter_metadata():
            if record.name == "guidebelt":
                out.update(record.metadata)
        return out


def restamp(msg: Message, shift: Callable[[float], float]) -> Message:
    fields = {name: shift(getattr(msg, name)) for name in STAMPED if hasattr(msg, name)}
    return msg.model_copy(update=fields) if fields else msg


def select(items: list[Recorded], what: str) -> list[Recorded]:
    if what == "all":
        return items
    if what == "inputs":
        return [r for r in items if r.topic in INPUTS]
    if what == "outputs":
        return [r for r in items if r.topic not in INPUTS]
    raise ValueError(f"replay what: inputs, outputs or all, not {what!r}")


class Player:
    """Publishes ``items`` on ``session``: ``speed`` times real time (0: as fast as it can)."""

    def __init__(self, session: zenoh.Session, items: list[Recorded], speed: float = 1.0):
        if speed < 0:
            raise ValueError("speed must be >= 0")
        self.session = session
        self.items = items
        self.speed = speed
        self.sent = 0
        self.last: Message | None = None
        """The last message sent, as sent (re-stamped)."""
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._t0_rec = items[0].log_time if items else 0.0

    def publish(self, item: Recorded, now: float) -> None:
        """One message, its stamps moved as if it were heard ``now`` (a stamp that was 5 ms
        older than its hearing stays 5 ms older, divided by the speed-up)."""
        rate = self.speed or 1.0
        msg = restamp(item.msg, lambda s: max(0.0, now + (s - item.log_time) / rate))
        pub = self._publishers.get(item.key)
        if pub is None:
            pub = self._publishers[item.key] = wire.declare_publisher(
                self.session, item.topic, T.user_of(item.key)
            )
        pub.put(codec.encode(msg))
        self.last = msg
        self.sent += 1

    def run(
        self,
        stop: threading.Event | None = None,
        on_sent: Callable[[int], None] | None = None,
    ) -> int:
        """Publish everything on the recording's schedule; the number sent."""
        stop = stop or threading.Event()
        start = time.monotonic()
        wall0 = time.time()
        for item in self.items:
            if self.speed:
                due = start + (item.log_time - self._t0_rec) / self.speed
                if stop.wait(max(0.0, due - time.monotonic())):
                    break
            elif stop.is_set():
                break
            self.publish(item, wall0 + (time.monotonic() - start))
            if on_sent is not None:
                on_sent(self.sent)
        return self.sent

    def close(self) -> None:
        for pub in self._publishers.values():
            pub.undeclare()
        self._publishers.clear()
