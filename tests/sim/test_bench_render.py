"""bench rows and plot, render and demo pictures, through the CLI as a user runs them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from sim.benchmark import ROW_FIELDS, BenchConfig, run_bench, table_rows
from sim.courtyard import make_courtyard
from sim.render import COLOURS, render_walk, walk_image
from sim.walk import walk

pytestmark = pytest.mark.timeout(120)
PNG = b"\x89PNG\r\n\x1a\n"


def test_bench_rows_have_the_documented_fields_and_sane_values():
    config = BenchConfig(grids=[50], unknowns=[0.2, 0.4], backend="cpu", repeats=2)
    result = run_bench(config)
    assert len(result.rows) == 4
    for row in result.rows:
        assert set(ROW_FIELDS) <= row.keys()
        assert row["backend"] == "cpu" and row["variant"] == "fast" and row["grid"] == 50
        assert row["scenario"] == "courtyard"  # the default
        assert row["arrived"] and row["steps"] > 20 and row["same_walk"]
        assert row["iter_avg"] > 0
        assert 0 < row["ms_median"] <= row["ms_p95"] and row["ms_mean"] > 0
        assert row["inflate_ms_median"] >= 0 and row["device"]
    by_mode = {(r["unknown"], r["mode"]): r for r in result.rows}
    for unknown in (0.2, 0.4):
        eds, dss = by_mode[(unknown, "eds")], by_mode[(unknown, "dss")]
        assert eds["steps"] == dss["steps"]
        # DSS recomputes the whole field every step; EDS only what changed
        assert dss["touched_avg"] > eds["touched_avg"]
        assert result.series[("courtyard", 50, unknown, "eds")].size == eds["steps"]
    t1, t2 = table_rows(result.rows)
    assert len(t1) == len(t2) == 2 and t1[0][:3] == ["courtyard", "50", "20%"]


def test_bench_command_writes_json_and_plot(tmp_path):
    out, fig = tmp_path / "rows.json", tmp_path / "fig9.png"
    res = CliRunner().invoke(
        app,
        ["bench", "--grid", "50", "--unknown", "0.4", "--json", str(out), "--plot", str(fig)],
    )
    assert res.exit_code == 0, res.output
    assert "Iter_avg" in res.output and "p99" in res.output
    rows = json.loads(out.read_text())
    assert [r["mode"] for r in rows] == ["eds", "dss"]
    assert fig.read_bytes().startswith(PNG)


def test_bench_walks_each_scenario_asked_and_groups_by_it(tmp_path):
    out, fig = tmp_path / "rows.json", tmp_path / "fig9.png"
    res = CliRunner().invoke(
        app,
        ["bench", "--scenario", "explore,building", "--grid", "100", "--unknown", "0.2",
         "--json", str(out), "--plot", str(fig)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "explore" in res.output and "building" in res.output
    rows = json.loads(out.read_text())
    assert [(r["scenario"], r["mode"]) for r in rows] == [
        ("explore", "eds"), ("explore", "dss"), ("building", "eds"), ("building", "dss"),
    ]  # fmt: skip
    assert all(set(ROW_FIELDS) <= r.keys() and r["arrived"] and r["same_walk"] for r in rows)
    assert fig.read_bytes().startswith(PNG)
    t1, _ = table_rows(rows)
    assert [line[0] for line in t1] == ["explore", "building"]
    # rows written before the field existed are the courtyard's
    old = [{k: v for k, v in r.items() if k != "scenario"} for r in rows[:2]]
    assert table_rows(old)[0][0][0] == "courtyard"


@pytest.mark.parametrize(
    ("args", "said"),
    [(["--scenario", "mall"], "unknown scenario 'mall'"),
     (["--scenario", "building", "--grid", "50"], "building: grid must be at least 100")],
)  # fmt: skip
def test_bench_refuses_a_bad_scenario_or_grid_before_walking(args, said):
    res = CliRunner().invoke(app, ["bench", "--unknown", "0.2", *args])
    assert res.exit_code != 0
    assert said in " ".join(res.output.split())  # rich wraps the message
    with pytest.raises(ValueError, match=said):
        run_bench(BenchConfig(grids=[50], unknowns=[0.2], scenarios=["courtyard", "mall"]
                              if "mall" in said else ["building"]))  # fmt: skip


def test_max_steps_caps_the_walks_and_the_rows_say_so(tmp_path):
    out = tmp_path / "capped.json"
    res = CliRunner().invoke(
        app, ["bench", "--grid", "50", "--unknown", "0.4", "--max-steps", "7", "--json", str(out)]
    )
    assert res.exit_code == 0, res.output
    rows = json.loads(out.read_text())
    assert [(r["mode"], r["steps"], r["capped"], r["arrived"]) for r in rows] == [
        ("eds", 7, True, False),
        ("dss", 7, True, False),
    ]
    assert "7 (capped)" in res.output
    uncapped = run_bench(BenchConfig(grids=[50], unknowns=[0.4], max_steps=10_000)).rows
    assert all(r["arrived"] and not r["capped"] and r["steps"] > 7 for r in uncapped)


def test_bench_refuses_an_unknown_mode():
    res = CliRunner().invoke(app, ["bench", "--grid", "50", "--modes", "eds,bogus"])
    assert res.exit_code != 0


def test_render_paints_every_class_and_writes_a_png(tmp_path):
    scenario = make_courtyard(grid=50, unknown=0.4, seed=0)
    result = walk(scenario, backend="cpu", mode="eds")
    img = walk_image(scenario, result)
    pixels = img.reshape(-1, 3)
    classes = [np.all(np.isclose(pixels, colour), axis=1) for colour in COLOURS.values()]
    assert np.all(np.any(classes, axis=0))  # every cell painted with a legend colour
    assert sum(bool(c.any()) for c in classes) >= 5
    out = render_walk(scenario, result, tmp_path / "walk.png")
    assert out.read_bytes().startswith(PNG)


def test_render_command(tmp_path):
    out = tmp_path / "w.png"
    res = CliRunner().invoke(app, ["render", "--grid", "50", "--unknown", "0.2", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "arrived" in res.output and out.read_bytes().startswith(PNG)
    res = CliRunner().invoke(app, ["render", "--scenario", "building", "--unknown", "0.2",
                                   "--out", str(out)])  # fmt: skip
    assert res.exit_code == 0 and "arrived" in res.output, res.output
    res = CliRunner().invoke(app, ["render", "--scenario", "building", "--grid", "50"])
    assert res.exit_code != 0 and "at least 100" in " ".join(res.output.split())


def test_demo_walks_in_process_and_saves_the_picture(tmp_path):
    out = tmp_path / "sub" / "demo.png"
    res = CliRunner().invoke(app, ["demo", "--in-process", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "arrived" in res.output and "ms per step" in res.output
    assert out.read_bytes().startswith(PNG)


def test_plain_entry_point_needs_no_typer(tmp_path, capsys):
    from sim.benchmark import main

    out = tmp_path / "rows.json"
    main(["--grid", "50", "--unknown", "0.2", "--modes", "eds", "--json", str(out)])
    text = capsys.readouterr().out
    assert "Iter_avg" in text and "device:" in text
    (row,) = json.loads(out.read_text())
    assert row["mode"] == "eds" and set(ROW_FIELDS) <= row.keys()


def test_plain_entry_point_takes_scenarios(tmp_path, capsys):
    from sim.benchmark import main

    out = tmp_path / "rows.json"
    main(["--scenario", "streets", "--grid", "100", "--unknown", "0.2", "--modes", "eds",
          "--json", str(out)])  # fmt: skip
    assert "streets" in capsys.readouterr().out
    (row,) = json.loads(out.read_text())
    assert row["scenario"] == "streets" and row["arrived"]
    for bad in (["--scenario", "mall"], ["--scenario", "building", "--grid", "50"]):
        with pytest.raises(SystemExit):
            main(bad)
    err = capsys.readouterr().err
    assert "unknown scenario 'mall'" in err and "building: grid must be at least 100" in err
