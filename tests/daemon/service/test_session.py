"""``UserSession`` without zenoh: coalescing, resync, and the pieces around it (config,
systemd notify, journald lines)."""

from __future__ import annotations

import asyncio
import logging
import socket
import time

import numpy as np
import pytest

from daemon.planning.dijkstra import dijkstra_field
from daemon.service.config import DaemonConfig, load_config
from daemon.service.logs import JournalFormatter
from daemon.service.runner import UserRunner
from daemon.service.sdnotify import Notifier
from daemon.service.session import Inbox, UserSession
from protocol import codec
from protocol.messages import Goal, GoalCell, MapDelta, MapSnapshot, NavPath, NavState, Pose

SHAPE = (30, 30)


def session(**overrides) -> UserSession:
    return UserSession("u", DaemonConfig(backend="cpu", **overrides))


def delta(seq, cells, values, shape=SHAPE) -> MapDelta:
    return MapDelta.from_arrays(seq, shape, np.array(cells), np.array(values), time.time())


def pose(cell, stamp=None) -> Pose:
    r, c = cell
    return Pose(x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57,
                stamp=stamp or time.time())


def goal(r, c) -> Goal:
    return Goal(target=GoalCell(row=r, col=c), stamp=time.time())


def test_deltas_in_one_step_are_applied_together_and_the_field_stays_exact():
    s = session()
    s.step(Inbox(deltas=[delta(0, [], [])], goal=goal(3, 15), pose=pose((26, 15))), time.time())
    assert s.state == NavState.GUIDING
    wall = [12 * 30 + c for c in range(0, 25)]
    # Three deltas arrive while a step runs: the next step takes them in one update.
    batch = [delta(1, wall[:10], [1] * 10), delta(2, wall[10:], [1] * 15), delta(3, [5], [1])]
    out = s.step(Inbox(deltas=batch, pose=pose((26, 15))), time.time())
    assert s.map_seq == 3
    assert np.array_equal(s.planner.costs(), dijkstra_field(s.map.blocked, (3, 15)))
    assert out.path() is not None and out.path().cells[0] == (26, 15)
    assert s.replans == 1  # the wall cut the straight path


def test_the_latest_pose_wins_and_deltas_coalesce_in_the_runner():
    published: list[tuple[str, bytes]] = []

    async def scenario():
        runner = UserRunner(
            session(), lambda k, b: published.append((k, b)), lambda *a: None, 1.0
        )
        runner.put_delta(delta(0, [], []))
        runner.put_goal(goal(3, 15))
        poses = [pose((20, c), stamp=time.time() - 0.01 * (5 - c)) for c in range(5)]
        for p in poses:  # all before the worker runs: one step, the last pose
            runner.put_pose(p)
        for _ in range(200):
            await asyncio.sleep(0.01)
            if any(k.endswith("/path") for k, _ in published):
                break
        await runner.close()
        return poses, runner.session.steps

    poses, steps = asyncio.run(scenario())
    paths = [codec.decode(NavPath, b) for k, b in published if k.endswith("/path")]
    assert len(paths) == 1 and steps == 1
    assert paths[0].pose_stamp == poses[-1].stamp and paths[0].cells[0] == (20, 4)
    assert published[-1][0].endswith("/status")  # close(): the final status comes last


def test_a_gap_buffers_deltas_and_a_snapshot_replays_the_newer_ones():
    s = session()
    s.step(Inbox(deltas=[delta(0, [1], [1])]), time.time())
    out = s.step(Inbox(deltas=[delta(3, [2], [1]), delta(4, [3], [1])]), time.time())
    assert out.want_snapshot and s.resyncing
    assert [st.code for st in out.statuses] == ["sequence_gap"]
    assert s.map.occupancy.reshape(-1)[[2, 3]].tolist() == [2, 2]  # nothing applied
    occ = np.full(SHAPE, 2, np.uint8)
    occ.reshape(-1)[[1, 2]] = 1
    snap = MapSnapshot.from_array(3, occ, time.time())  # includes delta 3, not 4
    s.step(Inbox(snapshot=snap), time.time())
    assert not s.resyncing and s.map_seq == 4
    assert s.map.occupancy.reshape(-1)[[1, 2, 3]].tolist() == [1, 1, 1]


def test_a_delta_for_another_shape_changes_nothing():
    s = session()
    s.step(Inbox(deltas=[delta(0, [1], [1])]), time.time())
    before = s.map.occupancy.copy()
    out = s.step(Inbox(deltas=[delta(1, [2], [1], shape=(40, 40))]), time.time())
    assert [st.code for st in out.statuses] == ["shape_mismatch"]
    assert np.array_equal(s.map.occupancy, before) and s.map_seq == 0


def test_a_pose_before_the_map_is_used_once_the_map_comes():
    s = session()
    s.step(Inbox(goal=goal(3, 15), pose=pose((20, 15))), time.time())
    assert s.state == NavState.PLANNING
    out = s.step(Inbox(deltas=[delta(0, [], [])]), time.time())
    assert out.path() is not None and s.state == NavState.GUIDING


def test_config_file_environment_and_arguments_in_that_order(tmp_path, monkeypatch):
    path = tmp_path / "g.toml"
    path.write_text('backend = "reference"\nlang = "es"\n[zenoh]\nlisten = ["tcp/127.0.0.1:1"]\n')
    monkeypatch.setenv("GUIDEBELT_LANG", "en")
    monkeypatch.setenv("GUIDEBELT_ZENOH__MULTICAST_SCOUTING", "false")
    cfg = load_config(path, max_users=3)
    assert (cfg.backend, cfg.lang, cfg.max_users) == ("reference", "en", 3)
    assert cfg.zenoh.listen == ["tcp/127.0.0.1:1"] and cfg.zenoh.multicast_scouting is False
    path.write_text("bakend = 'cpu'\n")
    with pytest.raises(ValueError, match="bakend"):
        load_config(path)
    with pytest.raises(FileNotFoundError):
        load_config(tmp_path / "missing.toml")


def test_notifier_speaks_systemds_datagram_protocol(tmp_path, monkeypatch):
    addr = str(tmp_path / "n.sock")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(addr)
    sock.settimeout(2)
    monkeypatch.setenv("WATCHDOG_USEC", "4000000")
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    n = Notifier(addr)
    try:
        assert n.ready("up") and sock.recv(100) == b"READY=1\nSTATUS=up"
        assert n.watchdog() and sock.recv(100) == b"WATCHDOG=1"
        assert n.stopping() and sock.recv(100) == b"STOPPING=1"
        assert n.watchdog_interval_s() == 2.0
    finally:
        n.close()
        sock.close()
    assert not Notifier("").ready()  # outside systemd: a no-op


def test_journal_lines_carry_priority_and_fields():
    rec = logging.LogRecord("guidebelt.x", logging.WARNING, "", 0, "rejected", (), None)
    rec.fields = {"user": "ann", "reason": "pose is 2 s old"}
    line = JournalFormatter().format(rec)
    assert line == '<4>guidebelt.x: rejected user=ann reason="pose is 2 s old"'


def test_from_inside_the_inflation_margin_the_path_leads_out_then_on():
    s = session()
    wall = [10 * 30 + c for c in range(5, 25)]  # inflated 3 cells up and down
    s.step(Inbox(deltas=[delta(0, wall, [1] * len(wall))], goal=goal(3, 15)), time.time())
    out = s.step(Inbox(pose=pose((12, 15))), time.time())  # 2 cells below the wall
    assert s.map.blocked[12, 15] and s.state == NavState.GUIDING
    cells = out.path().cells
    assert cells[0] == (12, 15) and cells[-1] == (3, 15)
    first_free = next(i for i, c in enumerate(cells) if not s.map.blocked[c])
    assert all(not s.map.blocked[c] for c in cells[first_free:])
    assert first_free <= s.radius_cells  # straight out of the margin, not through the wall
