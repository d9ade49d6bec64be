"""The genetic algorithm of Ghoniem et al. (GA with A* as its fitness), and the "GA alone".

The paper's Algorithm 1, as read here:

1. **Chromosome** (Section 4.2, Eq. 2-4): the path ``P = [S, P_1, ..., P_n, T]``, the start,
   ``n = GaParams.waypoints`` random free cells (``No_Of_Points_In_Solution``) and the goal.
   Only the waypoints are genes; S and T never change.
2. **Initial population**: ``population`` chromosomes of random free waypoints. "Free" is
   read as a free cell the user can reach: waypoints are drawn from the start's connected
   component (one flood fill per run). A waypoint in a pocket cut off from the start can never
   be part of a path, and drawing one would only make A* flood the whole map to say so.
3. **Fitness** (Algorithm 2, "the evaluation function f(n) of the A* algorithm is used as the
   fitness function"): the cost ``c`` of Eq. 2 with each ``d_i`` the cost of the A* path
   between consecutive points, searched with the compiled A* of ``astar_kernels.py``
   (octile heuristic, ties of ``f`` broken by the lower ``h``: each segment is optimal).
   Roulette selection needs a quantity to maximise: a chromosome's share is ``1 / c``.
   ``IsFeasible(O_i, O_{i+1})`` (Algorithm 2) holds when A* joins the two points; with
   waypoints drawn from the start's component it holds for every pair, and a chromosome
   whose segment has no path would get share 0.
4. **Roulette wheel selection** (Section 4.3, "every individual is associated with a portion
   proportional to its fitness"): ``population`` parents drawn with replacement.
5. **Single-point crossover**: parents are paired in order; with probability
   ``crossover_rate`` a cut point is drawn among the waypoint genes and the tails swapped.
6. **Mutation**: each waypoint gene, with probability ``mutation_rate``, is replaced by a
   random reachable cell "which is not existed in the path" (Section 4.3).
7. **Evaluate, replace**: the children replace the parents (generational; the paper says
   "update the old solution P with the new one" and names no elitism). The best chromosome
   seen in any generation is the answer. **Termination condition**: ``generations`` rounds.

The answer's path is the A* segments joined at the waypoints. Where it passes a cell twice
(a waypoint off to the side, reached and left by the same way), the loop between the two
visits is cut: the path stays a walk of 8-adjacent free cells and only gets cheaper. This
step is ours, not the paper's; ``GaResult.fitness_cost`` is the paper's ``c`` before it.

**GA alone** (``evolve_straight``): the same GA where the paper's "conventional GA" is read
from Section 4.2: the path is the straight segments between consecutive points, ``d_i`` the
Euclidean distance of Eq. 4, and ``IsFeasible`` says that the segment crosses no blocked
cell (Eq. 3: ``f(x_i, y_i) = 0`` along it). Segments are rasterised with Bresenham's line,
which gives 8-adjacent cells, so the path can be walked and measured on the same grid as
A*'s; a chromosome with an infeasible segment has share 0. With few waypoints on a cluttered
map no chromosome may be feasible: the GA then answers no path (``GaResult.cost`` INF).

Randomness: one ``numpy.random.Generator`` seeded from ``(seed, start, goal)``: a run is a
pure function of the map, the ends and ``GaParams``; the same inputs give the same path.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..grid import INF, Cell, path_cost
from .ga_segments import Segments, reachable

_EMPTY = np.empty((0, 2), dtype=np.int32)


@dataclass(frozen=True, slots=True)
class GaParams:
    """Algorithm 1's inputs. The defaults are small so that a step on which the planner
    reroutes stays short on a walk (10-90 ms on one core at 100-200 cells a side, measured
    with ``guidebelt bench``); ``sim/ga_study.py`` sets larger ones."""

    population: int = 8
    """Population_Size: chromosomes per generation."""
    generations: int = 6
    """No_Of_Generations: the termination condition."""
    crossover_rate: float = 0.8
    """Probability that a pair of parents is crossed (single point)."""
    mutation_rate: float = 0.2
    """Probability that one waypoint gene is replaced."""
    waypoints: int = 2
    """No_Of_Points_In_Solution: waypoints between start and goal (the genes)."""
    seed: int = 0

    def __post_init__(self) -> None:
        if self.population < 2:
            raise ValueError(f"population must be >= 2, got {self.population}")
        if self.generations < 1:
            raise ValueError(f"generations must be >= 1, got {self.generations}")
        if self.waypoints < 1:
            raise ValueError(f"waypoints must be >= 1, got {self.waypoints}")
        for name in ("crossover_rate", "mutation_rate"):
            rate = getattr(self, name)
            if not 0.0 <= rate <= 1.0:
                raise ValueError(f"{name} must lie in [0, 1], got {rate}")


@dataclass(frozen=True, slots=True)
class GaResult:
    path: np.ndarray
    """``(k, 2) int32`` cells from start to goal; empty when no path was found."""
    cost: int
    """The path's cost in 10/14 units (``grid.path_cost``), INF when there is none."""
    fitness_cost: float
    """The paper's ``c`` (Eq. 2) of the best chromosome (before loop cutting); INF if none."""
    waypoints: np.ndarray
    """``(n, 2) int32``: the best chromosome's waypoints (empty when none is feasible)."""
    evaluations: int
    """Chromosomes evaluated."""
    searches: int
    """A* segment searches run (a segment is searched once per run, then remembered)."""
    expanded: int
    """Cells expanded by those searches."""
    max_open: int
    """The largest open list of any of them."""
    ms: float


@njit(cache=True, nogil=True)
def bresenham(r0, c0, r1, c1, out):  # pragma: no cover - compiled
    """Cells of Bresenham's line from (r0, c0) to (r1, c1), both included, into ``out``
    ((max(|dr|, |dc|) + 1, 2)); consecutive cells are 8-adjacent."""
    dr = abs(r1 - r0)
    dc = abs(c1 - c0)
    sr = 1 if r1 > r0 else -1
    sc = 1 if c1 > c0 else -1
    err = dc - dr
    r, c = r0, c0
    i = 0
    while True:
        out[i, 0] = r
        out[i, 1] = c
        i += 1
        if r == r1 and c == c1:
            break
        e2 = 2 * err
        if e2 > -dr and e2 < dc:  # both axes step: one diagonal move, never two straight
            err += dc - dr
            r += sr
            c += sc
        elif e2 > -dr:
            err -= dr
            c += sc
        else:
            err += dc
            r += sr
    return i


def straight_line(a: Cell, b: Cell) -> np.ndarray:
    """The 8-adjacent cells of the straight segment from ``a`` to ``b`` (both included)."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1])) + 1
    out = np.empty((n, 2), dtype=np.int64)
    count = bresenham(int(a[0]), int(a[1]), int(b[0]), int(b[1]), out)
    return out[:count].astype(np.int32)


def cut_loops(cells: np.ndarray) -> np.ndarray:
    """``cells`` (1-D) with every stretch between two visits of one cell removed."""
    seen: dict[int, int] = {}
    out: list[int] = []
    for v in cells.tolist():
        at = seen.get(v)
        if at is not None:
            for dropped in out[at + 1 :]:
                del seen[dropped]
            del out[at + 1 :]
            continue
        seen[v] = len(out)
        out.append(v)
    return np.asarray(out, dtype=np.int64)


def _rng(params: GaParams, start: Cell, goal: Cell) -> np.random.Generator:
    return np.random.default_rng([params.seed, start[0], start[1], goal[0], goal[1]])


def _run(
    rng: np.random.Generator,
    params: GaParams,
    start: int,
    goal: int,
    pool: np.ndarray,
    segment_cost,
    carried: np.ndarray | None = None,
) -> tuple[np.ndarray | None, float, int]:
    """Algorithm 1 on genes drawn from ``pool`` (padded cells); ``segment_cost(a, b)`` is the
    d_i of Eq. 2 (INF when infeasible); ``carried`` (m padded cells), if given, replaces the
    first random chromosome. Returns (best chromosome or None, its c, evaluations)."""
    n, m = params.population, params.waypoints
    pop = pool[rng.integers(0, pool.size, (n, m))]
    if carried is not None:
        pop[0] = carried

    def evaluate(chromosomes: np.ndarray) -> np.ndarray:
        costs = np.empty(len(chromosomes), dtype=np.float64)
        for i, genes in enumerate(chromosomes):
            points = [start, *genes.tolist(), goal]
            total = 0.0
            for a, b in itertools.pairwise(points):
                d = segment_cost(a, b)
                if d >= INF:
                    total = float(INF)
                    break
                total += d
            costs[i] = total
        return costs

    best, best_c, evaluations = None, float(INF), 0
    costs = evaluate(pop)
    evaluations += n
    for generation in range(params.generations + 1):
        i = int(np.argmin(costs))
        if costs[i] < best_c:
            best, best_c = pop[i].copy(), float(costs[i])
        if generation == params.generations:
            break
        # Roulette wheel, share 1/c (c > 0: the start is not the goal, every step costs).
        share = np.where(costs < INF, 1.0 / np.maximum(costs, 1e-9), 0.0)
        total = share.sum()
        p = share / total if total > 0 else np.full(n, 1.0 / n)
        parents = pop[rng.choice(n, size=n, p=p)]
        children = parents.copy()
        for j in range(0, n - 1, 2):
            # With one gene a cut inside the genes does not exist: crossing would only swap
            # the two parents, so the draw is made (the stream stays the same) and no more.
            if rng.random() < params.crossover_rate and m > 1:
                cut = int(rng.integers(1, m))  # genes [cut:] swap: one point, inside the genes
                children[j, cut:], children[j + 1, cut:] = parents[j + 1, cut:], parents[j, cut:]
        for j in range(n):
            for gene in range(m):
                if rng.random() < params.mutation_rate:
                    fresh = pool[int(rng.integers(0, pool.size))]
                    if fresh not in children[j] and fresh not in (start, goal):
                        children[j, gene] = fresh
        pop = children
        costs = evaluate(pop)
        evaluations += n
    return best, best_c, evaluations


def _ends_ok(seg: Segments, start: Cell, goal: Cell) -> bool:
    h, w = seg.shape
    inside = all(0 <= c[0] < h and 0 <= c[1] < w for c in (start, goal))
    return inside and not seg.blk[seg.padded(start)] and not seg.blk[seg.padded(goal)]


def _no_path(t0: float, seg: Segments, evaluations: int = 0) -> GaResult:
    return GaResult(_EMPTY, int(INF), float(INF), _EMPTY, evaluations, seg.searches,
                    seg.expanded, seg.max_open, (time.perf_counter() - t0) * 1e3)  # fmt: skip


def _reach(
    seg: Segments, start: Cell, goal: Cell, t0: float
) -> GaResult | tuple[int, int, np.ndarray]:
    """What both GAs check first: the answer when there is nothing to evolve (an end outside
    or blocked, the goal cut off: no path; start at the goal: itself), else the padded ends and
    the mask of cells reachable from the start (where waypoints are drawn)."""
    if not _ends_ok(seg, start, goal):
        return _no_path(t0, seg)
    s, g = seg.padded(start), seg.padded(goal)
    if s == g:
        one = np.array([start], dtype=np.int32)
        return GaResult(one, 0, 0.0, _EMPTY, 0, 0, 0, 0, (time.perf_counter() - t0) * 1e3)
    mask = np.zeros(seg.blk.size, dtype=np.bool_)
    reachable(seg.blk, seg.off, s, mask)
    if not mask[g]:
        return _no_path(t0, seg)
    return s, g, mask


def evolve(
    blocked: np.ndarray,
    start: Cell,
    goal: Cell,
    params: GaParams,
    segments: Segments | None = None,
    carried: list[Cell] | None = None,
) -> GaResult:
    """GA+A* (Algorithms 1-2) from ``start`` to ``goal`` on ``blocked`` (``bool``, (h, w)).

    No path (empty, INF) when an end is outside the map or blocked or the goal cannot be
    reached; ``[start]`` at cost 0 when start is the goal. ``carried``: ``waypoints`` cells
    that enter the initial population as one chromosome (the planner carries its last route
    over a reroute); ignored unless every one is reachable from ``start``."""
    t0 = time.perf_counter()
    seg = segments or Segments()
    seg.load(blocked)
    start, goal = (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1]))
    ends = _reach(seg, start, goal, t0)
    if isinstance(ends, GaResult):
        return ends
    s, g, mask = ends
    pool = np.flatnonzero(mask)
    genes = None
    if carried is not None and len(carried) == params.waypoints:
        genes = np.array([seg.padded(c) for c in carried], dtype=np.int64)
        inside = all(0 <= c[0] < seg.shape[0] and 0 <= c[1] < seg.shape[1] for c in carried)
        if not (inside and mask[genes].all()):
            genes = None
    rng = _rng(params, start, goal)
    best, best_c, evaluations = _run(rng, params, s, g, pool, seg.cost, genes)
    if best is None:
        return _no_path(t0, seg, evaluations)
    points = [s, *best.tolist(), g]
    joined = [
        seg.path(a, b)[(1 if i else 0) :] for i, (a, b) in enumerate(itertools.pairwise(points))
    ]
    cells = cut_loops(np.concatenate(joined))
    path = np.stack((cells // seg.width - 1, cells % seg.width - 1), axis=1).astype(np.int32)
    return GaResult(
        path, path_cost(path), best_c, _waypoints(seg, best), evaluations, seg.searches,
        seg.expanded, seg.max_open, (time.perf_counter() - t0) * 1e3,
    )  # fmt: skip


def evolve_straight(blocked: np.ndarray, start: Cell, goal: Cell, params: GaParams) -> GaResult:
    """GA alone: straight, feasible segments between the waypoints (module docstring).

    Waypoints are drawn from the start's component as for ``evolve``; no A* is run."""
    t0 = time.perf_counter()
    seg = Segments()
    seg.load(blocked)
    free = ~np.asarray(blocked, dtype=bool)
    start, goal = (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1]))
    ends = _reach(seg, start, goal, t0)
    if isinstance(ends, GaResult):
        return ends
    s, g, mask = ends
    memo: dict[tuple[int, int], float] = {}

    def euclid_if_free(a: int, b: int) -> float:
        hit = memo.get((a, b))
        if hit is None:
            line = straight_line(seg.cell(a), seg.cell(b))
            if free[line[:, 0], line[:, 1]].all():
                ra, ca = seg.cell(a)
                rb, cb = seg.cell(b)
                hit = 10.0 * float(np.hypot(ra - rb, ca - cb))  # Eq. 4, in the grid's 10 units
            else:
                hit = float(INF)
            memo[(a, b)] = hit
        return hit

    pool = np.flatnonzero(mask)
    best, best_c, evaluations = _run(_rng(params, start, goal), params, s, g, pool, euclid_if_free)
    if best is None or best_c >= INF:
        return _no_path(t0, seg, evaluations)
    points = [seg.cell(v) for v in [s, *best.tolist(), g]]
    joined = [
        straight_line(a, b)[(1 if i else 0) :]
        for i, (a, b) in enumerate(itertools.pairwise(points))
    ]
    flat = np.concatenate(joined).astype(np.int64)
    cells = cut_loops(flat[:, 0] * seg.shape[1] + flat[:, 1])
    path = np.stack(np.divmod(cells, seg.shape[1]), axis=1).astype(np.int32)
    return GaResult(
        path, path_cost(path), best_c, _waypoints(seg, best), evaluations, 0, 0, 0,
        (time.perf_counter() - t0) * 1e3,
    )  # fmt: skip


def _waypoints(seg: Segments, genes: np.ndarray) -> np.ndarray:
    return np.array([seg.cell(int(v)) for v in genes], dtype=np.int32).reshape(-1, 2)
