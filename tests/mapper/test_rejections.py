"""Bad frames: a clear, counted refusal and a map exactly as it was."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mapper.camera_model import CameraPose
from mapper.frame import FrameRejected, Refusal

from .scenes import NORTH, box_scene, frame, mapper


@pytest.fixture
def warm():
    m = mapper()
    m.process(frame(box_scene(), 10.0))
    return m


def _bad_frames(good):
    nan = good.depth.astype(np.float32) / 1000.0
    nan[:] = np.nan
    far = CameraPose.level(8.0, 5.0, 1.3, 1.57, 0.5)
    return [
        (dataclasses.replace(good, depth=good.depth[:, :-1]), Refusal.WRONG_SIZE),
        (dataclasses.replace(good, intrinsics=None), Refusal.NO_INTRINSICS),
        (dataclasses.replace(good, pose=None), Refusal.NO_POSE),
        (dataclasses.replace(good, depth=np.zeros_like(good.depth)), Refusal.NO_DEPTH),
        (dataclasses.replace(good, depth=nan), Refusal.NO_DEPTH),
        (dataclasses.replace(good, depth=good.depth.astype(np.int32)), Refusal.BAD_DEPTH),
        (dataclasses.replace(good, stamp=9.0), Refusal.STALE),
        (dataclasses.replace(good, stamp=10.0), Refusal.STALE),
        (dataclasses.replace(good, stamp=float("nan")), Refusal.STALE),
        (dataclasses.replace(good, pose=far, stamp=10.1), Refusal.POSE_JUMP),
    ]


def test_each_bad_frame_is_refused_and_leaves_the_map_unchanged(warm):
    good = frame(box_scene(), 11.0)
    for bad, why in _bad_frames(good):
        before = warm.occupancy.copy()
        seen = warm.seen_at.copy()
        odds = warm.logodds.copy()
        with pytest.raises(FrameRejected) as exc:
            warm.process(bad)
        assert exc.value.refusal is why, (why, exc.value)
        assert np.array_equal(warm.occupancy, before)
        assert np.array_equal(warm.seen_at, seen)
        assert np.array_equal(warm.logodds, odds)
    assert sum(warm.refused.values()) == len(_bad_frames(good))
    assert warm.refused[Refusal.STALE] == 3
    warm.process(good)  # and the next good frame is mapped as usual
    assert warm.frames == 2


def test_a_real_relocation_is_believed_after_a_few_jumps(warm):
    for i in range(5):
        with pytest.raises(FrameRejected):
            warm.process(frame(box_scene(), 11.0 + 0.1 * i, xy=(5.5, 5.5), heading=-NORTH))
    warm.process(frame(box_scene(), 12.0, xy=(5.5, 5.5), heading=-NORTH))
    assert warm.last_xy == pytest.approx((5.5, 5.5))


def test_bad_intrinsics_and_orientation_are_refused_at_construction():
    from mapper.camera_model import Intrinsics

    with pytest.raises(ValueError):
        Intrinsics(640, 480, float("nan"), 500, 320, 240)
    with pytest.raises(ValueError):
        CameraPose((0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 2.0))
