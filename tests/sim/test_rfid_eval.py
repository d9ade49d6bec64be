"""The accuracy evaluation and the commands: rfid-eval, rfid-tags, rfid --mock."""

from __future__ import annotations

import json
import socket

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from cli import rfid as rfid_cli
from drivers.rfid.tags import TagMap
from sim.courtyard import make_courtyard
from sim.rfid_eval import PAPER, along, evaluate, summary_row, tags_for, true_route, walked


@pytest.fixture(scope="module")
def scenario():
    return make_courtyard(100, 0.4, seed=2)


def app() -> typer.Typer:
    a = typer.Typer()
    rfid_cli.register(a)
    return a


def test_walk_leaves_the_cell_centres(scenario) -> None:
    route = true_route(scenario)
    s = np.linspace(0.0, 4.0, 81)
    side = walked(route, s, (0.04, -0.03), 0.05, 2.0) - along(route, s) - [0.04, -0.03]
    sway = np.hypot(*side.T)
    assert sway.max() <= 0.05 + 1e-9 and sway.max() > 0.045  # swaying up to 5 cm
    assert sway[0] < 1e-9  # …around the shifted route


@pytest.mark.timeout(60)
def test_floor_tags_meet_the_papers_claim_and_lsq_beats_the_centroid(scenario) -> None:
    route = true_route(scenario)
    res = {}
    for layout in ("none", "floor"):
        tag_map = tags_for(scenario, layout, seed=2)
        for method in ("centroid", "lsq"):
            res[method, layout] = evaluate(
                tag_map, route, method=method, lf_layout=layout, seed=2, offset=(0.037, -0.061)
            )
    floor = res["lsq", "floor"].row()
    assert floor["median_m"] <= 0.10 and floor["lf_tags"] is True
    assert floor["lf_fraction"] > 0.8
    none_c, none_l = res["centroid", "none"].row(), res["lsq", "none"].row()
    assert none_l["lf_fraction"] == 0.0
    assert none_l["median_m"] > floor["median_m"]
    assert none_l["p95_m"] < none_c["p95_m"]  # why lsq is the default


@pytest.mark.timeout(120)
def test_rfid_eval_command_writes_rows(tmp_path) -> None:
    out = tmp_path / "rfid.json"
    result = CliRunner().invoke(
        app(),
        ["rfid-eval", "--seeds", "1", "--walks", "1", "--setting", "dense", "--json", str(out)],
    )
    assert result.exit_code == 0, result.output
    rows = json.loads(out.read_text())
    assert {(r["method"], r["lf_layout"]) for r in rows} == {
        (m, lay) for m in ("centroid", "lsq", "filter") for lay in ("none", "corners", "floor")
    }
    for r in rows:
        assert set(r) >= {"method", "lf_tags", "median_m", "p95_m", "availability"}
        assert r["lf_tags"] == (r["lf_layout"] != "none")
        assert 0 < r["median_m"] <= r["p95_m"]


@pytest.mark.timeout(60)
def test_in_the_papers_setting_only_the_filter_always_has_a_pose() -> None:
    """1.5 m reads, tags on corners only, LF patches at crossings (``PAPER``); two courtyards
    of the five ``guidebelt rfid-eval`` pools, two walks each."""
    pooled: dict[str, list] = {"lsq": [], "filter": []}
    for seed in (0, 1):
        court = make_courtyard(100, 0.4, seed)
        route = true_route(court)
        tag_map = tags_for(court, "crossings", seed, edge_spacing_m=PAPER.edge_spacing_m)
        offsets = np.random.default_rng(seed).uniform(-0.1, 0.1, size=(2, 2))
        for method, runs in pooled.items():
            runs += [evaluate(tag_map, route, method=method, lf_layout="crossings",
                              seed=seed * 1000 + w, offset=(float(o[0]), float(o[1])),
                              uhf_range_m=PAPER.uhf_range_m)
                     for w, o in enumerate(offsets)]  # fmt: skip
    lsq, filt = (summary_row(m, "crossings", pooled[m]) for m in ("lsq", "filter"))
    assert lsq["availability"] < 0.6  # three tags in 1.5 m reach are rare
    assert lsq["all_p95_m"] == float("inf") or lsq["all_p95_m"] > 1.0
    assert filt["availability"] == 1.0
    assert filt["all_median_m"] <= 0.15 and filt["all_p95_m"] <= 0.40
    assert filt["heading_median_deg"] <= 10.0


def test_crossing_patches_are_small_and_beside_corners(scenario) -> None:
    floor = tags_for(scenario, "floor", seed=2)
    patches = tags_for(scenario, "crossings", seed=2, edge_spacing_m=PAPER.edge_spacing_m)
    assert 0 < len(patches.lf_ids) < 0.25 * len(floor.lf_ids)
    assert len(patches.uhf_ids) < len(floor.uhf_ids)  # corners only, no edge fill
    # Every LF tag lies in a patch beside an obstacle: within 0.45 + 0.5 m (and a cell) of one.
    rows, cols = np.nonzero(scenario.known == 1)
    h = scenario.known.shape[0]
    cells = np.column_stack([(cols + 0.5) * scenario.cell_m, (h - rows - 0.5) * scenario.cell_m])
    d = np.hypot(*(patches.lf_xy[:, None, :] - cells[None, :, :]).transpose(2, 0, 1))
    assert d.min(axis=1).max() <= 0.45 + 0.5 + 0.15


def test_rfid_tags_command_writes_a_valid_map(tmp_path) -> None:
    out = tmp_path / "tags.json"
    result = CliRunner().invoke(app(), ["rfid-tags", "--out", str(out), "--lf-layout", "corners"])
    assert result.exit_code == 0, result.output
    tag_map = TagMap.load(out)
    assert len(tag_map.uhf_ids) >= 3 and len(tag_map.lf_ids) > 0


@pytest.mark.timeout(60)
def test_rfid_command_runs_the_node_on_a_mock_reader() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    result = CliRunner().invoke(
        app(),
        [
            "rfid",
            "--user",
            "bob",
            "--mock",
            "--duration",
            "2.5",
            "--no-scouting",
            "--listen",
            f"tcp/127.0.0.1:{port}",
        ],
    )
    assert result.exit_code == 0, result.output
    stats = json.loads(result.output.strip().splitlines()[-1])
    assert stats["poses"] >= 15 and stats["accepted"] > 0
    assert stats["garbage"] == stats["unknown_tag"] == 0
