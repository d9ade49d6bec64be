"""Extended A* against classic A*: how often it misses or lengthens a path, and the paper's setups.

``python -m sim.extended_astar_study`` prints two tables:

1. **Optimality on random maps.** For each density, ``--queries`` random queries (``--maps``
   maps of ``--side`` x ``--side`` cells, one goal and several starts each, ends free). The
   Dijkstra optimum comes from ``AStarPlanner.costs()`` (the exact field). For each variant of
   extended A* (the default; the skip rule alone, d = 0; the memory criterion alone) it counts
   the queries with a path that it answers with none (*missed*), and of those it answers, the
   share costlier than the optimum and by how much, on salt-and-pepper noise and on boxes
   (``random_map``). Why: the paper says its changes have "no
   significant impact"; this measures it on maps of the kind guidebelt plans on.
2. **The paper's setups A/B/C** (Rettkowski et al. 2016, Fig. 5, only drawn in the paper):
   320 x 240 cells (their image size after resizing; the text's "320x340" is read as a typo),
   A empty, B a few obstacles, C walls with narrow gaps and clutter, seeded. For classic A*
   and extended A*, with the octile heuristic (guidebelt's) and with Manhattan (the paper's),
   nodes expanded, max open list, search time (median of ``--repeats``), path cost (``KEYS``:
   ties of f broken by the lower h, or not at all as in the paper's listing); beside
   the paper's own claims (up to 5.55x fewer nodes, up to 2.88x faster; its per-setup values
   are only in Figs. 6-7, not in the text).
"""

from __future__ import annotations

import argparse
import platform
import subprocess
from dataclasses import dataclass

import numpy as np

from daemon.planning.cpu.astar import AStarPlanner
from daemon.planning.cpu.extended_astar import ExtendedAStarPlanner
from daemon.planning.grid import INF, Cell

SETUP_SHAPE = (240, 320)
SETUP_START: Cell = (225, 15)
SETUP_GOAL: Cell = (15, 305)
PAPER_NODES = 5.55
PAPER_SPEED = 2.88

KEYS = (("octile", "exact"), ("manhattan", "exact"), ("manhattan", "none"))
"""Heuristic and tie-break: guidebelt's (octile, ties of f by lower h); the paper's heuristic
with the same tie-break; the paper's listing as written (Manhattan, ties in heap order)."""

VARIANTS: dict[str, dict] = {
    "extended (d=1, skip, goal on gen.)": {},
    "skip open only (d=0)": {"clearance": 0},
    "memory criterion only (d=1)": {"skip_open": False},
}


@dataclass
class Miss:
    """Counts for one variant at one density."""

    reachable: int = 0
    missed: int = 0
    found: int = 0
    longer: int = 0
    excess_sum: float = 0.0
    excess_max: float = 0.0

    def add(self, optimum: int, cost: int) -> None:
        if optimum >= INF:
            assert cost >= INF, "a path where none exists"
            return
        self.reachable += 1
        if cost >= INF:
            self.missed += 1
            return
        assert cost >= optimum, "cheaper than the optimum"
        self.found += 1
        if cost > optimum:
            excess = (cost - optimum) / optimum if optimum else 0.0
            self.longer += 1
            self.excess_sum += excess
            self.excess_max = max(self.excess_max, excess)


def random_map(rng: np.random.Generator, side: int, density: float, kind: str) -> np.ndarray:
    """``noise``: each cell blocked with probability ``density`` (the worst case for the
    memory criterion: most free cells touch an obstacle). ``boxes``: rectangles of 2-8 cells
    a side until ``density`` of the map is blocked, closer to an inflated map's blobs."""
    if kind == "noise":
        return rng.random((side, side)) < density
    blocked = np.zeros((side, side), bool)
    while blocked.mean() < density:
        r, c = rng.integers(0, side, 2)
        hh, ww = rng.integers(2, 9, 2)
        blocked[r : r + hh, c : c + ww] = True
    return blocked


def optimality(
    densities: list[float], side: int, maps: int, queries: int, seed: int, kind: str
) -> str:
    """Table 1: missed / longer rates per density and variant."""
    per_map = max(1, queries // maps)
    lines = [f"random {side}x{side} maps ({kind}), {maps * per_map} queries per density, "
             f"seed {seed}; missed: of the reachable; longer: of those answered",
             f"{'density':>7}  {'variant':<36} {'reachable':>9} {'missed':>14} "
             f"{'longer':>14} {'mean excess':>11} {'max excess':>10}"]  # fmt: skip
    exact = AStarPlanner()
    for density in densities:
        rng = np.random.default_rng([seed, int(density * 1000)])
        counts = {name: Miss() for name in VARIANTS}
        planners = {name: ExtendedAStarPlanner(**kw) for name, kw in VARIANTS.items()}
        for _ in range(maps):
            blocked = random_map(rng, side, density, kind)
            free = np.flatnonzero(~blocked)
            if free.size < 2:
                continue
            goal = divmod(int(rng.choice(free)), side)
            exact.plan(blocked, goal)
            field = exact.costs()
            for p in planners.values():
                p.plan(blocked, goal)
            for flat in rng.choice(free, per_map):
                start = divmod(int(flat), side)
                for name, p in planners.items():
                    counts[name].add(int(field[start]), p.cost_at(start))
        for name, c in counts.items():
            longer = c.longer / c.found if c.found else 0.0
            mean = c.excess_sum / c.longer if c.longer else 0.0
            lines.append(
                f"{density:>7.2f}  {name:<36} {c.reachable:>9} "
                f"{c.missed:>5} ({c.missed / max(c.reachable, 1):>6.1%}) "
                f"{c.longer:>5} ({longer:>6.1%}) {mean:>11.1%} {c.excess_max:>10.1%}"
            )
    return "\n".join(lines)


def setup_map(name: str, seed: int) -> np.ndarray:
    """Setup A (empty), B (a few boxes) or C (walls with gaps, clutter), 240 x 320, seeded."""
    h, w = SETUP_SHAPE
    blocked = np.zeros(SETUP_SHAPE, bool)
    rng = np.random.default_rng([seed, ord(name)])
    if name == "B":
        for _ in range(6):
            r, c = int(rng.integers(40, h - 70)), int(rng.integers(40, w - 70))
            blocked[r : r + int(rng.integers(15, 35)), c : c + int(rng.integers(15, 35))] = True
    elif name == "C":
        for i, row in enumerate((70, 130, 190)):
            blocked[row : row + 4, :] = True
            gap = 20 + (i % 2) * (w - 60) + int(rng.integers(-10, 10))  # alternating sides
            blocked[row : row + 4, gap : gap + 12] = False
        for _ in range(40):
            r, c = int(rng.integers(20, h - 30)), int(rng.integers(10, w - 20))
            blocked[r : r + int(rng.integers(3, 10)), c : c + int(rng.integers(3, 10))] = True
    elif name != "A":
        raise ValueError(f"unknown setup {name!r}")
    for r, c in (SETUP_START, SETUP_GOAL):
        blocked[r - 3 : r + 4, c - 3 : c + 4] = False
    return blocked


def measure(
    planner: AStarPlanner, blocked: np.ndarray, repeats: int
) -> tuple[int, int, float, int]:
    """(expanded, max open, median search ms, cost) of the start-to-goal search."""
    ms = []
    for _ in range(repeats):
        planner.plan(blocked, SETUP_GOAL)  # a new map version: the next read searches again
        planner.path(SETUP_START)
        assert planner.search_stats is not None
        ms.append(planner.search_stats.ms)
    stats = planner.search_stats
    return stats.iterations, planner.max_open, float(np.median(ms)), planner.cost_at(SETUP_START)


def setups(seed: int, repeats: int) -> str:
    """Table 2: classic against extended A* on setups A/B/C, two heuristics."""
    lines = [f"setups A/B/C, {SETUP_SHAPE[1]}x{SETUP_SHAPE[0]} cells, start {SETUP_START}, "
             f"goal {SETUP_GOAL}, seed {seed}, time = median of {repeats} searches",
             f"{'setup':<5} {'key':<11} {'planner':<9} {'expanded':>8} {'max open':>8} "
             f"{'ms':>8} {'cost':>6}   {'nodes x':>7} {'open x':>6} {'speed x':>7}"]  # fmt: skip
    for name in "ABC":
        blocked = setup_map(name, seed)
        for heuristic, ties in KEYS:
            a = measure(AStarPlanner(heuristic, ties), blocked, repeats)
            e = measure(ExtendedAStarPlanner(heuristic=heuristic, tie_break=ties), blocked, repeats)
            heuristic = f"{heuristic[:5]}/{ties}"
            for label, m in (("A*", a), ("extended", e)):
                cost = "none" if m[3] >= INF else str(m[3])
                ratios = "" if label == "A*" else (
                    f"   {a[0] / max(e[0], 1):>7.2f} {a[1] / max(e[1], 1):>6.2f} "
                    f"{a[2] / max(e[2], 1e-9):>7.2f}"
                )  # fmt: skip
                lines.append(f"{name:<5} {heuristic:<11} {label:<9} {m[0]:>8} {m[1]:>8} "
                             f"{m[2]:>8.3f} {cost:>6}{ratios}")  # fmt: skip
    lines.append(f"paper (Figs. 6-7, ARM A9, Manhattan): up to {PAPER_NODES}x fewer nodes, "
                 f"up to {PAPER_SPEED}x faster; per-setup values only drawn")  # fmt: skip
    return "\n".join(lines)


def header() -> str:
    """Machine and commit, for the lab notes."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=False).stdout.strip()  # fmt: skip
    except OSError:
        commit = "?"
    return f"machine {platform.machine()} {platform.processor() or ''}, commit {commit}".strip()


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--densities", default="0.05,0.1,0.2,0.3,0.4")
    p.add_argument("--side", type=int, default=64)
    p.add_argument("--maps", type=int, default=200)
    p.add_argument("--queries", type=int, default=2000, help="per density")
    p.add_argument("--repeats", type=int, default=21)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--skip-optimality", action="store_true")
    a = p.parse_args(argv)
    print(header())
    if not a.skip_optimality:
        densities = [float(d) for d in a.densities.split(",")]
        for kind in ("noise", "boxes"):
            print(optimality(densities, a.side, a.maps, a.queries, a.seed, kind))
            print()
    print(setups(a.seed, a.repeats))


if __name__ == "__main__":
    main()
