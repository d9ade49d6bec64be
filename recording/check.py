"""``guidebelt replay --check``: a fresh daemon on a recording's inputs, its outputs compared.

Alignment is by input sequence, not by wall time: the recorded inputs are fed one at a time,
each re-stamped to now, and the next goes only once the daemon has answered this one (the
path planned from this pose, or on this map delta; a status after a goal), as the simulated
walker itself waits. Every output, recorded or replayed, is labelled with the number of the
last input before it. The belt patterns (kind, motors, pulse) and the statuses (state, code)
of each user are compared as sequences with repeats folded (the daemon's tick refreshes a
pattern at times that depend on the clock, not on the inputs); each difference is reported
with the input it followed.
"""

from __future__ import annotations

import difflib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltPattern, MapDelta, Message, NavPath, NavStatus, Pose

from .channels import INPUTS
from .replay import Player, Recorded

COMPARED = (T.BELT, T.STATUS)
ANSWER_S = 1.0
"""The longest wait for the daemon's answer to one input the recorded daemon answered. One it
did not answer (a pose before any goal) waits as long as the recording did before the next:
longer would let the fresh daemon find a pose stale that the recorded one found fresh."""


def value(msg: Message) -> tuple:
    if isinstance(msg, BeltPattern):
        return (str(msg.kind), tuple(msg.motors), msg.period_ms)
    if isinstance(msg, NavStatus):
        return (str(msg.state), str(msg.code))
    raise TypeError(type(msg))


@dataclass
class Stream:
    """One user's outputs on one key: (label, value) with repeats folded."""

    items: list[tuple[int, tuple]] = field(default_factory=list)

    def add(self, label: int, v: tuple) -> None:
        if not self.items or self.items[-1][1] != v:
            self.items.append((label, v))


@dataclass
class Difference:
    key: str
    after_input: int
    recorded: list[tuple]
    replayed: list[tuple]

    def __str__(self) -> str:
        return (
            f"{self.key} after input #{self.after_input}: recorded {self.recorded}, "
            f"replayed {self.replayed}"
        )


@dataclass
class CheckReport:
    inputs: int
    compared: dict[str, int]
    """Folded outputs compared, per key."""
    differences: list[Difference]
    unanswered: int
    """Inputs the daemon gave no answer to within ``ANSWER_S``."""


def _answered_in_recording(items: list[Recorded]) -> list[bool]:
    """For each input, whether the recorded daemon answered it before the next input came (a
    path from this pose or on this delta; a status after a goal or anything else). An answer
    that came later may have needed that next input (a pose answered once the goal came)."""
    inputs = [i for i, r in enumerate(items) if r.topic in INPUTS]
    out = []
    for n, at in enumerate(inputs):
        item = items[at]
        user = T.user_of(item.key)
        until = inputs[n + 1] if n + 1 < len(inputs) else len(items)
        out.append(any(_answers(items[j], user, item.msg) for j in range(at + 1, until)))
    return out


def _answers(out: Recorded, user: str, sent: Message) -> bool:
    if T.user_of(out.key) != user:
        return False
    if isinstance(sent, Pose):
        return isinstance(out.msg, NavPath) and abs(out.msg.pose_stamp - sent.stamp) < 1e-6
    if isinstance(sent, MapDelta):
        return isinstance(out.msg, NavPath) and out.msg.map_seq >= sent.seq
    return isinstance(out.msg, NavStatus)


def recorded_streams(items: list[Recorded]) -> tuple[list[Recorded], dict[str, Stream]]:
    inputs: list[Recorded] = []
    streams: dict[str, Stream] = {}
    for r in items:
        if r.topic in INPUTS:
            inputs.append(r)
        elif r.topic in COMPARED:
            streams.setdefault(r.key, Stream()).add(len(inputs) - 1, value(r.msg))
    return inputs, streams


class _Listener:
    """The fresh daemon's outputs, labelled with the input being fed when each came."""

    def __init__(self, session: zenoh.Session) -> None:
        self.label = -1
        self.streams: dict[str, Stream] = {}
        self.paths: dict[str, NavPath] = {}
        self.statuses = 0
        self._cond = threading.Condition()
        self._subs = [
            wire.declare_subscriber(session, t, Callback(self._on(t), indirect=False))
            for t in (*COMPARED, T.PATH)
        ]

    def _on(self, topic: T.Topic):
        def on_sample(sample: zenoh.Sample) -> None:
            assert topic.model is not None
            msg = codec.decode(topic.model, sample.payload.to_bytes())
            key = str(sample.key_expr)
            with self._cond:
                if isinstance(msg, NavPath):
                    self.paths[T.user_of(key)] = msg
                else:
                    self.streams.setdefault(key, Stream()).add(self.label, value(msg))
                    self.statuses += isinstance(msg, NavStatus)
                self._cond.notify_all()

        return on_sample

    def wait(self, done: Callable[[], bool], timeout_s: float) -> bool:
        with self._cond:
            return self._cond.wait_for(done, timeout_s)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()


def _answered(listener: _Listener, item: Recorded, sent: Message, statuses: int):
    """What tells that the daemon has taken ``sent`` (the input as re-stamped)."""
    user = T.user_of(item.key)

    def path() -> NavPath | None:
        return listener.paths.get(user)

    if isinstance(sent, Pose):
        return lambda: (p := path()) is not None and abs(p.pose_stamp - sent.stamp) < 1e-6
    if isinstance(sent, MapDelta):
        return lambda: (p := path()) is not None and p.map_seq >= sent.seq
    return lambda: listener.statuses > statuses


def check(
    session: zenoh.Session,
    items: list[Recorded],
    on_input: Callable[[int], None] | None = None,
) -> CheckReport:
    """Feed ``items``' inputs to the daemon ``session`` is connected to; compare its outputs."""
    inputs, expected = recorded_streams(items)
    listener = _Listener(session)
    player = Player(session, inputs, speed=0)
    was_answered = _answered_in_recording(items)
    unanswered = 0
    try:
        time.sleep(0.1)  # the daemon's subscribers match ours before the first input
        for i, item in enumerate(inputs):
            with listener._cond:
                listener.label = i
                statuses = listener.statuses
            player.publish(item, time.time())
            assert player.last is not None
            limit = ANSWER_S
            if not was_answered[i]:
                gap = inputs[i + 1].log_time - item.log_time if i + 1 < len(inputs) else 0.2
                limit = min(ANSWER_S, max(0.0, gap))
            if not listener.wait(_answered(listener, item, player.last, statuses), limit):
                unanswered += 1
            if on_input is not None:
                on_input(i + 1)
        time.sleep(0.2)  # the last step's status follows its path
    finally:
        listener.close()
        player.close()
    return CheckReport(
        inputs=len(inputs),
        compared={k: len(s.items) for k, s in expected.items()},
        differences=compare(expected, listener.streams),
        unanswered=unanswered,
    )


def compare(expected: dict[str, Stream], got: dict[str, Stream]) -> list[Difference]:
    out = []
    for key in sorted(set(expected) | set(got)):
        a = expected.get(key, Stream()).items
        b = got.get(key, Stream()).items
        matcher = difflib.SequenceMatcher(a=[v for _, v in a], b=[v for _, v in b], autojunk=False)
        for op, i1, i2, j1, j2 in matcher.get_opcodes():
            if op == "equal":
                continue
            label = a[i1][0] if i1 < len(a) else (b[j1][0] if j1 < len(b) else -1)
            out.append(Difference(key, label, [v for _, v in a[i1:i2]], [v for _, v in b[j1:j2]]))
    return out
