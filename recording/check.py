"""``guidebelt replay --check``: a fresh daemon on a recording's inputs, its outputs compared.

Alignment is by input sequence, not by wall time. The recorded inputs are put in the order
their senders stamped them (the input sequence) and fed one at a time, each re-stamped to
now; the next goes once the daemon has answered this one (the path planned from this pose or
on this map delta, a status after a goal), as the simulated walker itself waits. An input
the recorded daemon answered only together with the user's next one (a pose before the
goal) waits only as long as the recording did.

What is compared, per user:

- the belt pattern (kind, motors, pulse) of each planning step, the step named by what it
  planned on: the pose it planned from (by its number among the inputs) and the last map
  delta it reflects (its path's ``map_seq``). Both daemons plan from pose #k on map m: the
  patterns must be equal. A step only the replay has (it fed deltas one by one where the
  recorded daemon took two at once) is not a difference; a recorded step the replay never
  made is one;
- the statuses (state, code) as a sequence with repeats folded (the daemon's tick repeats
  them at times that depend on the clock, not on the inputs).
"""

from __future__ import annotations

import bisect
import difflib
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import (
    BeltPattern,
    MapDelta,
    Message,
    NavPath,
    NavStatus,
    Pose,
    StatusCode,
)

from .channels import INPUTS
from .replay import Player, Recorded

ANSWER_S = 1.0
"""The longest wait for the daemon's answer to an input the recorded daemon answered."""
RESEND_S = 0.2
"""A pose with no answer by then is sent again (the simulated walker's own pose period)."""

StepKey = tuple[str, int, int]
"""(user, number of the pose input planned from, last map delta reflected)."""


def belt_value(msg: BeltPattern) -> tuple:
    return (str(msg.kind), tuple(msg.motors), msg.period_ms)


def status_value(msg: NavStatus) -> tuple:
    return (str(msg.state), str(msg.code))


@dataclass
class Difference:
    what: str
    after_input: int
    recorded: list[tuple]
    replayed: list[tuple]

    def __str__(self) -> str:
        return (
            f"{self.what} after input #{self.after_input}: recorded {self.recorded}, "
            f"replayed {self.replayed}"
        )


@dataclass
class Outputs:
    """One daemon's outputs, in the order heard, and the input being fed as each came."""

    items: list[tuple[int, str, Message]] = field(default_factory=list)

    def step_belts(self, pose_index: dict[tuple[str, float], int]) -> dict[StepKey, tuple | None]:
        """The belt pattern of the first step planned from each (pose, map): a belt and its
        path share the step's stamp."""
        # All belts first: a step's belt and path travel on two keys, heard in either order.
        belts = {
            (T.user_of(key), msg.stamp): belt_value(msg)
            for _label, key, msg in self.items
            if isinstance(msg, BeltPattern)
        }
        out: dict[StepKey, tuple | None] = {}
        for _label, key, msg in self.items:
            user = T.user_of(key)
            if isinstance(msg, NavPath):
                k = pose_index.get((user, msg.pose_stamp))
                if k is not None:
                    out.setdefault((user, k, msg.map_seq), belts.get((user, msg.stamp)))
        return out

    def statuses(self) -> dict[str, list[tuple[int, tuple]]]:
        folded: dict[str, list[tuple[int, tuple]]] = {}
        for label, key, msg in self.items:
            # A daemon's own stop (SHUTDOWN) answers no input: the fresh one is not stopped.
            if isinstance(msg, NavStatus) and msg.code != StatusCode.SHUTDOWN:
                seq = folded.setdefault(T.user_of(key), [])
                if not seq or seq[-1][1] != status_value(msg):
                    seq.append((label, status_value(msg)))
        return folded


@dataclass
class CheckReport:
    inputs: int
    steps_compared: int
    """Recorded planning steps whose belt pattern was compared."""
    statuses_compared: int
    differences: list[Difference]
    unanswered: int
    """Inputs the fresh daemon did not answer (the recorded one left some unanswered too)."""
    replayed: Outputs = field(default_factory=lambda: Outputs())
    """The fresh daemon's outputs, labelled by input, for a closer look at a difference."""


def split(items: list[Recorded]) -> tuple[list[Recorded], Outputs, dict[tuple[str, float], int]]:
    """A recording's inputs in the order their senders stamped them, its outputs labelled by
    the input before them, and its poses' numbers. Stamp order, not the order heard: the
    recorder hears the simulator's delta and pose publishers and the daemon's on separate
    links, and may hear a delta after the path the daemon planned on it."""
    inputs = sorted((r for r in items if r.topic in INPUTS), key=lambda r: r.msg.stamp)
    poses = {
        (T.user_of(r.key), r.msg.stamp): n for n, r in enumerate(inputs) if isinstance(r.msg, Pose)
    }
    outputs = Outputs()
    heard = 0
    for r in items:
        if r.topic in INPUTS:
            heard += 1
        else:
            outputs.items.append((heard - 1, r.key, r.msg))
    return inputs, outputs, poses


def _same_user_next(inputs: list[Recorded]) -> dict[int, int]:
    """Input number → the number of the same user's next input. Users are stepped apart (a
    runner each), so that is the next input that counts for an answer."""
    following: dict[int, int] = {}
    last_of: dict[str, int] = {}
    for n, item in enumerate(inputs):
        user = T.user_of(item.key)
        if user in last_of:
            following[last_of[user]] = n
        last_of[user] = n
    return following


def _answered_alone(inputs: list[Recorded], outputs: Outputs) -> list[bool]:
    """For each input, whether the recorded daemon answered it without the user's next input.
    A step's path names the pose it planned from: a step that answered this input and did not
    plan from the next pose took this one alone. When the next input is not a pose, the step
    must have begun (its stamp, the daemon's clock) before the next input was stamped (the
    senders' clock; one machine in the demo). A pose sent before the goal was answered only
    once the goal came: feeding it, the check waits no longer than the recording did, or
    the fresh daemon would find that pose stale."""
    by_stamp = sorted(((msg.stamp, key, msg) for _l, key, msg in outputs.items), key=lambda o: o[0])
    stamps = [o[0] for o in by_stamp]
    paths = {(T.user_of(k), m.stamp): m for _s, k, m in by_stamp if isinstance(m, NavPath)}
    following = _same_user_next(inputs)
    out = []
    for n, item in enumerate(inputs):
        user, sent = T.user_of(item.key), item.msg
        nxt = inputs[following[n]].msg if n in following else None
        after = following.get(following[n]) if n in following else None
        until = inputs[after].msg.stamp if after is not None else math.inf
        window = by_stamp[
            bisect.bisect_left(stamps, sent.stamp) : bisect.bisect_left(stamps, until)
        ]
        out.append(
            any(
                _answers(key, msg, user, sent)
                and not _reflects(paths.get((user, msg.stamp)), msg.stamp, nxt)
                for _s, key, msg in window
            )
        )
    return out


def _reflects(path: NavPath | None, step: float, nxt: Message | None) -> bool:
    """Whether the step stamped ``step`` (with ``path``, if it made one) had taken ``nxt``."""
    if nxt is None:
        return False
    if path is not None and isinstance(nxt, Pose):
        return path.pose_stamp == nxt.stamp
    # Not ``map_seq`` for a delta: a delta the daemon ignored (an old sequence number, a
    # walker starting again under the same name) is below it and was never taken.
    return step >= nxt.stamp


def _answers(key: str, out: Message, user: str, sent: Message) -> bool:
    if T.user_of(key) != user:
        return False
    if isinstance(sent, Pose):
        return isinstance(out, NavPath) and out.pose_stamp == sent.stamp
    if isinstance(sent, MapDelta):
        return isinstance(out, NavPath) and out.map_seq >= sent.seq
    return isinstance(out, NavStatus)


class _Listener:
    """The fresh daemon's outputs, labelled with the input being fed when each came."""

    def __init__(self, session: zenoh.Session) -> None:
        self.labels: dict[str, int] = {}
        self.outputs = Outputs()
        self._cond = threading.Condition()
        self._subs = [
            wire.declare_subscriber(session, t, Callback(self._on(t), indirect=False))
            for t in (T.BELT, T.PATH, T.STATUS)
        ]

    def _on(self, topic: T.Topic):
        model = topic.model
        assert model is not None

        def on_sample(sample: zenoh.Sample) -> None:
            msg = codec.decode(model, sample.payload.to_bytes())
            key = str(sample.key_expr)
            with self._cond:
                self.outputs.items.append((self.labels.get(T.user_of(key), -1), key, msg))
                self._cond.notify_all()

        return on_sample

    def feed(self, user: str, label: int) -> int:
        """Label ``user``'s outputs from now on with ``label``; how many outputs came so far."""
        with self._cond:
            self.labels[user] = label
            return len(self.outputs.items)

    def wait_answer(self, key: str, sent: list[Message], since: int, timeout_s: float) -> bool:
        """Wait until an output since ``since`` answers one of ``sent`` (one input, sent once
        or again)."""
        user = T.user_of(key)

        def answered() -> bool:
            return any(
                _answers(k, m, user, one) for _, k, m in self.outputs.items[since:] for one in sent
            )

        with self._cond:
            return self._cond.wait_for(answered, timeout_s)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()


def check(
    session: zenoh.Session,
    items: list[Recorded],
    on_input: Callable[[int], None] | None = None,
) -> CheckReport:
    """Feed ``items``' inputs to the daemon ``session`` is connected to; compare its outputs.

    Each user's inputs are fed by a thread of their own, in lock step with that user's
    answers: fed one after another across users, one user's wait would age another's pose."""
    inputs, recorded, recorded_poses = split(items)
    feed = _Feed(inputs, _answered_alone(inputs, recorded), _Listener(session), on_input)
    by_user: dict[str, list[int]] = {}
    for n, item in enumerate(inputs):
        by_user.setdefault(T.user_of(item.key), []).append(n)
    threads = [
        threading.Thread(target=feed.user, args=(session, numbers), name=f"check-{user}")
        for user, numbers in by_user.items()
    ]
    try:
        time.sleep(0.1)  # the daemon's subscribers match ours before the first input
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        time.sleep(0.2)  # the last step's status follows its path
    finally:
        feed.listener.close()
    if feed.error is not None:
        raise feed.error
    outputs = feed.listener.outputs
    want, got = recorded.step_belts(recorded_poses), outputs.step_belts(feed.poses)
    want_status, got_status = recorded.statuses(), outputs.statuses()
    return CheckReport(
        inputs=len(inputs),
        steps_compared=len(want),
        statuses_compared=sum(len(v) for v in want_status.values()),
        differences=compare_steps(want, got) + compare_statuses(want_status, got_status),
        unanswered=feed.unanswered,
        replayed=outputs,
    )


class _Feed:
    """What the per-user feeders share: the listener, the replayed poses' numbers, counts."""

    def __init__(self, inputs, answered_alone, listener: _Listener, on_input) -> None:
        self.inputs = inputs
        self.answered_alone = answered_alone
        self.following = _same_user_next(inputs)
        self.listener = listener
        self.on_input = on_input
        self.poses: dict[tuple[str, float], int] = {}
        self.unanswered = 0
        self.fed = 0
        self.error: BaseException | None = None
        self._lock = threading.Lock()

    def user(self, session: zenoh.Session, numbers: list[int]) -> None:
        player = Player(session, [self.inputs[n] for n in numbers], speed=0)
        try:
            for n in numbers:
                self._one(player, n)
        except BaseException as exc:  # reported by check(), on its own thread
            self.error = exc
        finally:
            player.close()

    def _one(self, player: Player, n: int) -> None:
        item = self.inputs[n]
        user = T.user_of(item.key)
        since = self.listener.feed(user, n)
        sent = self._send(player, user, n)
        if self.answered_alone[n]:
            answered = self._await(player, user, n, [sent], since)
        else:
            nxt = self.following.get(n)
            gap = self.inputs[nxt].msg.stamp - item.msg.stamp if nxt is not None else 0.2
            answered = self.listener.wait_answer(item.key, [sent], since, min(ANSWER_S, gap))
        with self._lock:
            self.unanswered += not answered
            self.fed += 1
            if self.on_input is not None:
                self.on_input(self.fed)

    def _send(self, player: Player, user: str, n: int) -> Message:
        player.publish(self.inputs[n], time.time())
        sent = player.last
        assert sent is not None
        if isinstance(sent, Pose):
            self.poses[(user, sent.stamp)] = n
        return sent

    def _await(self, player: Player, user: str, n: int, sent: list[Message], since: int) -> bool:
        """Wait for the answer; a pose not answered within ``RESEND_S`` is sent again. Poses
        are latest-wins on the wire (a full queue drops one), and the walker too sends its
        pose again when nothing comes back, so the recorded daemon never waited for one."""
        end = time.monotonic() + ANSWER_S
        key = self.inputs[n].key
        while True:
            left = end - time.monotonic()
            step = min(RESEND_S, left) if isinstance(sent[0], Pose) else left
            if self.listener.wait_answer(key, sent, since, max(0.0, step)):
                return True
            if time.monotonic() >= end:
                return False
            sent.append(self._send(player, user, n))


def compare_steps(
    want: dict[StepKey, tuple | None], got: dict[StepKey, tuple | None]
) -> list[Difference]:
    out = []
    for key in sorted(want):
        user, pose, seq = key
        if key not in got:
            what = f"{user}: belt of the step from pose #{pose} on map {seq} (replay made none)"
            out.append(Difference(what, pose, [want[key]], []))
        elif got[key] != want[key]:
            what = f"{user}: belt of the step from pose #{pose} on map {seq}"
            out.append(Difference(what, pose, [want[key]], [got[key]]))
    return out


def compare_statuses(
    want: dict[str, list[tuple[int, tuple]]], got: dict[str, list[tuple[int, tuple]]]
) -> list[Difference]:
    out = []
    for user in sorted(set(want) | set(got)):
        a, b = want.get(user, []), got.get(user, [])
        matcher = difflib.SequenceMatcher(a=[v for _, v in a], b=[v for _, v in b], autojunk=False)
        for op, i1, i2, j1, j2 in matcher.get_opcodes():
            if op != "equal":
                label = a[i1][0] if i1 < len(a) else (b[j1][0] if j1 < len(b) else -1)
                what = f"{user}: statuses"
                out.append(Difference(what, label, [v for _, v in a[i1:i2]],
                                      [v for _, v in b[j1:j2]]))  # fmt: skip
    return out
