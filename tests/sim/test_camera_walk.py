"""The camera in the loop, short: world → RGB-D frames → mapper → daemon → belt over zenoh."""

from __future__ import annotations

import pytest


@pytest.mark.timeout(150)
def test_a_short_camera_walk_moves_on_without_collision():
    from sim.camera_walk import camera_walk

    # Seed 8: the walk that arrived in 99 steps on the H200 host's table.
    w = camera_walk(8, max_steps=25, timeout_s=100)
    assert w.reason in ("step limit", "arrived"), w.reason
    assert w.collisions == 0
    assert w.refused == 0 and w.frames >= w.steps  # a frame with every pose
    assert w.people == 3
