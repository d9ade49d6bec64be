"""Chen et al.'s visibility graph + A*: their Table 1, path length, and the courtyard walks.

``python -m sim.visgraph_study`` prints three tables:

1. **Table 1's shape** (search time, new algorithm against Dijkstra; min, max, average). The
   paper's maps are an indoor room with a few convex obstacles of fewer than seven edges
   (Figs. 2, 7; the text gives no size, obstacle count or query count). Here: ``--maps``
   rooms of 10 m x 10 m at 10 cm (100 x 100 cells), each with ``--obstacles`` random convex
   polygons (3-6 edges, 0.4-2 m across) rasterised and inflated by the user's 0.3 m as the
   daemon does, and ``--queries`` random start/goal pairs per room. Per query:
   *A\\* (kept map)*: the planner keeps the room's polygons and every visibility already
   judged, the start and goal change (§4.4); *A\\* (cold)*: the first query after the room was
   cut, nothing judged yet; *Dijkstra (whole graph)*: every pair of nodes judged for the new
   start and goal, then Dijkstra (the paper's baseline, which must "refactor the visual
   map"); *Dijkstra (lazy)*: the kept map searched with ``h = 0``. The same code times all.
2. **Length on the courtyard** (fully known, the true map inflated): the visibility path's
   Euclidean length against the EDS grid path's length, raw and after guidance's turning
   points (``daemon/guidance/turning_points.py``), and the visibility path's own cells after
   turning points; plus how often the polygons shut a passage the grid keeps open.
3. **Courtyard walks** (unknown obstacles found on the way, as ``guidebelt bench`` walks):
   arrivals, metres walked against EDS, the share of path reads the polygons could not answer
   (the grid's A* answered them, ``VisGraphPlanner.fallbacks``), planning time per step.
"""

from __future__ import annotations

import argparse
import math
import platform
import subprocess
import time

import numpy as np

from daemon.guidance.turning_points import turning_points
from daemon.navigation.navigator import Navigator
from daemon.planning import make_planner
from daemon.planning.grid import OCCUPIED, Cell
from daemon.planning.inflation import dilate, radius_in_cells
from daemon.planning.visgraph.planner import VisGraphPlanner
from daemon.planning.visgraph.polygons import convex_hull, covers
from sim.courtyard import make_courtyard
from sim.walk import paper_settings, walk

PAPER_TABLE1 = {"new algorithm": (0.4560, 0.8650, 0.6605), "Dijkstra": (1.3550, 1.9460, 1.6505)}
"""Chen et al., Table 1: search time in seconds (minimum, maximum, average), MATLAB."""
ROOM = 100
USER_RADIUS_M = 0.30
CELL_M = 0.10


def room(rng: np.random.Generator, obstacles: int) -> np.ndarray:
    """A 10 m room with ``obstacles`` random convex polygons of 3-6 edges, inflated."""
    occupied = np.zeros((ROOM, ROOM), dtype=bool)
    rr, cc = np.mgrid[0:ROOM, 0:ROOM].astype(np.float64)
    for _ in range(obstacles):
        for _attempt in range(20):
            centre = rng.uniform(10, ROOM - 10, size=2)
            size = rng.uniform(4, 20)
            poly = convex_hull(centre + rng.uniform(-size / 2, size / 2, size=(6, 2)))
            if 3 <= len(poly) <= 6:
                break
        occupied |= covers(poly, rr, cc)
    return dilate(occupied, radius_in_cells(USER_RADIUS_M, CELL_M))


def free_pair(rng: np.random.Generator, blocked: np.ndarray) -> tuple[Cell, Cell]:
    free = np.argwhere(~blocked)
    while True:
        a, b = free[rng.integers(len(free))], free[rng.integers(len(free))]
        if math.dist(a, b) > ROOM / 2:
            return (int(a[0]), int(a[1])), (int(b[0]), int(b[1]))


def table1(maps: int, obstacles: int, queries: int, seed: int) -> dict[str, list[float]]:
    """Seconds per query of each search (see the module's docstring)."""
    rng = np.random.default_rng(seed)
    times: dict[str, list[float]] = {
        "A* (kept map)": [], "A* (cold)": [], "Dijkstra (whole graph)": [],
        "Dijkstra (lazy, kept map)": [],
    }  # fmt: skip
    lengths_agree = True
    for _ in range(maps):
        blocked = room(rng, obstacles)
        pairs = [free_pair(rng, blocked) for _ in range(queries)]
        kept, kept_dijkstra = VisGraphPlanner(), VisGraphPlanner(heuristic=False)
        for start, goal in pairs:
            cold = VisGraphPlanner()
            cold.plan(blocked, goal)
            t0 = time.perf_counter()
            _, a_cold, _ = cold.polygon_path(start)
            times["A* (cold)"].append(time.perf_counter() - t0)
            whole = VisGraphPlanner(heuristic=False)
            whole.plan(blocked, goal)
            t0 = time.perf_counter()
            _, d_whole, _ = whole.polygon_path(start, whole_graph=True)
            times["Dijkstra (whole graph)"].append(time.perf_counter() - t0)
            for planner, name in (
                (kept, "A* (kept map)"),
                (kept_dijkstra, "Dijkstra (lazy, kept map)"),
            ):
                planner.plan(blocked, goal)
                t0 = time.perf_counter()
                _, length, _ = planner.polygon_path(start)
                times[name].append(time.perf_counter() - t0)
                lengths_agree &= math.isclose(length, a_cold, rel_tol=1e-9) or length == a_cold
            lengths_agree &= math.isclose(d_whole, a_cold, rel_tol=1e-9) or d_whole == a_cold
    if not lengths_agree:
        raise AssertionError("the searches found different lengths")
    return times


def polyline_cells(points: np.ndarray) -> float:
    return float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 0.0


def lengths(grid: int, unknowns: list[float], seeds: int) -> list[dict]:
    """Per courtyard: visibility length against EDS raw and after turning points."""
    rows = []
    for unknown in unknowns:
        for seed in range(seeds):
            sc = make_courtyard(grid, unknown, seed=seed)
            blocked = dilate(sc.true == OCCUPIED, sc.radius_cells)
            eds = make_planner("eds", "cpu")
            eds.plan(blocked, sc.goal)
            grid_path = eds.path(sc.start)
            vis = VisGraphPlanner(fallback=False)
            vis.plan(blocked, sc.goal)
            vis_cells = vis.path(sc.start)
            m = sc.cell_m
            row = {
                "unknown": unknown,
                "seed": seed,
                "shut": len(grid_path) > 0 and not len(vis_cells),
            }
            row["eds_raw"] = polyline_cells(grid_path.astype(float)) * m
            row["eds_tp"] = polyline_cells(turning_points(grid_path, blocked)) * m
            if len(vis_cells):
                row["vis"] = vis.last_length * m
                row["vis_tp"] = polyline_cells(turning_points(vis_cells, blocked)) * m
            rows.append(row)
    return rows


def walks(grid: int, unknowns: list[float], seeds: int) -> list[dict]:
    """Courtyard walks with visgraph and with EDS: arrivals, length, fallbacks, step time."""
    rows = []
    for unknown in unknowns:
        for seed in range(seeds):
            sc = make_courtyard(grid, unknown, seed=seed)
            nav = Navigator("walk", paper_settings(sc, "visgraph", "cpu", "fast"))
            res = walk(sc, backend="cpu", mode="visgraph", navigator=nav)
            eds = walk(sc, backend="cpu", mode="eds")
            planner = nav.route.planner
            assert isinstance(planner, VisGraphPlanner)
            ms = res.plan_ms
            rows.append({
                "unknown": unknown, "seed": seed, "arrived": res.arrived,
                "eds_arrived": eds.arrived, "walked": res.walked_m, "eds_walked": eds.walked_m,
                "steps": res.steps, "fallbacks": planner.fallbacks, "reads": len(ms),
                "ms_median": float(np.median(ms)), "ms_p99": float(np.percentile(ms, 99)),
                "ms_max": float(ms.max()), "eds_ms_median": float(np.median(eds.plan_ms)),
            })  # fmt: skip
    return rows


def print_table1(times: dict[str, list[float]]) -> None:
    print("Table 1 (search time per query, ms: min / max / mean; the paper's in s, MATLAB)")
    for name, values in times.items():
        v = np.array(values) * 1e3
        print(f"  {name:28s} {v.min():8.2f} {v.max():8.2f} {v.mean():8.2f}   (n = {v.size})")
    for name, (lo, hi, avg) in PAPER_TABLE1.items():
        print(f"  paper: {name:21s} {lo * 1e3:8.0f} {hi * 1e3:8.0f} {avg * 1e3:8.0f}")
    a = np.mean(times["A* (kept map)"])
    d = np.mean(times["Dijkstra (whole graph)"])
    paper = PAPER_TABLE1["Dijkstra"][2] / PAPER_TABLE1["new algorithm"][2]
    print(
        f"  mean ratio Dijkstra (whole graph) / A* (kept map): {d / a:.1f}x (paper: {paper:.1f}x)"
    )
    print(f"  mean ratio Dijkstra (lazy) / A* (kept map): "
          f"{np.mean(times['Dijkstra (lazy, kept map)']) / a:.1f}x; A* cold / kept: "
          f"{np.mean(times['A* (cold)']) / a:.1f}x")  # fmt: skip


def print_lengths(rows: list[dict]) -> None:
    print("Length on the fully known courtyard (m): EDS grid path raw / after turning points,")
    print("visibility path (polygon length) / its cells after turning points")
    for r in rows:
        vis = "shut" if r["shut"] else f"{r['vis']:6.2f} {r['vis_tp']:6.2f}"
        print(f"  {r['unknown']:.0%} seed {r['seed']}: EDS {r['eds_raw']:6.2f} {r['eds_tp']:6.2f}"
              f"   visgraph {vis}")  # fmt: skip
    ok = [r for r in rows if not r["shut"]]
    if ok:
        ratio = np.array([r["vis"] / r["eds_tp"] for r in ok])
        raw = np.array([r["vis"] / r["eds_raw"] for r in ok])
        print(f"  visgraph / EDS after turning points: median {np.median(ratio):.3f} "
              f"(min {ratio.min():.3f}, max {ratio.max():.3f}); / EDS raw: median "
              f"{np.median(raw):.3f}")  # fmt: skip
    print(f"  shut by the polygons (grid has a path, graph none): {sum(r['shut'] for r in rows)}"
          f" of {len(rows)}")  # fmt: skip


def print_walks(rows: list[dict]) -> None:
    print("Courtyard walks (visgraph vs EDS): arrived, m walked, graph had no path / path reads,"
          " planning ms per step median / p99 / max (EDS median)")  # fmt: skip
    for r in rows:
        print(f"  {r['unknown']:.0%} seed {r['seed']}: arrived {r['arrived']} "
              f"(EDS {r['eds_arrived']})"
              f", {r['walked']:.1f} m (EDS {r['eds_walked']:.1f}), fallbacks {r['fallbacks']}/"
              f"{r['reads']}, {r['ms_median']:.1f} / {r['ms_p99']:.1f} / {r['ms_max']:.1f} ms"
              f" (EDS {r['eds_ms_median']:.2f})")  # fmt: skip
    fb, reads = sum(r["fallbacks"] for r in rows), sum(r["reads"] for r in rows)
    print(f"  path reads the grid's A* answered: {fb} of {reads} ({fb / max(reads, 1):.1%})")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", type=int, default=5)
    ap.add_argument("--obstacles", type=int, default=8)
    ap.add_argument("--queries", type=int, default=20)
    ap.add_argument("--grid", type=int, default=100)
    ap.add_argument("--unknown", default="0.2,0.4,0.6")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--skip-walks", action="store_true")
    a = ap.parse_args(argv)
    unknowns = [float(x) for x in a.unknown.split(",")]
    rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    cpu = platform.processor() or platform.machine()
    print(f"# {when}, {cpu}, commit {rev.stdout.strip() or '?'}")
    VisGraphPlanner().plan(np.zeros((4, 4), bool), (0, 0))  # compile before timing
    warm = VisGraphPlanner()
    warm.plan(room(np.random.default_rng(99), 3), (5, 5))
    warm.polygon_path((90, 90), whole_graph=True)
    print_table1(table1(a.maps, a.obstacles, a.queries, a.seed))
    print_lengths(lengths(a.grid, unknowns, a.seeds))
    if not a.skip_walks:
        print_walks(walks(a.grid, unknowns, a.seeds))


if __name__ == "__main__":
    main()
