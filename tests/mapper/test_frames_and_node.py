"""Frames from a folder to the daemon: ``guidebelt mapper --frames`` against a real daemon."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mapper.frame import FrameRejected, Refusal
from mapper.frames_io import read_frame, read_frames, write_frame
from mapper.occupancy_mapper import OCCUPIED
from sim.scene3d import BOX, empty_scene

from .scenes import CAM_XY, NORTH, box_scene, camera, frame, mapper

ROOT = Path(__file__).resolve().parents[2]


def test_png_and_json_round_trip(tmp_path):
    f = frame(box_scene(), 5.0, rng=1)
    write_frame(tmp_path, "000000", f)
    back = read_frame(tmp_path / "000000.json")
    assert back.depth.dtype == np.uint16 and np.array_equal(back.depth, f.depth)
    assert back.intrinsics == f.intrinsics and back.stamp == 5.0
    assert back.pose.position == pytest.approx(f.pose.position)
    assert back.color is not None and back.color.shape == (480, 640, 3)


def test_unreadable_frames_are_refused_whole(tmp_path):
    f = frame(box_scene(), 5.0)
    write_frame(tmp_path, "000000", f)
    (tmp_path / "000001.json").write_text('{"stamp": 6.0, "intrinsics": {"width": -1}}')
    (tmp_path / "000002.json").write_text('{"stamp": 7.0}')  # no intrinsics, no pose
    (tmp_path / "000002.png").write_bytes(b"not a png")
    got = list(read_frames(tmp_path))
    assert not isinstance(got[0], FrameRejected)
    assert isinstance(got[1], FrameRejected) and got[1].refusal is Refusal.UNREADABLE
    assert isinstance(got[2], FrameRejected) and got[2].refusal is Refusal.UNREADABLE


def _stop_scene():
    """A box 0.45 m ahead of the camera: closer than the 0.6 m STOP distance."""
    scene = empty_scene((60, 60), 0.1)
    scene.put((slice(40, 45), slice(28, 34)), BOX, 0.0, 0.9)
    return scene


@pytest.mark.timeout(120)
def test_mapper_command_feeds_the_daemon_and_the_belt_stops(daemon, peer, tmp_path):
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import BeltPattern, MapSnapshot

    user = "cam-user"
    for i in range(3):
        write_frame(tmp_path, f"{i:06d}", frame(_stop_scene(), 100.0 + i, rng=i))
    (tmp_path / "000009.json").write_text("{not json")  # counted, not fatal
    belts: list[BeltPattern] = []
    got = threading.Event()

    def on_belt(sample) -> None:
        belts.append(codec.decode(BeltPattern, sample.payload.to_bytes()))
        got.set()

    sub = wire.declare_subscriber(peer, T.BELT, on_belt, user)
    try:
        run = subprocess.run(
            [sys.executable, "-m", "cli.app", "mapper", "--frames", str(tmp_path), "--user",
             user, "--size", "60,60", "--backend", "cpu", "--rate", "10", "--connect",
             f"tcp/127.0.0.1:{daemon.port}", "--floor-every", "2", "--floor-async"],
            cwd=ROOT, capture_output=True, text=True, timeout=90,
        )  # fmt: skip
        assert run.returncode == 0, run.stderr
        assert "3 frames mapped" in run.stdout and "unreadable 1" in run.stdout
        assert got.wait(10)
        assert any(b.kind == "stop" for b in belts)
        snap = None
        deadline = time.monotonic() + 5
        while snap is None and time.monotonic() < deadline:
            for reply in wire.get(peer, T.MAP_SNAPSHOT, user):
                if reply.ok is not None:
                    snap = codec.decode(MapSnapshot, reply.ok.payload.to_bytes())
        assert snap is not None
        occ = snap.array()
        assert (occ[44, 28:34] == 1).all()  # the box's near face, in the daemon's own map
        assert (occ[46:48, 29:33] == 0).all()  # cleared along the rays in front of it
    finally:
        sub.undeclare()


def test_a_frame_rendered_into_the_lent_buffer_maps_as_its_own_array():
    """A producer that writes its depth where the mapper lends (``depth_buffer``; on cpu a
    plain array) gives the same frame, bit for bit, and the same map: the renderer's cast
    writes the buffer in place, and the buffer is reused frame after frame."""
    scene, cam = box_scene(), camera()
    own, lent = mapper(), mapper()
    buf = lent.depth_buffer(480, 640)
    assert buf.shape == (480, 640) and buf.dtype == np.uint16
    for i, rng in enumerate((1, 2)):
        pose = cam.pose(*CAM_XY, NORTH + 0.05 * i)
        a = cam.render(scene, pose, 5.0 + i, np.random.default_rng(rng))
        b = cam.render(scene, pose, 5.0 + i, np.random.default_rng(rng), out=buf)
        assert b.depth is buf and np.array_equal(a.depth, b.depth)
        ra, rb = own.process(a), lent.process(b)
        assert np.array_equal(ra.cells, rb.cells) and np.array_equal(ra.values, rb.values)
        assert ra.proximity == rb.proximity
    assert np.array_equal(own.occupancy, lent.occupancy) and (own.occupancy == OCCUPIED).any()
    own.close()
    lent.close()
