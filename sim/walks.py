"""Walks that follow the belt (or the voice): the daemon's ``Navigator`` guides a walker.

The benchmark's walk (the paper's courtyard, or any scenario of ``scenarios.py``), but the user
is the ``BeltWalker``: it feels the pattern and steps
in continuous space with noise; it never sees the path. The loop is ``closed_loop.run_walk``:
each walker action (``STEP_S`` of simulated time) the sensor's delta and the walker's pose go
to the navigator, which inflates, repairs its field, reads the path (leading out of the
inflation margin itself when a newly seen obstacle grew over the walker) and makes the pattern
and the cue; the walker reacts. So these figures are the daemon's navigator, not a copy of it.

Measured per walk: arrived or not, walked metres against the optimal path on the fully known
map (8-connected, the planner's own metric), collisions, cues spoken, holds, steps. With
``follow="voice"`` the walker is the ``VoiceWalker`` (``voice_walker.py``), which hears the
navigator's cues and never feels the belt; its walks also give the longest silence between
cues, the gap a listener walks through on the last thing it was told.

Guidance lives in ``daemon.guidance`` (pydantic models), imported inside the functions so this
module still imports with numpy and numba only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.grid import INF, cell_to_xy
from daemon.planning.inflation import radius_in_cells

from .belt_walker import BeltWalker, WalkerParams
from .closed_loop import STEP_S, run_walk
from .courtyard import USER_RADIUS_M, Scenario, dilate
from .scenarios import check_grid, make_scenario
from .voice_walker import VoiceWalker, VoiceWalkerParams
from .world import World

FOLLOW = ("belt", "voice")
"""Who walks in ``walks``: the walker that feels the belt, or the one that hears the cues."""

if TYPE_CHECKING:
    from daemon.guidance.guide import Guidance
    from daemon.navigation import NavigatorSettings

@dataclass(frozen=True)
class BeltWalk:
    arrived: bool
    reason: str
    walked_m: float
    optimal_m: float
    collisions: int
    cues: int
    holds: int
    actions: int
    track: np.ndarray
    """``(n, 2)`` walker positions in metres (x, y), start first."""
    steps: int = 0
    """Steps the walker took (turns, bumps and standing not counted)."""
    longest_silence_s: float | None = None
    """Voice walks: the longest time between two cues heard (the walk's start and its
    "arrived" count as cues; the stall after the last cue of a walk that never arrives does
    not); None for belt walks, which the belt guides every step."""
    route_changes: int = 0
    """Steps whose route left the route the user was guided on (``closed_loop.route_departs``)."""
    reroutes_announced: int = 0
    """Of those, said in words that step or the next."""

    @property
    def length_ratio(self) -> float:
        return self.walked_m / self.optimal_m if self.optimal_m > 0 else math.nan


def optimal_m(scenario: Scenario) -> float:
    """Length of the shortest 8-connected path on the fully known, inflated true map."""
    blocked = dilate(scenario.true == 1, scenario.radius_cells)
    g = int(dijkstra_field(blocked, scenario.goal)[scenario.start])
    return math.inf if g >= INF else g / 10.0 * scenario.cell_m


def user_radius_m(scenario: Scenario) -> float:
    """The user's radius as the daemon's config gives it (0.3 m) when the scenario was inflated
    by it. Not ``radius_cells * cell_m``: at 0.2 m cells that is 0.4 m, and at 5 cm cells
    0.30000000000000004, and either lets guidance shave one cell more of the margin than the
    daemon configured for 0.3 m does (one walk in three bumps at 50², two in twenty at 200²)."""
    if radius_in_cells(USER_RADIUS_M, scenario.cell_m) == scenario.radius_cells:
        return USER_RADIUS_M
    return scenario.radius_cells * scenario.cell_m


def belt_settings(
    scenario: Scenario,
    backend: str = "cpu",
    lang: str = "en",
    planner: str = "eds",
    voice: str = "companion",
) -> NavigatorSettings:
    """The navigator as the daemon runs it, at the scenario's cell size and user radius."""
    from daemon.navigation import NavigatorSettings

    return NavigatorSettings(
        planner=planner,
        backend=backend,
        cell_m=scenario.cell_m,
        user_radius_m=user_radius_m(scenario),
        lang=lang,
        voice=voice,  # type: ignore[arg-type]
    )


def belt_walk(
    scenario: Scenario,
    *,
    seed: int = 0,
    backend: str = "cpu",
    params: WalkerParams | None = None,
    smooth: bool = False,
    lang: str = "en",
    max_actions: int | None = None,
    guidance: Guidance | None = None,
    planner: str = "eds",
    follow: str = "belt",
    voice_params: VoiceWalkerParams | None = None,
) -> BeltWalk:
    """One walk of ``scenario`` by a belt walker (or, ``follow="voice"``, a voice walker with
    ``voice_params``) with noise seeded by ``seed``.

    ``guidance`` replaces the navigator's own (a hold policy, say); ``smooth`` asks for the
    rubber band in the navigator's default guidance.
    """
    if follow not in FOLLOW:
        raise ValueError(f"follow {follow!r}: choose one of {', '.join(FOLLOW)}")
    from daemon.guidance.guide import Guidance
    from daemon.navigation import Navigator

    # A walker who only hears is guided by a voice that guides alone, as its user would set.
    voice = "sole" if follow == "voice" else "companion"
    settings = belt_settings(scenario, backend, lang, planner, voice)
    if guidance is None and smooth:
        guidance = Guidance(
            cell_m=settings.cell_m, lang=settings.lang, radius_m=settings.user_radius_m,
            arrive_m=settings.arrive_m, smooth=True,
        )  # fmt: skip
    navigator = Navigator("walker", settings, guidance=guidance)
    x, y = cell_to_xy(scenario.shape, scenario.start, scenario.cell_m)
    walker: BeltWalker | VoiceWalker
    if follow == "voice":
        walker = VoiceWalker(
            x=x, y=y, heading=math.pi / 2, cell_m=scenario.cell_m,
            params=voice_params or VoiceWalkerParams(), rng=np.random.default_rng(seed),
        )  # fmt: skip
    else:
        walker = BeltWalker(
            x=x, y=y, heading=math.pi / 2, cell_m=scenario.cell_m,
            params=params or WalkerParams(), rng=np.random.default_rng(seed),
        )  # fmt: skip
    best = optimal_m(scenario)
    limit = max_actions or int(6 * best / walker.params.step_m) + 100
    # A walker with no path stands and waits (stop_on_no_path=False): it may find one again.
    done = run_walk(World(scenario, walker), navigator, max_actions=limit, step_s=STEP_S,
                    stop_on_no_path=False)  # fmt: skip
    silence = None
    if isinstance(walker, VoiceWalker):
        end = (len(done.track) - 1) * STEP_S if done.arrived else None
        silence = walker.longest_silence_s(0.0, end=end)
    return BeltWalk(
        arrived=done.arrived,
        reason=done.reason,
        walked_m=walker.walked_m,
        optimal_m=best,
        collisions=walker.collisions,
        cues=done.cues,
        holds=navigator.guidance.hold.holds,
        actions=len(done.track) - 1,
        track=np.array(done.track, dtype=np.float64),
        steps=walker.steps,
        longest_silence_s=silence,
        route_changes=done.route_changes,
        reroutes_announced=done.reroutes_announced,
    )


def _one(task: tuple) -> tuple:
    """One walk as ``(grid, unknown, arrived, ratio, collisions, cues, holds, steps,
    longest silence, route changes, announced)``: a plain tuple, so it crosses process
    boundaries cheaply."""
    name, grid, unknown, seed, backend, smooth, params, planner, follow, voice_params = task
    w = belt_walk(make_scenario(name, grid, unknown, seed), seed=seed, backend=backend,
                  smooth=smooth, params=params, planner=planner, follow=follow,
                  voice_params=voice_params)  # fmt: skip
    return (grid, unknown, w.arrived, w.length_ratio, w.collisions, w.cues, w.holds, w.steps,
            w.longest_silence_s, w.route_changes, w.reroutes_announced)  # fmt: skip


def summarise(grid: int, unknown: float, results: list[tuple], scenario: str = "courtyard") -> dict:
    """One JSON row from the per-walk tuples of ``_one``."""
    arrived = [r for r in results if r[2]]
    ratios = np.array([r[3] for r in arrived])
    return {
        "scenario": scenario,
        "grid": grid,
        "unknown": unknown,
        "runs": len(results),
        "success_rate": round(len(arrived) / len(results), 4),
        "length_ratio": round(float(ratios.mean()), 4) if ratios.size else None,
        "length_ratio_max": round(float(ratios.max()), 4) if ratios.size else None,
        "collisions": int(sum(r[4] for r in results)),
        "cues_per_walk": round(float(np.mean([r[5] for r in results])), 2),
        "holds": int(sum(r[6] for r in results)),
        "steps_per_walk": round(float(np.mean([r[7] for r in results])), 1),
        **_silences([r[8] for r in results]),
        # Route changes, and walks where every one was announced within a step of it.
        "route_changes": int(sum(r[9] for r in results)),
        "reroutes_announced": int(sum(r[10] for r in results)),
        "walks_with_changes": int(sum(r[9] > 0 for r in results)),
        "walks_all_announced": int(sum(r[9] > 0 and r[10] == r[9] for r in results)),
    }


def _silences(longest: list[float | None]) -> dict:
    """Mean and worst of the walks' longest silences (voice rows only: a belt row has none)."""
    values = [s for s in longest if s is not None]
    if not values:
        return {}
    return {
        "longest_silence_s": round(float(np.mean(values)), 1),
        "longest_silence_max_s": round(float(max(values)), 1),
    }


def run_table(
    grids: list[int],
    unknowns: list[float],
    runs: int,
    *,
    backend: str = "cpu",
    smooth: bool = False,
    first_seed: int = 0,
    jobs: int = 1,
    params: WalkerParams | None = None,
    planner: str = "eds",
    on_row: Callable[[dict], None] | None = None,
    scenarios: list[str] | None = None,
    follow: str = "belt",
    voice_params: VoiceWalkerParams | None = None,
) -> list[dict]:
    """``runs`` seeded walks (seed i: the world and the walker's noise) per scenario
    (default the courtyard), grid and density; one row each. ``jobs`` > 1 spreads the walks
    over processes. A bad scenario, grid or ``follow`` is refused before the first walk."""
    if follow not in FOLLOW:
        raise ValueError(f"follow {follow!r}: choose one of {', '.join(FOLLOW)}")
    scenarios = scenarios or ["courtyard"]
    for name in scenarios:
        for grid in grids:
            check_grid(name, grid)
    rows = []
    pool = None
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(jobs)
    try:
        for name, grid, unknown in [(n, g, u) for n in scenarios for g in grids for u in unknowns]:
            tasks = [
                (name, grid, unknown, first_seed + i, backend, smooth, params, planner,
                 follow, voice_params)
                for i in range(runs)
            ]
            results = list(pool.map(_one, tasks) if pool else map(_one, tasks))
            rows.append({**summarise(grid, unknown, results, name), "follow": follow})
            if on_row is not None:
                on_row(rows[-1])
    finally:
        if pool is not None:
            pool.shutdown()
    return rows
