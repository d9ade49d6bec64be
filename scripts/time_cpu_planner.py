"""Time the CPU planners on a walk through a random obstacle field (not the paper's scenario).

A square grid (400 x 400 by default) holds random disc-shaped obstacles covering a fraction
of it (0.4); start at the bottom, goal at the top, connected in the true map. The walker
starts with an empty map (unknown = free), and at each step a sensor (3 m = 30 cells, 80°
field of view around the direction of the path, no occlusion) reveals the true obstacles in
range; the revealed cells are inflated (``InflatedMap``) and the flipped cells go to an EDS
planner and a DSS planner (``update`` on each); the walker moves one cell along the EDS
path. Per step the script times ``update`` + ``path(walker)`` on each.
numba compilation is done on a small grid first and excluded.

    .venv/bin/python scripts/time_cpu_planner.py [--size 400] [--fraction 0.4] [--seed 1]
        [--variant fast|paper]

(with the package not installed in the venv, prefix ``PYTHONPATH=.``)
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from daemon.planning import InflatedMap, make_planner
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF, OCCUPIED

SENSOR_RANGE = 30
FOV = math.radians(80)


def random_field(size: int, fraction: float, rng: np.random.Generator) -> np.ndarray:
    occ = np.zeros((size, size), dtype=np.uint8)
    while occ.mean() < fraction:
        r = int(rng.integers(1, 5))
        cy, cx = rng.integers(0, size, 2)
        y, x = np.ogrid[-r : r + 1, -r : r + 1]
        disc = (y * y + x * x) <= r * r
        y0, x0 = cy - r, cx - r
        ys = slice(max(y0, 0), min(y0 + 2 * r + 1, size))
        xs = slice(max(x0, 0), min(x0 + 2 * r + 1, size))
        sub = disc[ys.start - y0 : ys.stop - y0, xs.start - x0 : xs.stop - x0]
        occ[ys, xs][sub] = OCCUPIED
    return occ


def scenario(size: int, fraction: float, seed: int, radius: int):
    rng = np.random.default_rng(seed)
    start, goal = (size - 2, size // 2), (1, size // 2)
    while True:
        occ = random_field(size, fraction, rng)
        for cell in (start, goal):  # a clear patch where the walk begins and ends
            occ[max(cell[0] - 3, 0) : cell[0] + 4, cell[1] - 3 : cell[1] + 4] = 0
        true_blocked = InflatedMap(occ, radius).blocked
        if dijkstra_field(true_blocked, goal)[start] < INF:
            return occ, start, goal


def sensor_cells(size: int, at: tuple[int, int], toward: tuple[int, int]) -> np.ndarray:
    """Flat indices of the cells within range and field of view (rows grow southwards)."""
    r = SENSOR_RANGE
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    heading = math.atan2(-(toward[0] - at[0]), toward[1] - at[1])
    ang = np.arctan2(-dy, dx) - heading
    ang = (ang + np.pi) % (2 * np.pi) - np.pi
    keep = (dy * dy + dx * dx <= r * r) & (np.abs(ang) <= FOV / 2)
    rows, cols = dy[keep] + at[0], dx[keep] + at[1]
    inside = (rows >= 0) & (rows < size) & (cols >= 0) & (cols < size)
    return rows[inside] * size + cols[inside]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--fraction", type=float, default=0.4)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radius", type=int, default=1, help="inflation radius in cells")
    ap.add_argument("--variant", choices=("fast", "paper"), default="fast")
    ap.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="cpu: this thread's CPU time, less disturbed by other work on a shared machine",
    )
    args = ap.parse_args()

    warm = make_planner("eds", "cpu", "fast")  # compile (or load cached) kernels outside the timing
    warm.plan(np.zeros((8, 8), bool), (0, 0))
    warm.update(np.array([9]), np.array([True]))
    warm.path((7, 7))

    clock = time.perf_counter if args.clock == "wall" else time.thread_time
    occ, start, goal = scenario(args.size, args.fraction, args.seed, args.radius)
    known = InflatedMap(np.zeros_like(occ), args.radius)
    eds, dss = make_planner("eds", "cpu", args.variant), make_planner("dss", "cpu", args.variant)
    eds.plan(known.blocked, goal)
    dss.plan(known.blocked, goal)
    true_flat = occ.reshape(-1)
    here = start
    eds_ms, dss_ms, touched, eds_it, dss_it = [], [], [], [], []
    path = eds.path(here)
    while here != goal:
        ahead = tuple(int(v) for v in path[min(5, len(path) - 1)])
        seen = sensor_cells(args.size, here, ahead)
        new = seen[known.occupancy.reshape(-1)[seen] != true_flat[seen]]
        flipped, now = known.apply(new, true_flat[new])

        t0 = clock()
        st = eds.update(flipped, now)
        path = eds.path(here)
        eds_ms.append((clock() - t0) * 1e3)
        t0 = clock()
        dss_it.append(dss.update(flipped, now).iterations)
        dss_path = dss.path(here)
        dss_ms.append((clock() - t0) * 1e3)
        touched.append(st.cells_touched)
        eds_it.append(st.iterations)
        if not np.array_equal(path, dss_path):
            raise SystemExit("EDS and DSS paths differ")
        if len(path) < 2:
            raise SystemExit(f"no path from {here}")
        here = (int(path[1][0]), int(path[1][1]))

    print(
        f"cpu-{args.variant}, grid {args.size}x{args.size}, obstacles {occ.mean():.0%}, "
        f"steps {len(eds_ms)}, iterations per step: EDS {np.mean(eds_it):.1f}, "
        f"DSS {np.mean(dss_it):.1f}; {args.clock} clock"
    )
    for name, ms in (("EDS update+path", eds_ms), ("DSS update+path", dss_ms)):
        a = np.array(ms)
        print(
            f"{name}: median {np.median(a):.3f} ms  mean {a.mean():.3f}  "
            f"p95 {np.percentile(a, 95):.3f}  max {a.max():.3f}"
        )
    print(
        f"EDS cells touched per step: median {int(np.median(touched))}, "
        f"max {max(touched)} of {args.size * args.size}"
    )


if __name__ == "__main__":
    main()
