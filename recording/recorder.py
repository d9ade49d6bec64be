"""``guidebelt record``: every message of a user's session, heard over zenoh, into MCAP.

Zenoh's callback only stamps the sample and queues its bytes; one writer thread decodes,
converts and writes, so a slow disk never holds up zenoh (nor, through it, the daemon).
The queue is bounded: a sample that finds it full is dropped and counted, never silently.
Samples that do not decode are counted and not written (a recording holds valid messages).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T

from .channels import RECORDED
from .log import McapLog

QUEUE_MAX = 200_000
"""About a minute of four users at the daemon's full rate: room for a disk that stalls."""


@dataclass
class RecordCounts:
    heard: int = 0
    written: int = 0
    dropped: int = 0
    """Samples that found the queue full."""
    invalid: int = 0
    """Samples that did not decode as their key's message."""
    files: int = 0


class Recorder:
    """``with Recorder(session, Path("walk.mcap"), user="ann") as rec:`` records until the end
    of the block; ``user=None`` records every user."""

    def __init__(
        self,
        session: zenoh.Session,
        out: Path,
        user: str | None = None,
        max_bytes: int = 256 * 2**20,
        metadata: dict | None = None,
        queue_max: int = QUEUE_MAX,
    ) -> None:
        self.session = session
        self.user = None if user in (None, "*") else T.check_user(user)
        self.log = McapLog(out, max_bytes, {"user": self.user or "*", **(metadata or {})})
        self.counts = RecordCounts()
        self._queue: queue.Queue = queue.Queue(queue_max)
        self._entities: list = []
        self._lock = threading.Lock()
        self._writer = threading.Thread(target=self._drain, name="record-writer", daemon=True)

    def start(self) -> Recorder:
        self._writer.start()
        for topic in RECORDED:
            cb = Callback(self._on_sample(topic), indirect=False)
            self._entities.append(wire.declare_subscriber(self.session, topic, cb, self.user))
        return self

    def _on_sample(self, topic: T.Topic):
        put, counts, lock = self._queue.put_nowait, self.counts, self._lock

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            item = (topic, str(sample.key_expr), sample.payload.to_bytes(), time.time())
            # Subscribers' callbacks run on several zenoh threads: the counts under a lock.
            with lock:
                counts.heard += 1
                try:
                    put(item)
                except queue.Full:
                    counts.dropped += 1

        return on_sample

    def _drain(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            topic, key, payload, heard = item
            try:
                msg = codec.decode(topic.model, payload)
            except codec.DecodeError:
                self.counts.invalid += 1
                continue
            self.log.write(key, msg, heard)
            self.counts.written += 1

    def backlog(self) -> int:
        return self._queue.qsize()

    def close(self) -> RecordCounts:
        """Stop hearing, write what is queued, finish the file(s); the counts."""
        for ent in self._entities:
            with contextlib.suppress(zenoh.ZError):
                ent.undeclare()
        self._entities = []
        if self._writer.is_alive():
            self._queue.put(None)
            self._writer.join()
        self.counts.files = len(self.log.counts.files)
        self.log.close(asdict(self.counts))
        return self.counts

    def __enter__(self) -> Recorder:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
