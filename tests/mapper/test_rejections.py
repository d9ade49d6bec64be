"""Bad frames: a clear, counted refusal and a map exactly as it was."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mapper.backends import Binner
from mapper.binning import bin_frame_cpu
from mapper.camera_model import CameraPose
from mapper.frame import FrameRejected, Refusal, count_valid

from .scenes import NORTH, bad_frames, box_scene, edge_frames, frame, mapper, outcome


@pytest.fixture
def warm():
    m = mapper()
    m.process(frame(box_scene(), 10.0))
    return m


def test_each_bad_frame_is_refused_and_leaves_the_map_unchanged(warm):
    good = frame(box_scene(), 11.0)
    for bad, why in bad_frames(good):
        before = warm.occupancy.copy()
        seen = warm.seen_at.copy()
        odds = warm.logodds.copy()
        with pytest.raises(FrameRejected) as exc:
            warm.process(bad)
        assert exc.value.refusal is why, (why, exc.value)
        assert np.array_equal(warm.occupancy, before)
        assert np.array_equal(warm.seen_at, seen)
        assert np.array_equal(warm.logodds, odds)
    assert sum(warm.refused.values()) == len(bad_frames(good))
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


def counting(m):
    """``m`` with a pass that counts the frame's pixels itself, as the cuda one does: the
    mapper then checks the depth and the motion once the pass is back."""

    def fn(depth, *args):
        b = bin_frame_cpu(depth, *args)
        b.present = count_valid(depth)
        return b

    m.binner = Binner("counting", fn, counts_valid=True)
    return m


def _state(m):
    fit = m._floor[0] if m._floor is not None else None
    return (m.occupancy.tobytes(), m.logodds.tobytes(), m.seen_at.tobytes(), m.last_stamp,
            m.frames, dict(m.refused), m._floor_age, m._floor_job is None,
            None if fit is None else (fit.floor_z, fit.rotation.tobytes()))  # fmt: skip


def test_a_pass_that_counts_the_pixels_refuses_as_the_host_check_does():
    """The cuda pass counts the frame's pixels, so its mapper checks those after the pass:
    the same frames refused, with the same refusal and reason, in the same order, and a
    refused frame keeps nothing, not even a floor fit that came back from the worker."""
    host, late = (mapper(floor_async=True, floor_every=1) for _ in range(2))
    counting(late)
    good = frame(box_scene(), 10.0)
    frames = [good, dataclasses.replace(good, stamp=10.05)]
    frames += [f for f, _ in bad_frames(dataclasses.replace(good, stamp=10.5))]
    frames += [
        dataclasses.replace(f, stamp=10.1 + 0.1 * i) for i, f in enumerate(edge_frames(good))
    ]
    frames.append(dataclasses.replace(good, stamp=11.0))
    refused = 0
    for f in frames:
        said = [outcome(m, f) for m in (host, late)]
        assert said[0] == said[1]
        refused += said[0] != "mapped"
        assert _state(host) == _state(late)
    assert refused == len(frames) - 5  # both good frames, the limit, the holes and the last
    assert late.refused[Refusal.NO_DEPTH] == 4  # zeros, NaN, one pixel short, zeros + jump
    host.close()
    late.close()
