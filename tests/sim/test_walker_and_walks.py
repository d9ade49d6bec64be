"""The walker that feels the belt, and a small run of the walks benchmark."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from daemon.guidance.patterns import PatternMaker
from protocol.messages import PatternKind
from sim.belt_walker import BeltWalker, WalkerParams
from sim.courtyard import USER_RADIUS_M, make_courtyard
from sim.walks import belt_settings, belt_walk, run_table
from sim.world import WalkerView

EXACT = WalkerParams(step_sd_m=0.0, perception_sd_deg=0.0, gait_sd_deg=0.0)


def open_world(n: int = 50) -> np.ndarray:
    return np.zeros((n, n), dtype=np.uint8)


def test_walker_steps_where_the_belt_points() -> None:
    w = BeltWalker(x=2.5, y=2.5, heading=math.pi / 2, cell_m=0.1, params=EXACT)
    maker = PatternMaker()
    assert w.react(maker.guide(math.radians(30), None, 0.0), open_world()) == "step"
    assert w.heading == pytest.approx(math.pi / 2 - math.radians(30), abs=0.01)  # rounding
    assert math.hypot(w.x - 2.5, w.y - 2.5) == pytest.approx(0.5)
    # far off the nose: turn on the spot first
    assert w.react(maker.guide(math.radians(90), None, 0.0), open_world()) == "turn"
    assert w.walked_m == pytest.approx(0.5)
    # near an obstacle the belt pulses and the steps get shorter, the faster the shorter
    near = maker.guide(0.0, 0.6, 0.0)
    w.react(near, open_world())
    assert 0 < near.period_ms < 800
    assert w.walked_m == pytest.approx(0.5 + 0.5 * near.period_ms / 800)
    w.react(maker.guide(0.0, 0.0, 0.0), open_world())  # fastest pulse: a quarter step
    assert w.walked_m == pytest.approx(0.5 + 0.5 * near.period_ms / 800 + 0.5 * 0.25)


def test_walker_stands_still_for_events_and_turns_around() -> None:
    w = BeltWalker(x=2.5, y=2.5, heading=0.0, cell_m=0.1, params=EXACT)
    maker = PatternMaker()
    for kind in (PatternKind.STOP, PatternKind.WAIT, PatternKind.NO_PATH, PatternKind.ARRIVED,
                 PatternKind.REROUTE, PatternKind.OFF):  # fmt: skip
        assert w.react(maker.event(kind, 0.0), open_world()) == "stand"
    assert (w.x, w.y, w.heading) == (2.5, 2.5, 0.0)
    assert w.react(maker.turn_around(math.radians(170), 0.0), open_world()) == "turn"
    assert abs(abs(w.heading) - math.pi) < 1e-9


def test_walker_turns_on_the_spot_to_look() -> None:
    w = BeltWalker(x=2.5, y=2.5, heading=0.0, cell_m=0.1, params=EXACT)
    look = PatternMaker().event(PatternKind.LOOK, 0.0)
    assert w.react(look, open_world()) == "turn" and w.react(look, open_world()) == "turn"
    assert (w.x, w.y) == (2.5, 2.5) and w.heading == pytest.approx(-math.radians(90))


def test_walker_counts_a_collision_and_does_not_walk_through() -> None:
    world = open_world()
    world[20:30, 30] = 1  # a wall 0.45 m east of the walker
    w = BeltWalker(x=2.55, y=2.5, heading=0.0, cell_m=0.1, params=EXACT)
    maker = PatternMaker()
    assert w.react(maker.guide(0.0, None, 0.0), world) == "bump"
    assert w.collisions == 1 and w.x == 2.55
    (b,) = w.bumps  # what the walk records of it: from where, into which cell, on what pattern
    assert (b.x, b.y, b.heading) == (2.55, 2.5, 0.0) and b.to_x == pytest.approx(3.05)
    assert b.cell == (24, 30) and world[b.cell] == 1
    assert b.kind == "guide" and b.motors == (200, 0, 0, 0) and b.period_ms == 0


def test_walker_reads_the_belt_never_the_path() -> None:
    maker = PatternMaker()
    belt = maker.guide(0.0, None, time.time())
    a = BeltWalker(x=2.5, y=2.5, heading=0.0, cell_m=0.1, rng=np.random.default_rng(3))
    b = BeltWalker(x=2.5, y=2.5, heading=0.0, cell_m=0.1, rng=np.random.default_rng(3))
    now = time.time()
    a.act(WalkerView(np.array([[0, 0], [0, 1]]), belt, open_world(), now))
    b.act(WalkerView(None, belt, open_world(), now))
    assert (a.x, a.y, a.heading) == (b.x, b.y, b.heading)
    # an expired pattern is felt as nothing
    old = maker.guide(0.0, None, now - 5.0)
    assert a.act(WalkerView(None, old, open_world(), now)) == "stand"


@pytest.mark.timeout(60)
def test_small_walks_arrive_without_collisions() -> None:
    for seed in (0, 1):
        walk = belt_walk(make_courtyard(100, 0.4, seed=seed), seed=seed)
        assert walk.arrived, walk.reason
        assert walk.collisions == 0
        assert walk.length_ratio < 1.10
        assert 0 < walk.cues < walk.actions
    rows = run_table([50], [0.2], 3)
    assert rows[0]["success_rate"] == 1.0 and rows[0]["collisions"] == 0
    assert set(rows[0]) >= {"grid", "unknown", "runs", "success_rate", "length_ratio",
                            "collisions", "cues_per_walk"}  # fmt: skip


def test_the_navigator_gets_the_daemons_radius_not_cells_times_size() -> None:
    # 6 x 0.05 m is 0.30000000000000004: guidance would shave a cell more than at 0.3 m.
    for grid in (50, 100, 200):
        scenario = make_courtyard(grid, 0.2, seed=0)
        assert belt_settings(scenario).user_radius_m == USER_RADIUS_M


@pytest.mark.timeout(60)
def test_walks_by_feel_in_each_scenario_asked() -> None:
    rows = run_table([100], [0.2], 1, scenarios=["explore", "building", "streets"])
    assert [r["scenario"] for r in rows] == ["explore", "building", "streets"]
    assert all(r["success_rate"] == 1.0 and r["collisions"] == 0 for r in rows)
    assert run_table([50], [0.2], 1)[0]["scenario"] == "courtyard"  # the default
    with pytest.raises(ValueError, match="building: grid must be at least"):
        run_table([50], [0.2], 1, scenarios=["building"])


def test_walks_command_takes_scenarios_and_refuses_a_bad_one(tmp_path) -> None:
    from typer.testing import CliRunner

    from cli.app import app

    out = tmp_path / "walks.json"
    args = ["--scenario", "streets", "--grid", "100", "--unknown", "0.2", "--runs", "1"]
    res = CliRunner().invoke(app, ["walks", *args, "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert [r["scenario"] for r in json.loads(out.read_text())] == ["streets"]
    res = CliRunner().invoke(app, ["walks", "--scenario", "mall", "--runs", "1"])
    assert res.exit_code != 0 and "unknown scenario 'mall'" in " ".join(res.output.split())
