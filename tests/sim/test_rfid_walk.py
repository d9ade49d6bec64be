"""The user guided by RFID poses, not the true pose, still reaches the goal (in process).

The paper's closed loop in the demo courtyard (100 x 100, 40 % unknown) with the same
planner the daemon uses; the planning cell comes from the localiser fed by simulated
reads at the user's true position. See ``sim/rfid_walk.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.grid import OCCUPIED
from sim.courtyard import make_courtyard
from sim.rfid_eval import tags_for
from sim.rfid_walk import rfid_walk
from sim.walk import walk


def backend() -> str:
    try:
        import daemon.planning.cpu.fast  # noqa: F401

        return "cpu"
    except ImportError:
        return "reference"


@pytest.mark.timeout(60)
@pytest.mark.parametrize("method", ["lsq", "centroid"])
def test_rfid_guided_walk_reaches_the_goal(method: str) -> None:
    scenario = make_courtyard(100, 0.4, seed=0)
    tag_map = tags_for(scenario, "floor", seed=0)
    # Off the cell centres, so the user is not always right beside a floor tag.
    res = rfid_walk(scenario, tag_map, backend=backend(), method=method, seed=0,
                    offset_m=(0.03, -0.045))
    assert res.arrived, res.reason
    assert res.final_error_m <= 0.3  # where the user truly ends up
    assert res.collisions == 0
    walked = res.walked
    assert not (scenario.true[walked[:, 0], walked[:, 1]] == OCCUPIED).any()
    # The walk was guided from noisy poses, not the truth…
    assert 0.0 < float(np.median(res.pose_errors)) <= 0.15
    # …and is about as long as the walk guided by the true pose.
    truth = walk(scenario, backend=backend())
    assert truth.arrived
    assert res.steps <= 1.2 * truth.steps


def test_offset_beyond_half_a_cell_is_refused() -> None:
    scenario = make_courtyard(100, 0.4, seed=0)
    with pytest.raises(ValueError, match="half a cell"):
        rfid_walk(scenario, tags_for(scenario, "none"), offset_m=(0.06, 0.0))
