"""Seed 004's map and target to the daemon: the bird's-eye mapper, then the node against a
real daemon over zenoh (LOOK while the target is not seen, GUIDE once it is)."""

from __future__ import annotations

import dataclasses
import math
import threading
import time

import numpy as np
import pytest

from mapper.birdseye.node import BirdsEyeMapper, BirdsEyeSettings
from mapper.birdseye.view import BirdsEye
from mapper.frame import FrameRejected, Refusal
from mapper.occupancy_mapper import FREE, OCCUPIED, UNKNOWN
from sim.birdseye_study import HEIGHT_M, KINECT, PITCH_DEG
from sim.camera import RgbdCamera
from sim.scene3d import BOX, TARGET, empty_scene

SHAPE = (80, 80)
CAM = (3.0, 1.5)
NORTH, EAST = math.pi / 2, 0.0


def scene():
    """The target's centre at (2.85, 4.05), 2.55 m north of the camera and a little left, clear
    of a 0.3 m box 1.5 m ahead, 0.2-0.5 m to the right (rows 47..49, cols 32..34)."""
    s = empty_scene(SHAPE, 0.1)
    s.mark[38:41, 27:30] = TARGET
    s.put((slice(47, 50), slice(32, 35)), BOX, 0.0, 0.3)
    return s


def frame(heading: float, stamp: float):
    cam = RgbdCamera(KINECT, mount_height_m=HEIGHT_M, pitch_deg=PITCH_DEG, missing=0.0)
    return cam.render(scene(), cam.pose(CAM[0], CAM[1], heading), stamp)


def mapper() -> BirdsEyeMapper:
    view = BirdsEye(KINECT, HEIGHT_M, math.radians(PITCH_DEG))
    return BirdsEyeMapper(view, KINECT.width, KINECT.height, BirdsEyeSettings(shape=SHAPE))


def test_the_bird_s_eye_map_lands_on_the_grid_and_the_target_in_the_world():
    m = mapper()
    r = m.process(frame(NORTH, 1.0))
    occ = m.occupancy
    assert r.target_xy is not None
    assert abs(r.target_xy[0] - 2.85) < 0.15 and abs(r.target_xy[1] - 4.05) < 0.15
    rows, cols = np.nonzero(occ == OCCUPIED)
    # The box: its near face at row 49; the view smears it away from the camera, never nearer.
    assert rows.size > 0 and rows.max() == 49 and cols.min() >= 31 and cols.max() <= 37
    assert (occ[51, 27:32] == FREE).all()  # the floor patch in front of it
    assert (occ[60:, :] == UNKNOWN).all()  # nearer than the patch (1.2 m): not seen
    assert set(np.unique(r.values)) <= {FREE, OCCUPIED} and r.cells.size == np.sum(occ != UNKNOWN)
    again = m.process(frame(NORTH, 2.0))
    assert again.cells.size == 0  # only changes go out
    away = m.process(frame(EAST, 3.0))
    assert away.target_xy is None


def test_unusable_frames_are_refused_and_leave_the_map_alone():
    m = mapper()
    m.process(frame(NORTH, 5.0))
    before = m.occupancy.copy()
    good = frame(EAST, 6.0)
    bad = [
        (dataclasses.replace(good, color=None), Refusal.NO_COLOUR),
        (dataclasses.replace(good, color=good.color[:240]), Refusal.WRONG_SIZE),
        (dataclasses.replace(good, pose=None), Refusal.NO_POSE),
        (dataclasses.replace(good, stamp=5.0), Refusal.STALE),
        (dataclasses.replace(good, stamp=math.nan), Refusal.STALE),
    ]
    for f, why in bad:
        with pytest.raises(FrameRejected) as exc:
            m.process(f)
        assert exc.value.refusal is why
        assert np.array_equal(m.occupancy, before) and m.last_stamp == 5.0


@pytest.mark.timeout(120)
def test_the_node_sends_the_map_and_the_goal_and_the_belt_says_look_until_seen(daemon, peer):
    from mapper.birdseye.node import BirdsEyeNode
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import BeltPattern, MapSnapshot, PatternKind, Pose, VoiceCue

    user = "bev-user"
    belts: list[BeltPattern] = []
    words: list[str] = []
    lock = threading.Lock()

    def on_belt(sample) -> None:
        with lock:
            belts.append(codec.decode(BeltPattern, sample.payload.to_bytes()))

    def on_voice(sample) -> None:
        with lock:
            words.append(codec.decode(VoiceCue, sample.payload.to_bytes()).text)

    subs = [wire.declare_subscriber(peer, T.BELT, on_belt, user),
            wire.declare_subscriber(peer, T.VOICE, on_voice, user)]  # fmt: skip
    session = daemon.peer()
    node = BirdsEyeNode(session, user, mapper())
    frames = {h: frame(h, 1.0) for h in (NORTH, EAST)}

    def walk_until(heading: float, kind: PatternKind, limit_s: float = 15.0) -> bool:
        deadline = time.monotonic() + limit_s
        while time.monotonic() < deadline:
            now = time.time()
            pose = Pose(x=CAM[0], y=CAM[1], heading=heading, stamp=now)
            wire.put(peer, T.POSE, user, codec.encode(pose))
            node.feed(dataclasses.replace(frames[heading], stamp=now))
            time.sleep(0.2)
            with lock:
                if any(b.kind == kind for b in belts):
                    return True
        return False

    try:
        node.start()
        # Facing east the target is not in view, and no goal is set: turn and look.
        assert walk_until(EAST, PatternKind.LOOK)
        assert node.goals_sent == 0
        with lock:
            assert "turn slowly and look for the target" in words
            assert all(b.kind != PatternKind.GUIDE for b in belts)
        # The user turns north: the target is seen, sent as the goal, and guidance begins.
        assert walk_until(NORTH, PatternKind.GUIDE)
        assert node.goals_sent == 1  # the target did not move: one goal
        snap = None
        deadline = time.monotonic() + 5
        while snap is None and time.monotonic() < deadline:
            for reply in wire.get(peer, T.MAP_SNAPSHOT, user):
                if reply.ok is not None:
                    snap = codec.decode(MapSnapshot, reply.ok.payload.to_bytes())
        assert snap is not None
        assert np.array_equal(snap.array(), node.mapper.occupancy)  # the daemon's map is ours
        assert (snap.array()[49, 32:35] == OCCUPIED).all()
        assert node.refused == {}
    finally:
        node.close()
        session.close()
        for s in subs:
            s.undeclare()


@pytest.mark.timeout(120)
def test_mapper_command_in_birdseye_mode_maps_a_folder_of_colour_frames(daemon, peer, tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    from mapper.frames_io import write_frame
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import MapSnapshot

    user = "bev-folder"
    for i in range(3):
        write_frame(tmp_path, f"{i:06d}", frame(NORTH, 100.0 + i))
    run = subprocess.run(
        [sys.executable, "-m", "cli.app", "mapper", "--frames", str(tmp_path), "--user", user,
         "--size", "80,80", "--birdseye", "--rate", "10", "--connect",
         f"tcp/127.0.0.1:{daemon.port}"],
        cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True, timeout=90,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "3 frames mapped" in run.stdout and "refused: none" in run.stdout
    snap = None
    deadline = time.monotonic() + 5
    while snap is None and time.monotonic() < deadline:
        for reply in wire.get(peer, T.MAP_SNAPSHOT, user):
            if reply.ok is not None:
                snap = codec.decode(MapSnapshot, reply.ok.payload.to_bytes())
    assert snap is not None and (snap.array()[49, 32:35] == OCCUPIED).all()
