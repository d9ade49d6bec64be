"""The A* planner in the closed loop and on the command line: it arrives, its paths cost
what EDS's cost, and bench / demo take it by name."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from daemon.planning.grid import OCCUPIED
from sim.benchmark import BenchConfig, format_tables, planner_rows, run_bench
from sim.courtyard import make_courtyard
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)


def test_astar_walks_the_courtyard_to_the_goal():
    scenario = make_courtyard(100, 0.4, seed=0)
    result = walk(scenario, backend="cpu", mode="astar")
    assert result.arrived and result.reason == "arrived"
    assert result.planner == "astar-cpu-octile"
    assert tuple(result.walked[0]) == scenario.start and tuple(result.walked[-1]) == scenario.goal
    steps = np.abs(np.diff(result.walked.astype(np.int64), axis=0))
    assert np.all(steps.max(axis=1) == 1)
    assert not np.any(scenario.true[result.walked[:, 0], result.walked[:, 1]] == OCCUPIED)
    # every step searched: the statistics say so
    assert len(result.iterations) == result.steps and np.all(result.iterations > 0)
    assert np.all(result.max_open > 0) and np.all(result.max_open <= result.cells_touched)
    eds = walk(scenario, backend="cpu", mode="eds")
    # Same costs at every step, not always the same cells: the walks are about as long.
    assert abs(result.walked_m - eds.walked_m) <= 0.1 * eds.walked_m


def test_bench_rows_and_the_planner_table_include_astar():
    result = run_bench(BenchConfig(grids=[50], unknowns=[0.4], modes=["eds", "dss", "astar"]))
    rows = {r["mode"]: r for r in result.rows}
    assert set(rows) == {"eds", "dss", "astar"}
    assert all(r["arrived"] for r in rows.values())
    assert rows["eds"]["same_walk"] and "same_walk" not in rows["astar"]
    assert rows["astar"]["planner"] == "astar-cpu-octile" and rows["astar"]["iter_avg"] > 0
    lines = planner_rows(result.rows)
    assert [line[3] for line in lines] == ["eds", "dss", "astar"] and len(lines[0]) == 11
    assert {line[0] for line in lines} == {"courtyard"}
    # the open list is reported for the planner that has one
    assert rows["eds"]["max_open"] == -1 and lines[0][-1] == "-"
    top = rows["astar"]["max_open"]
    assert 0 < top < 50 * 50 and lines[2][-1] == str(top)
    assert "by planner" in format_tables(result.rows)


def test_bench_and_demo_commands_take_astar(tmp_path):
    out = tmp_path / "rows.json"
    res = CliRunner().invoke(
        app, ["bench", "--grid", "50", "--unknown", "0.4", "--planner", "astar,eds",
              "--json", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "by planner" in res.output and "astar" in res.output
    assert [r["mode"] for r in json.loads(out.read_text())] == ["astar", "eds"]
    png = tmp_path / "demo.png"
    res = CliRunner().invoke(
        app, ["demo", "--in-process", "--grid", "50", "--planner", "astar", "--out", str(png)]
    )
    assert res.exit_code == 0, res.output
    assert "arrived" in res.output and png.exists()


def test_plain_entry_point_takes_astar(capsys):
    from sim.benchmark import main

    main(["--grid", "50", "--unknown", "0.2", "--modes", "astar"])
    assert "by planner" in capsys.readouterr().out
