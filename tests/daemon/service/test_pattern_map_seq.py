"""Over zenoh: each belt pattern the daemon puts names the map its step had applied
(``BeltPattern.map_seq``), not the newest delta it heard: a delta after a gap leaves the
patterns on the last map applied, and a pattern without a valid ``map_seq`` is refused whole."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.codec import DecodeError
from protocol.messages import BeltPattern, Goal, GoalCell, MapDelta, PatternKind, Pose

N, CELL_M, USER = 40, 0.25, "mapseq"


def _delta(seq: int, cells: np.ndarray, value: int) -> bytes:
    values = np.full(cells.size, value, np.uint8)
    return codec.encode(MapDelta.from_arrays(seq, (N, N), cells, values, time.time()))


@pytest.mark.timeout(60)
def test_every_pattern_names_the_last_delta_its_step_applied():
    from daemon.service.embedded import DaemonThread

    heard: list[tuple[int, BeltPattern]] = []  # (deltas sent before it arrived, pattern)
    sent = [0]
    cond = threading.Condition()

    def on_belt(sample) -> None:
        pattern = codec.decode(BeltPattern, sample.payload.to_bytes())
        with cond:
            heard.append((sent[0], pattern))
            cond.notify_all()

    def until(what, timeout_s: float = 10.0) -> BeltPattern:
        end = time.monotonic() + timeout_s
        with cond:
            while not any(what(p) for _, p in heard):
                assert cond.wait(max(0.0, end - time.monotonic())), f"no pattern; heard {heard}"
            return next(p for _, p in heard if what(p))

    with DaemonThread(backend="cpu", guide_hz=100, cell_m=CELL_M) as d:
        peer = d.peer()
        sub = wire.declare_subscriber(peer, T.BELT, wire_callback(on_belt), USER)
        try:
            time.sleep(0.3)  # the sessions meet
            walls = np.flatnonzero(np.pad(np.zeros((N - 2, N - 2), bool), 1, constant_values=1))
            wire.put(peer, T.MAP_DELTA, USER, _delta(0, walls, 1))
            goal = Goal(target=GoalCell(row=4, col=N // 2), stamp=time.time())
            wire.put(peer, T.GOAL, USER, codec.encode(goal))
            x, y = (N // 2 + 0.5) * CELL_M, 4.5 * CELL_M

            def pose() -> None:
                p = Pose(x=x, y=y, heading=1.57, stamp=time.time())
                wire.put(peer, T.POSE, USER, codec.encode(p))

            pose()
            until(lambda p: p.kind == PatternKind.GUIDE and p.map_seq == 0)
            blob = np.array([(N // 2) * N + N // 2 + k for k in range(3)], np.int64)
            for seq in (1, 2):  # an obstacle dropped on the way, then lifted
                with cond:
                    sent[0] = seq
                wire.put(peer, T.MAP_DELTA, USER, _delta(seq, blob, 2 - seq))
                pose()
                until(lambda p, s=seq: p.map_seq == s)
            with cond:
                sent[0] = 4
            wire.put(peer, T.MAP_DELTA, USER, _delta(4, blob, 1))  # 3 is lost: a gap
            pose()
            wait = until(lambda p: p.kind == PatternKind.WAIT)
        finally:
            sub.undeclare()
            peer.close()
    # The step that heard 4 could not apply it: its WAIT is on the map of delta 2.
    assert wait.map_seq == 2
    with cond:
        seqs = [p.map_seq for _, p in heard]
        # No pattern names a delta not yet sent, and none goes back to an older map.
        assert all(p.map_seq <= n for n, p in heard)
    assert seqs == sorted(seqs) and seqs[0] >= -1 and 4 not in seqs


def wire_callback(fn):
    from zenoh.handlers import Callback

    return Callback(fn, indirect=False)


def test_a_pattern_without_or_with_a_bad_map_seq_is_refused_at_the_edge():
    good = BeltPattern(
        seq=1, map_seq=5, kind=PatternKind.GUIDE, motors=(200, 0, 0, 0), ttl_ms=700, stamp=1.0
    )
    raw = good.model_dump()
    assert codec.decode(BeltPattern, codec.encode(good)) == good
    for value in (-1, 0, 2**32 - 1):  # -1: the user had no map yet
        assert codec.decode(BeltPattern, codec.encode(good.model_copy(update={"map_seq": value})))
    for value in (-2, 2**32, 1.5, "x", None, 10**30):
        with pytest.raises(DecodeError):
            codec.decode(BeltPattern, json.dumps({**raw, "map_seq": value}).encode())
    del raw["map_seq"]
    with pytest.raises(DecodeError):  # required: a pattern that does not say is no pattern
        codec.decode(BeltPattern, json.dumps(raw).encode())
