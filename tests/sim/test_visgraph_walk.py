"""The visibility-graph planner in the closed loop and on the command line: it arrives,
through free cells, and bench / demo take it by name."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from daemon.planning.grid import OCCUPIED
from sim.benchmark import BenchConfig, run_bench
from sim.courtyard import make_courtyard
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)


def test_visgraph_walks_the_courtyard_to_the_goal():
    scenario = make_courtyard(50, 0.4, seed=0)
    result = walk(scenario, backend="cpu", mode="visgraph")
    assert result.arrived and result.reason == "arrived"
    assert result.planner == "visgraph-cpu"
    assert tuple(result.walked[0]) == scenario.start and tuple(result.walked[-1]) == scenario.goal
    steps = np.abs(np.diff(result.walked.astype(np.int64), axis=0))
    assert np.all(steps.max(axis=1) == 1)
    assert not np.any(scenario.true[result.walked[:, 0], result.walked[:, 1]] == OCCUPIED)
    # every step before the goal searched the graph: nodes expanded, visibility judged
    assert np.all(result.iterations[:-1] > 0) and np.all(result.cells_touched[:-1] > 0)


def test_bench_rows_and_the_demo_take_visgraph(tmp_path):
    result = run_bench(BenchConfig(grids=[50], unknowns=[0.2], modes=["eds", "visgraph"]))
    rows = {r["mode"]: r for r in result.rows}
    assert rows["visgraph"]["arrived"] and rows["visgraph"]["planner"] == "visgraph-cpu"
    png = tmp_path / "demo.png"
    res = CliRunner().invoke(
        app, ["demo", "--in-process", "--grid", "50", "--planner", "visgraph", "--out", str(png)]
    )
    assert res.exit_code == 0, res.output
    assert "arrived" in res.output and png.exists()
