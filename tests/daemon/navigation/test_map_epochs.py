"""Map sources with epochs: a restarted mapper (new epoch, sequence 0 again) is resynchronised
from its snapshot, not ignored up to the old sequence; what its old epoch still sends is refused.
Also the codec's optional epoch, and a map restored from the daemon's own store."""

from __future__ import annotations

import struct
import time

import numpy as np
import pytest

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.planning.grid import OCCUPIED
from protocol import codec
from protocol.messages import (
    Goal,
    GoalCell,
    MapDelta,
    MapSnapshot,
    NavState,
    PatternKind,
    Pose,
)
from sim.courtyard import make_courtyard
from sim.world import World

SHAPE = (30, 30)
A, B = 0xA11CE, 2**64 - 1  # two epochs; B at the top of the range


def navigator() -> Navigator:
    return Navigator("u", NavigatorSettings(backend="cpu"))


def delta(seq, cells, values, epoch) -> MapDelta:
    return MapDelta.from_arrays(
        seq, SHAPE, np.array(cells), np.array(values), time.time(), epoch=epoch
    )


def pose(cell) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57, stamp=time.time())


# -- the wire -----------------------------------------------------------------------------


def test_the_epoch_travels_in_deltas_and_snapshots_and_old_senders_still_decode():
    d = delta(3, [1, 2], [1, 0], epoch=B)
    data = codec.encode(d)
    assert len(data) == codec.HEADER.size + 8 + 10
    assert codec.decode(MapDelta, data) == d
    snap = MapSnapshot.from_array(4, np.eye(20, dtype=np.uint8), time.time(), epoch=A)
    assert codec.decode(MapSnapshot, codec.encode(snap)).epoch == A
    old = codec.encode(delta(3, [1], [1], epoch=None))  # flags 0: as a sender before epochs
    assert struct.unpack_from("<H", old, 6) == (0,) and codec.decode(MapDelta, old).epoch is None


@pytest.mark.parametrize(
    ("flags", "tail", "why"),
    [(0x0002, b"", "unknown header flags"), (0x0001, b"\x00" * 4, "epoch follows")],
)
def test_unknown_flags_and_a_missing_epoch_are_refused(flags, tail, why):
    head = struct.pack("<4sHHIIIdI", b"GBMD", 1, flags, 0, 10, 10, 1.0, 0)
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(MapDelta, head + tail)
    assert err.value.code == "malformed" and why in err.value.reason


def test_an_epoch_beyond_64_bits_is_invalid():
    with pytest.raises(ValueError, match="less than"):
        delta(0, [], [], epoch=2**64)


# -- the keeper ---------------------------------------------------------------------------


def test_a_restarted_source_is_resynchronised_and_its_old_epoch_refused():
    s = navigator()
    goal = Goal(target=GoalCell(row=3, col=15), stamp=time.time())
    s.step(Inbox(deltas=[delta(0, [], [], A)], goal=goal, pose=pose((26, 15))), time.time())
    for seq in range(1, 40):  # the old source got far
        s.step(Inbox(deltas=[delta(seq, [899], [1], A)], pose=pose((26, 15))), time.time())
    assert s.maps.seq == 39 and s.state == NavState.GUIDING
    wall = [12 * 30 + c for c in range(0, 25)]
    out = s.step(Inbox(deltas=[delta(0, wall, [1] * 25, B)], pose=pose((26, 15))), time.time())
    # Not taken for "already applied": the map is stale and the user waits for the snapshot.
    assert out.want_snapshot and s.maps.stale and s.maps.epoch == B
    assert [st.code for st in out.statuses] == ["new_epoch"]
    assert [p.kind for p in out.belt] == [PatternKind.WAIT]
    out = s.step(Inbox(pose=pose((26, 15))), time.time())
    assert [p.kind for p in out.belt] == [PatternKind.WAIT] and out.path() is None
    # The old epoch is refused by name, and so is a snapshot of it.
    out = s.step(Inbox(deltas=[delta(40, [7], [1], A)]), time.time())
    assert [st.code for st in out.statuses] == ["old_epoch"] and s.rejected_by_code["old_epoch"]
    occ = np.full(SHAPE, 2, np.uint8)
    occ.reshape(-1)[wall] = 1
    out = s.step(Inbox(snapshot=MapSnapshot.from_array(5, occ, time.time(), A)), time.time())
    assert [st.code for st in out.statuses] == ["old_epoch"] and s.maps.stale
    # The new epoch's snapshot brings the wall; deltas buffered meanwhile replay on top.
    out = s.step(Inbox(deltas=[delta(1, [0], [1], B)]), time.time())
    assert out.want_snapshot  # the failed snapshot is asked for again
    snap = MapSnapshot.from_array(0, occ, time.time(), B)
    s.step(Inbox(snapshot=snap, pose=pose((26, 15))), time.time())
    assert not s.maps.stale and s.maps.seq == 1 and s.maps.epoch == B
    assert (s.maps.map.occupancy.reshape(-1)[wall] == 1).all()
    assert s.maps.map.occupancy.reshape(-1)[0] == 1
    assert s.state in (NavState.GUIDING, NavState.REROUTING)


def test_restart_the_source_mid_walk_at_sequence_0_and_the_new_wall_reaches_the_map():
    """The closed loop of ``sim.closed_loop``, by hand: the mapper restarts mid-walk and a
    wall appears in front of the user at the same time."""
    scenario = make_courtyard(50, 0.2, seed=3)
    world = World(scenario, "path", epoch=A)
    s = Navigator("u", NavigatorSettings(backend="cpu", cell_m=scenario.cell_m))
    now = 1000.0
    goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=now)
    inbox = Inbox(deltas=world.first_deltas(now), goal=goal)
    wall: np.ndarray | None = None
    waited = 0
    for step in range(400):
        inbox.pose = world.pose(now)
        out = s.step(inbox, now)
        if s.state == NavState.ARRIVED:
            break
        if wall is not None and s.maps.stale:
            waited += 1
            assert out.path() is None  # never guided on the map it knows is stale
        if step == 8:  # the mapper restarts; something new stands in the way
            r, c = (int(v) for v in out.path_cells[min(6, len(out.path_cells) - 1)])
            wall = np.zeros(scenario.shape, bool)
            wall[r - 1 : r + 2, c - 1 : c + 2] = True
            world.true[wall] = OCCUPIED
            inbox = Inbox(deltas=world.restart_mapper(now))
        else:
            world.act(out.path_cells, out.belt[-1] if out.belt else None, now)
            inbox = Inbox(deltas=world.sense(now))
        if out.want_snapshot:  # as the sim node's map source answers
            inbox.snapshot = world.snapshot(now)
        now += 0.1
    assert s.state == NavState.ARRIVED
    assert wall is not None and waited >= 1
    assert s.maps.epoch == world.epoch != A
    assert (s.maps.map.occupancy[wall & (world.known == OCCUPIED)] == OCCUPIED).all()
    assert (world.known[wall] == OCCUPIED).any()  # the sensor did see the wall
    assert np.array_equal(s.maps.map.occupancy, world.known)


def test_a_restored_map_waits_for_the_source_or_stands_when_it_is_silent():
    s = navigator()
    occ = np.full(SHAPE, 2, np.uint8)
    s.maps.restore(occ, 7, A, attempts=2)
    goal = Goal(target=GoalCell(row=3, col=15), stamp=time.time())
    out = s.step(Inbox(goal=goal, pose=pose((26, 15))), time.time())
    assert [p.kind for p in out.belt] == [PatternKind.WAIT] and out.path() is None
    s.step(Inbox(snapshot_failed=True), time.time())  # the source may not be back yet
    out = s.step(Inbox(pose=pose((26, 15))), time.time())
    assert [p.kind for p in out.belt] == [PatternKind.WAIT] and out.path() is None
    s.step(Inbox(snapshot_failed=True), time.time())  # still none: the stored map stands
    out = s.step(Inbox(pose=pose((26, 15))), time.time())
    assert out.path() is not None and s.maps.seq == 7
    out = s.step(Inbox(deltas=[delta(8, [3], [1], A)]), time.time())
    assert s.maps.seq == 8 and not out.want_snapshot  # the same epoch goes on in sequence


def test_a_restored_map_is_replaced_by_the_sources_snapshot():
    s = navigator()
    s.maps.restore(np.full(SHAPE, 2, np.uint8), 7, A, attempts=3)
    occ = np.full(SHAPE, 0, np.uint8)
    occ[12, :20] = 1
    s.step(Inbox(snapshot=MapSnapshot.from_array(9, occ, time.time(), A)), time.time())
    assert not s.maps.stale and not s.maps.restored and s.maps.seq == 9
    assert np.array_equal(s.maps.map.occupancy, occ)
