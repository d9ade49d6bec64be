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


@pytest.mark.timeout(60)
def test_a_bump_is_recorded_with_what_it_ran_into_and_what_the_belt_said():
    import math
    import time

    from daemon.guidance.patterns import PatternMaker
    from protocol.messages import NavPath
    from sim.belt_walker import BeltWalker, WalkerParams
    from sim.camera_node import CameraSimNode
    from sim.courtyard import make_courtyard

    node = CameraSimNode(None, "walker", make_courtyard(100, 0.2, 8), seed=8)  # never run
    exact = WalkerParams(step_sd_m=0.0, perception_sd_deg=0.0, gait_sd_deg=0.0)
    # 0.25 m north of the courtyard's south wall (row 99), facing it, free floor between.
    node.walker = BeltWalker(x=5.05, y=0.35, heading=-math.pi / 2, cell_m=0.1, params=exact)
    belt = PatternMaker().guide(0.0, None, time.time() - 0.05)  # straight on
    assert node.world.act(None, belt, time.time()) == "bump"
    node._bumped(NavPath.model_construct(map_seq=-1), belt)
    (rec,) = node.bumps
    assert rec["kind"] == "wall" and rec["cell"] == [99, 50] and rec["xy"] == [5.05, 0.35]
    assert rec["mapped"] == 1  # the border is on the start map
    assert rec["pattern"]["kind"] == "guide" and rec["pattern"]["age_ms"] >= 50
    assert rec["person_m"] > 0  # the people are elsewhere
    assert rec["frame_proximity"] is None and rec["frame_age_ms"] is None  # no frame taken yet
