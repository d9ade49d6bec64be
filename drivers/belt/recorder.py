"""A mock belt driver: a zenoh node that records every pattern it is sent
(``python -m drivers.belt.recorder --connect tcp/127.0.0.1:7447 --out belt.jsonl``).

It subscribes where the real belt driver does (the ``BELT`` topic, one user or every user),
decodes with the same codec, and keeps what arrived with its arrival time; undecodable
payloads are counted, as the real driver would refuse them. Optionally one JSON line per
pattern goes to a file, for the demo and for anyone checking a run afterwards.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltPattern, Message
from protocol.session import ZenohSettings
from protocol.topics import Topic

M = TypeVar("M", bound=Message)


@dataclass(frozen=True)
class Received(Generic[M]):
    user: str
    msg: M
    at: float
    """``time.perf_counter()`` on arrival, for latency measurements."""


class Recorder(Generic[M]):
    """Records the messages of one topic, for one user or every user."""

    def __init__(
        self,
        session: zenoh.Session,
        topic: Topic,
        user: str | None = None,
        out: Path | None = None,
    ) -> None:
        if topic.model is None:
            raise ValueError(f"{topic.name} carries no message to record")
        self.topic = topic
        self.kind: type[M] = topic.model  # type: ignore[assignment]
        self.received: list[Received[M]] = []
        self.rejected = 0
        self._cond = threading.Condition()
        self._file = out.open("a") if out is not None else None
        self._sub = wire.declare_subscriber(
            session, topic, Callback(self._on_sample, indirect=False), user
        )

    def _on_sample(self, sample: zenoh.Sample) -> None:
        at = time.perf_counter()
        try:
            msg = codec.decode(self.kind, sample.payload.to_bytes())
            user = self.topic.user_of(sample.key_expr)
        except ValueError:
            with self._cond:
                self.rejected += 1
            return
        with self._cond:
            self.received.append(Received(user, msg, at))
            if self._file is not None:
                self._file.write(json.dumps({"user": user, **msg.model_dump(mode="json")}) + "\n")
                self._file.flush()
            self._cond.notify_all()

    def wait_for(
        self, pred: Callable[[Received[M]], bool], timeout_s: float = 5.0
    ) -> Received[M] | None:
        """The first received message (old or new) with ``pred(received)``, or None."""
        end = time.monotonic() + timeout_s
        with self._cond:
            while True:
                for r in self.received:
                    if pred(r):
                        return r
                left = end - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)

    def clear(self) -> None:
        with self._cond:
            self.received.clear()

    def close(self) -> None:
        self._sub.undeclare()
        if self._file is not None:
            self._file.close()
            self._file = None


class BeltRecorder(Recorder[BeltPattern]):
    def __init__(
        self, session: zenoh.Session, user: str | None = None, out: Path | None = None
    ) -> None:
        super().__init__(session, T.BELT, user, out)

    def kinds(self, user: str | None = None) -> list[str]:
        with self._cond:
            return [str(r.msg.kind) for r in self.received if user in (None, r.user)]


def main(recorder: type[Recorder] = BeltRecorder, what: str = "belt patterns") -> None:
    """Run a recorder as its own process until SIGTERM or Ctrl-C, one JSON line per message."""
    import argparse
    import signal

    ap = argparse.ArgumentParser(description=f"Record {what} from a guidebelt daemon.")
    ap.add_argument("--connect", action="append", default=None, help="zenoh endpoint")
    ap.add_argument("--user", default=None, help="one user (default: every user)")
    ap.add_argument("--out", type=Path, default=Path("/dev/stdout"))
    args = ap.parse_args()
    settings = ZenohSettings(
        connect=args.connect or ["tcp/127.0.0.1:7447"], multicast_scouting=False
    )
    session = wire.open_session(settings)
    rec = recorder(session, args.user, args.out)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        stop.wait()
    except KeyboardInterrupt:
        pass
    finally:
        rec.close()
        session.close()


if __name__ == "__main__":
    main()
