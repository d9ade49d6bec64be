"""The paper's rubber band on the harmonic field: ends fixed, never a point or segment in a
blocked cell, and the harmonic path's 45° and 90° turns spread into small ones."""

from __future__ import annotations

import numpy as np

from daemon.guidance.smoothing import path_length, smooth_path, smoothing_model, turning_angles
from daemon.planning import make_planner
from daemon.planning.harmonic.rubber_band import rubber_band


def test_the_band_shortens_and_smooths_without_touching_an_obstacle(maps):
    rng = np.random.default_rng(5)
    for _ in range(4):
        goal, start = (3, 3), (46, 45)
        blocked = maps.walled_map(rng, 50, 0.06, goal, start)
        planner = make_planner("harmonic", "cpu")
        planner.plan(blocked, goal)
        path = planner.path(start)
        if len(path) < 3:
            continue
        band = rubber_band(path, planner.field(), blocked)
        assert np.allclose(band[0], path[0] + 0.5) and np.allclose(band[-1], path[-1] + 0.5)
        assert maps.segments_free(blocked, band)
        assert path_length(band) <= path_length(path + 0.5) + 1e-9
        assert (turning_angles(band) > 30).sum() < max(1, (turning_angles(path) > 30).sum())


def test_the_band_goes_on_from_where_the_last_call_left_it(maps):
    rng = np.random.default_rng(9)
    goal, start = (3, 3), (56, 55)
    blocked = maps.walled_map(rng, 60, 0.06, goal, start)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, goal)
    path = planner.path(start)
    first = planner.band(path, blocked)
    lengths = [path_length(first)]
    for _ in range(4):
        lengths.append(path_length(planner.band(path, blocked)))
    # Each call goes on from the last band: shorter than one call's worth from the centres.
    assert lengths[-1] < lengths[0] and lengths[0] < path_length(path + 0.5)
    # The walker moves on: the rest of the path starts from the old band where it can.
    rest = path[7:]
    band = planner.band(rest, blocked)
    assert np.allclose(band[[0, -1]], rest[[0, -1]] + 0.5)
    assert maps.segments_free(blocked, band)
    # A new plan forgets the old band.
    planner.plan(blocked, goal)
    assert np.allclose(planner.band(path, blocked), first)


def test_one_smoothing_model_per_planner():
    assert "harmonic" in smoothing_model("harmonic")
    assert smoothing_model("eds") == smoothing_model("astar") != smoothing_model("harmonic")
    blocked = np.zeros((20, 20), dtype=bool)
    path = np.array([(1, 1), (2, 2), (3, 2), (4, 3), (5, 3)], dtype=np.int32)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, (5, 3))
    out = smooth_path("harmonic", path, blocked, 0.1, field=planner.field())
    assert out.shape == (5, 2)


def test_guidance_smooths_with_the_planners_own_band(maps):
    from daemon.guidance.guide import Guidance, turning_points_from_polyline
    from daemon.guidance.smoothing import planner_band
    from daemon.navigation.navigator import Navigator, NavigatorSettings

    rng = np.random.default_rng(3)
    blocked = maps.random_map(rng, 40, 40, 0.05)
    goal, start = (2, 2), (37, 36)
    blocked[goal] = blocked[start] = False
    planner, twin = make_planner("harmonic", "cpu"), make_planner("harmonic", "cpu")
    planner.plan(blocked, goal)
    twin.plan(blocked, goal)
    path = planner.path(start)
    assert len(path) > 2
    guidance = Guidance(smooth=True)
    guidance.planner = lambda: planner
    expected = turning_points_from_polyline(twin.band(path, blocked), blocked,
                                            guidance.max_leg_cells)  # fmt: skip
    assert np.allclose(guidance._points(path, blocked), expected)
    assert planner_band(make_planner("eds", "cpu")) is None  # the repulsion band's planners
    # The navigator hands guidance the planner its route holds (a CPU fallback included).
    nav = Navigator("u", NavigatorSettings(planner="harmonic", backend="cpu"))
    assert nav.guidance.planner is not None and nav.guidance.planner() is nav.route.planner
