"""GA+A* in the closed loop and on the command line: it arrives through free cells, and
bench, walks and demo take it by name."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from daemon.planning.grid import OCCUPIED
from sim.benchmark import BenchConfig, run_bench
from sim.courtyard import make_courtyard
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)


def test_ga_astar_walks_the_courtyard_to_the_goal():
    scenario = make_courtyard(100, 0.4, seed=1)
    result = walk(scenario, backend="cpu", mode="ga-astar")
    assert result.arrived and result.reason == "arrived"
    assert result.planner == "ga-astar-cpu-p8g6w2"
    assert tuple(result.walked[0]) == scenario.start and tuple(result.walked[-1]) == scenario.goal
    steps = np.abs(np.diff(result.walked.astype(np.int64), axis=0))
    assert np.all(steps.max(axis=1) == 1)
    assert not np.any(scenario.true[result.walked[:, 0], result.walked[:, 1]] == OCCUPIED)
    # The GA runs when the kept path is blocked or left, not at every step.
    ran = result.iterations > 0
    assert ran[0] and 0 < ran.sum() < result.steps
    eds = walk(scenario, backend="cpu", mode="eds")
    assert result.walked_m >= eds.walked_m * 0.9  # EDS's paths are optimal on the known map


def test_bench_walks_it_beside_eds():
    result = run_bench(BenchConfig(grids=[50], unknowns=[0.2], modes=["eds", "ga-astar"]))
    rows = {r["mode"]: r for r in result.rows}
    assert rows["eds"]["arrived"] and rows["ga-astar"]["arrived"]
    assert rows["ga-astar"]["planner"] == "ga-astar-cpu-p8g6w2"
    assert rows["ga-astar"]["steps"] >= rows["eds"]["steps"] > 0


def test_bench_walks_and_demo_commands_take_it(tmp_path):
    out = tmp_path / "rows.json"
    res = CliRunner().invoke(
        app, ["bench", "--grid", "50", "--unknown", "0.4", "--planner", "ga-astar",
              "--json", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert [r["mode"] for r in json.loads(out.read_text())] == ["ga-astar"]
    png = tmp_path / "demo.png"
    res = CliRunner().invoke(
        app, ["demo", "--in-process", "--grid", "50", "--planner", "ga-astar", "--out", str(png)]
    )
    assert res.exit_code == 0, res.output
    assert "arrived" in res.output and png.exists()
    res = CliRunner().invoke(
        app, ["walks", "--runs", "2", "--grid", "50", "--unknown", "0.2", "--planner", "ga-astar",
              "--json", str(tmp_path / "walks.json")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output


def test_the_study_rows_compare_the_three_methods_on_one_map(capsys):
    from sim.ga_study import format_rows, main, study

    rows = study([30], [0.1], [100], [0.2], maps=1, repeats=1, seed=0)
    assert [r.method for r in rows[:4]] == ["GA", "A*", "GA+A*", "GA+A* (planner)"]
    assert {r.setup for r in rows} == {"room-30 10%", "courtyard-100 20%"}
    by = {(r.setup, r.method): r for r in rows}
    for setup in ("room-30 10%", "courtyard-100 20%"):
        assert by[(setup, "A*")].vs_astar_median == 1.0 and by[(setup, "A*")].found == 1
        for method in ("GA+A*", "GA+A* (planner)"):
            r = by[(setup, method)]
            assert r.found == 1 and r.vs_astar_median >= 1.0 and r.searches_median > 1
            assert r.ms_median > 0 and r.length_m_median >= by[(setup, "A*")].length_m_median
    assert "paper (Table 2" in format_rows(rows)
    main(["--rooms", "30", "--densities", "0.2", "--courtyards", "", "--maps", "1",
          "--repeats", "1"])  # fmt: skip
    assert "room-30 20%" in capsys.readouterr().out
