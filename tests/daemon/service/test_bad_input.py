"""Every kind of bad input: its status, its belt pattern, a counter; nothing crashes and a
rejected delta changes nothing. Each case uses its own user, so cases cannot mix."""

from __future__ import annotations

import json
import struct
import time

import numpy as np
import pytest
from zenoh.handlers import Callback

from daemon.service.embedded import DaemonThread
from drivers.belt.recorder import BeltRecorder, Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import (
    MAX_DELTA_CELLS,
    Goal,
    GoalCell,
    GoalLandmark,
    Health,
    MapDelta,
    MapSnapshot,
    NavStatus,
    Pose,
)

SHAPE = (20, 20)
CELL_M = 0.10


class Watch:
    """Status and belt recorders for one user."""

    def __init__(self, session, user: str) -> None:
        self.user = user
        self.status: Recorder[NavStatus] = Recorder(session, T.STATUS, user)
        self.belt = BeltRecorder(session, user)
        time.sleep(0.15)  # declarations reach the daemon before the first input

    def expect(self, code: str, state: str, pattern: str, timeout_s: float = 10.0) -> NavStatus:
        got = self.status.wait_for(lambda r: r.msg.code == code, timeout_s)
        assert got is not None, f"{self.user}: no status {code}; saw {self.codes()}"
        assert got.msg.state == state
        assert self.belt.wait_for(lambda r: r.msg.kind == pattern, timeout_s) is not None, (
            f"{self.user}: no {pattern} pattern; saw {self.belt.kinds()}"
        )
        return got.msg

    def codes(self) -> list[str]:
        return [r.msg.code for r in self.status.received]

    def close(self) -> None:
        self.status.close()
        self.belt.close()


@pytest.fixture
def watch(peer):
    made: list[Watch] = []

    def make(user: str) -> Watch:
        made.append(Watch(peer, user))
        return made[-1]

    yield make
    for w in made:
        w.close()


def put(session, topic: T.Topic, user: str, payload) -> None:
    data = payload if isinstance(payload, bytes) else codec.encode(payload)
    wire.put(session, topic, user, data)


def delta(seq: int, cells=(), values=(), shape=SHAPE) -> MapDelta:
    return MapDelta.from_arrays(
        seq, shape, np.array(cells, np.int64), np.array(values, np.uint8), time.time()
    )


def walls(shape=SHAPE) -> tuple[list[int], list[int]]:
    """The border of the map, occupied."""
    occ = np.zeros(shape, bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    cells = np.flatnonzero(occ).tolist()
    return cells, [1] * len(cells)


def pose_at(cell: tuple[int, int], age_s: float = 0.0) -> Pose:
    x, y = (cell[1] + 0.5) * CELL_M, (SHAPE[0] - cell[0] - 0.5) * CELL_M
    return Pose(x=x, y=y, heading=1.57, stamp=time.time() - age_s)


def goal_cell(r: int, c: int) -> Goal:
    return Goal(target=GoalCell(row=r, col=c), stamp=time.time())


def snapshot(peer, user: str) -> MapSnapshot | None:
    for reply in wire.get(peer, T.MAP_SNAPSHOT, user):
        if reply.ok is not None:
            return codec.decode(MapSnapshot, reply.ok.payload.to_bytes())
    return None


def health(peer) -> Health:
    reply = next(r.ok for r in wire.get(peer, T.HEALTH) if r.ok is not None)
    return codec.decode(Health, reply.payload.to_bytes())


@pytest.mark.timeout(90)
@pytest.mark.parametrize(
    ("topic", "payload", "code"),
    [
        (T.GOAL, b"\x00\xff not json", "malformed"),
        (T.POSE, b"{\"x\": 1.0, \"y\":", "malformed"),
        (T.MAP_DELTA, b"GBMD\x01", "malformed"),
        (T.POSE, json.dumps({"x": "east", "y": 1, "heading": 0, "stamp": 1}).encode(),
         "wrong_type"),
        (T.GOAL, json.dumps({"target": {"kind": "cell", "row": [1], "col": 2}, "stamp": 1})
         .encode(), "wrong_type"),
        (T.POSE, json.dumps({"x": 1, "y": 1, "heading": 0, "stamp": 1, "z": 3}).encode(),
         "unknown_field"),
        (T.GOAL, json.dumps({"target": {"kind": "cell", "row": 1, "col": 2}, "stamp": 1,
                             "priority": "high"}).encode(), "unknown_field"),
    ],
)
def test_undecodable_messages_stop_the_belt_and_are_counted(peer, watch, topic, payload, code):
    user = f"bad-{code}-{topic.name}".replace("_", "-")
    w = watch(user)
    before = health(peer).rejected
    put(peer, topic, user, payload)
    status = w.expect(code, "error", "stop")
    assert status.rejected == 1
    assert health(peer).rejected == before + 1


@pytest.mark.timeout(90)
def test_goal_off_the_map_inside_an_obstacle_or_unknown(peer, watch):
    w = watch("goals")
    cells, values = walls()
    put(peer, T.MAP_DELTA, "goals", delta(0, [*cells, 5 * 20 + 5], [*values, 1]))
    put(peer, T.POSE, "goals", pose_at((15, 10)))
    put(peer, T.GOAL, "goals", goal_cell(50, 3))
    assert "outside" in w.expect("goal_off_map", "no_path", "no_path").reason
    w.belt.clear()
    put(peer, T.GOAL, "goals", goal_cell(5, 5))
    assert "obstacle" in w.expect("goal_in_obstacle", "no_path", "no_path").reason
    w.belt.clear()
    put(peer, T.GOAL, "goals", Goal(target=GoalLandmark(name="nowhere"), stamp=time.time()))
    w.expect("unknown_landmark", "no_path", "no_path")
    # A good goal afterwards is guided to: the session survived all three.
    put(peer, T.GOAL, "goals", goal_cell(6, 10))
    put(peer, T.POSE, "goals", pose_at((15, 10)))
    assert w.belt.wait_for(lambda r: r.msg.kind == "guide") is not None


@pytest.mark.timeout(90)
def test_goal_with_no_path_says_so(peer, watch):
    w = watch("walled")
    occ = np.zeros(SHAPE, bool)
    occ[1:12, 1] = occ[1:12, 11] = occ[1, 1:12] = occ[11, 1:12] = True  # a closed box round (6, 6)
    cells = np.flatnonzero(occ).tolist()
    put(peer, T.MAP_DELTA, "walled", delta(0, cells, [1] * len(cells)))
    put(peer, T.GOAL, "walled", goal_cell(6, 6))
    put(peer, T.POSE, "walled", pose_at((15, 15)))
    w.expect("no_path", "no_path", "no_path")


@pytest.mark.timeout(90)
def test_pose_off_the_map_and_stale_pose_stop_the_user(peer, watch):
    w = watch("poses")
    put(peer, T.MAP_DELTA, "poses", delta(0, *walls()))
    put(peer, T.GOAL, "poses", goal_cell(6, 10))
    put(peer, T.POSE, "poses", Pose(x=-4.0, y=1.0, heading=0.0, stamp=time.time()))
    w.expect("pose_off_map", "error", "stop")
    w.belt.clear()
    put(peer, T.POSE, "poses", pose_at((15, 10), age_s=2.0))
    status = w.expect("stale_pose", "stale", "stop")
    assert status.rejected == 2


@pytest.mark.timeout(90)
def test_guiding_stops_when_poses_stop_coming(peer, watch):
    w = watch("silent")
    put(peer, T.MAP_DELTA, "silent", delta(0, *walls()))
    put(peer, T.GOAL, "silent", goal_cell(6, 10))
    put(peer, T.POSE, "silent", pose_at((15, 10)))
    assert w.status.wait_for(lambda r: r.msg.state == "guiding") is not None
    w.belt.clear()
    # No more poses: within stale_pose_s plus a tick the belt says STOP.
    status = w.expect("stale_pose", "stale", "stop", timeout_s=3.0)
    assert "no pose" in status.reason


@pytest.mark.timeout(90)
def test_oversized_delta_is_rejected_whole(peer, watch):
    w = watch("big")
    cells, values = walls()
    put(peer, T.MAP_DELTA, "big", delta(0, cells, values))
    put(peer, T.POSE, "big", pose_at((15, 10)))
    time.sleep(0.3)
    before = snapshot(peer, "big")
    assert before is not None
    n = MAX_DELTA_CELLS + 1
    header = struct.pack("<4sHHIIIdI", b"GBMD", 1, 0, 1, *SHAPE, time.time(), n)
    body = np.full(n, 21, "<u4").tobytes() + np.ones(n, np.uint8).tobytes()
    put(peer, T.MAP_DELTA, "big", header + body)
    w.expect("oversized", "error", "wait")
    after = snapshot(peer, "big")
    assert after.seq == before.seq == 0
    assert np.array_equal(after.array(), before.array())


@pytest.mark.timeout(90)
def test_sequence_gap_asks_for_a_snapshot_and_resyncs(peer, watch):
    w = watch("gappy")
    source = np.full(SHAPE, 2, np.uint8)
    source[10, 3:17] = 1  # the mapper knows a wall the daemon never got a delta for
    asked = []

    def on_source(query) -> None:
        asked.append(time.time())
        snap = MapSnapshot.from_array(7, source, time.time())
        wire.reply(query, T.MAP_SOURCE, "gappy", codec.encode(snap))
        query.drop()

    mapper = wire.declare_queryable(
        peer, T.MAP_SOURCE, Callback(on_source, indirect=False), "gappy"
    )
    try:
        put(peer, T.MAP_DELTA, "gappy", delta(0, *walls()))
        time.sleep(0.3)
        put(peer, T.MAP_DELTA, "gappy", delta(2, [21], [1]))
        status = w.expect("sequence_gap", "stale", "wait")
        assert "expected delta 1, got 2" in status.reason
        deadline = time.time() + 5
        while time.time() < deadline:
            snap = snapshot(peer, "gappy")
            if snap is not None and snap.seq == 7:
                break
            time.sleep(0.05)
        assert asked, "the daemon never asked the map source"
        assert snap.seq == 7
        assert np.array_equal(snap.array(), source)  # delta 2 (older than 7) was not replayed
        # The sequence goes on from the snapshot.
        put(peer, T.MAP_DELTA, "gappy", delta(8, [22], [1]))
        time.sleep(0.3)
        snap = snapshot(peer, "gappy")
        assert snap.seq == 8 and snap.array().reshape(-1)[22] == 1
    finally:
        mapper.undeclare()


@pytest.mark.timeout(90)
def test_bad_key_and_the_daemon_keeps_serving(peer, daemon):
    before = health(peer).rejected
    # The table refuses to build this key, so it is made by hand from a valid one.
    peer.put(T.POSE.any_user().replace("*", "Not A User"), b"{}")
    time.sleep(0.3)
    after = health(peer)
    assert after.rejected == before + 1
    assert daemon.daemon.ready.is_set()


@pytest.mark.timeout(90)
def test_a_silent_user_is_forgotten_and_their_belt_turned_off():
    with DaemonThread(backend="cpu", user_idle_s=0.5, tick_s=0.1) as d:
        peer = d.peer()
        try:
            w = Watch(peer, "ghost")
            put(peer, T.POSE, "ghost", b"not a pose")
            w.expect("malformed", "error", "stop")
            final = w.expect("idle", "idle", "off", timeout_s=5.0)
            assert "nothing heard" in final.reason
            assert "ghost" not in health(peer).users
            w.close()
        finally:
            peer.close()
