"""``guidebelt compare``: every planner on the same walks, one table and one figure."""

from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from cli.app import app
from sim.compare import COMPARE_HEADS, CompareConfig, run_compare, table_cells
from sim.scenarios import make_scenario

pytestmark = pytest.mark.timeout(120)
PNG = b"\x89PNG\r\n\x1a\n"


def test_the_planners_walk_the_same_world_and_the_rows_say_what_the_walker_got():
    config = CompareConfig(planners=["eds", "dss", "astar", "extended-astar"], grids=[50],
                           unknowns=[0.4])  # fmt: skip
    rows, device = run_compare(config)
    by = {r["planner"]: r for r in rows}
    assert list(by) == config.planners and device
    eds, dss, astar = by["eds"], by["dss"], by["astar"]
    # One field, two ways of keeping it: the same walk to the cell and the same turns.
    for key in ("steps", "walked_m", "turns", "turn_total_deg", "arrived"):
        assert eds[key] == dss[key]
    assert eds["arrived"] and astar["arrived"]
    scenario = make_scenario("courtyard", 50, 0.4, 0)
    crow_m = math.dist(scenario.start, scenario.goal) * scenario.cell_m
    for r in (eds, astar):
        # The turning points pull the staircase of cells straight: never longer than it, never
        # shorter than the straight line.
        assert crow_m - 1e-9 <= r["turning_points_m"] <= r["walked_m"] + 1e-9
        assert r["turns"] > 0 and 10.0 <= r["turn_mean_deg"] <= r["turn_max_deg"] <= 180.0
        assert 0 < r["ms_median"] <= r["ms_p99"] <= r["ms_max"] and r["walk_ms"] > 0
    # DSS relaxes the whole field at every step, EDS what changed, A* what it searched.
    assert dss["touched_per_step"] > eds["touched_per_step"] > 0
    assert astar["max_open"] > 0 and eds["max_open"] == -1
    # Extended A*'s memory criterion closes this courtyard's gaps; its fallback finds them.
    assert by["extended-astar"]["arrived"]
    cells = table_cells(rows)
    assert all(len(line) == len(COMPARE_HEADS) for line in cells)
    assert [line[4] for line in cells] == ["yes"] * 4


def test_a_walk_that_did_not_arrive_says_why_in_the_table():
    row = {"scenario": "courtyard", "grid": 50, "unknown": 0.4, "planner": "x", "arrived": False,
           "reason": "no path", "steps": 0, "walked_m": 0.0, "turns": 0, "turn_mean_deg": 0.0,
           "ms_median": 0.0, "ms_p99": 0.0, "ms_max": 0.0, "walk_ms": 0.0,
           "touched_per_step": 0.0}  # fmt: skip
    assert table_cells([row])[0][4] == "no (no path)"


def test_the_command_writes_the_table_json_and_figure(tmp_path):
    out_json, out_png = tmp_path / "c.json", tmp_path / "c.png"
    result = CliRunner().invoke(app, ["compare", "--planners", "eds,astar", "--grid", "50",
                                      "--unknown", "0.2", "--json", str(out_json),
                                      "--plot", str(out_png)])  # fmt: skip
    assert result.exit_code == 0, result.output
    rows = json.loads(out_json.read_text())
    assert [r["planner"] for r in rows] == ["eds", "astar"] and all(r["arrived"] for r in rows)
    assert out_png.read_bytes()[:8] == PNG and out_png.stat().st_size > 20_000
    assert "planners on the same walks" in result.output


def test_an_unknown_planner_is_refused_before_any_walk():
    result = CliRunner().invoke(app, ["compare", "--planners", "eds,nosuch", "--grid", "50"])
    assert result.exit_code == 2
    assert "unknown planner 'nosuch'" in result.output
