"""A restarted daemon restores each session from its state database: the user waits (``restored``)
until a fresh pose, the stored map waits for its source's snapshot, and the goal needs no
client. A corrupt database costs the restore, not the start."""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest
from zenoh.handlers import Callback

from daemon.service.embedded import DaemonThread
from drivers.belt.recorder import BeltRecorder, Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapDelta, MapSnapshot, NavPath, NavStatus, Pose

EPOCH = 77
SHAPE = (20, 20)


def walls() -> np.ndarray:
    occ = np.zeros(SHAPE, np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    return occ


def pose() -> Pose:
    return Pose(x=1.0, y=0.6, heading=1.57, stamp=time.time())


@pytest.mark.timeout(60)
def test_a_restarted_daemon_restores_the_session_and_waits_for_a_fresh_pose(tmp_path):
    occ = walls()
    cells = np.flatnonzero(occ)
    with DaemonThread(backend="cpu", state_dir=tmp_path, persist_map_s=0.1) as daemon:
        peer = daemon.peer()
        status: Recorder[NavStatus] = Recorder(peer, T.STATUS, "ann")
        time.sleep(0.2)
        delta = MapDelta.from_arrays(0, SHAPE, cells, occ.reshape(-1)[cells], time.time(), EPOCH)
        wire.put(peer, T.MAP_DELTA, "ann", codec.encode(delta))
        wire.put(peer, T.GOAL, "ann", codec.encode(Goal(target=GoalCell(row=5, col=10), stamp=1)))
        # Poses until the status says guiding: one pose's status may pass before the
        # subscriber is matched on a slow machine, and a single pose goes stale after 1 s.
        guiding, deadline = None, time.monotonic() + 20.0
        while guiding is None and time.monotonic() < deadline:
            wire.put(peer, T.POSE, "ann", codec.encode(pose()))
            guiding = status.wait_for(lambda r: r.msg.state == "guiding", 0.3)
        assert guiding is not None
        status.close()
        peer.close()
    # Meanwhile the source saw a wall across the way (the stopped daemon never heard of it).
    occ[10, :10] = 1
    source = MapSnapshot.from_array(5, occ, time.time(), EPOCH)
    asked: list[float] = []

    def on_source(query) -> None:
        asked.append(time.time())
        wire.reply(query, T.MAP_SOURCE, "ann", codec.encode(source))
        query.drop()

    with DaemonThread(backend="cpu", state_dir=tmp_path) as daemon:
        peer = daemon.peer()
        status = Recorder(peer, T.STATUS, "ann")
        belt = BeltRecorder(peer, "ann")
        paths: Recorder[NavPath] = Recorder(peer, T.PATH, "ann")
        queryable = wire.declare_queryable(peer, T.MAP_SOURCE, Callback(on_source), "ann")
        restored = status.wait_for(lambda r: r.msg.code == "restored", 5.0)
        assert restored is not None and restored.msg.state == "stale"
        assert belt.wait_for(lambda r: r.msg.kind == "wait", 2.0) is not None
        assert not paths.received  # no pose since the restart: no guidance at all
        deadline = time.monotonic() + 3.0  # asked again once a second until the source is back
        while not asked and time.monotonic() < deadline:
            time.sleep(0.05)
        assert asked, "the restored map was not confirmed with the source"
        t_pose = time.time()
        wire.put(peer, T.POSE, "ann", codec.encode(pose()))  # no goal sent: it was kept
        path = paths.wait_for(lambda r: r.msg.pose_stamp >= t_pose, 5.0)
        assert path is not None
        assert all(r != 10 or c >= 10 + 3 for r, c in path.msg.cells)  # around the new wall
        snap = next(r.ok for r in wire.get(peer, T.MAP_SNAPSHOT, "ann") if r.ok is not None)
        back = codec.decode(MapSnapshot, snap.payload.to_bytes())
        assert np.array_equal(back.array(), occ) and back.epoch == EPOCH and back.seq == 5
        for rec in (status, belt, paths):
            rec.close()
        queryable.undeclare()
        peer.close()


@pytest.mark.timeout(30)
def test_a_corrupt_database_is_moved_aside_and_the_daemon_starts_fresh(tmp_path, caplog):
    (tmp_path / "state.db").write_bytes(b"\x00garbage" * 1000)
    with (
        caplog.at_level(logging.INFO, logger="guidebelt.state"),
        DaemonThread(backend="cpu", state_dir=tmp_path) as daemon,
    ):
        assert daemon.daemon.state is not None and daemon.daemon.state.db is not None
    said = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert said == ["state database unusable, moved aside; starting with no saved state"]
    assert len(list(tmp_path.glob("state.db.bad-*"))) == 1
