"""Harmonic fields measured: the replanning step beside EDS on the same walk, and where the
paper's potential goes flat (grid size x float type).

``replan_rows``: the benchmark's walk (``walk.walk``, the daemon's navigator on the courtyard)
with ``harmonic`` and with ``eds`` on one backend; per row the median / p99 / max of the
replanning step (``step_ms``: the planner's repair + path read, wall clock, device
synchronisation included), sweeps per step and the first plan.

``plateau_rows``: the converged field of each map (log space, float64 on the CPU up to 400²,
the device's float32 above), then the same field stored as the paper's ``u`` and as ``1 − u``
in float32 and float64: a reachable cell with no strictly lower neighbour is a cell the
descent stops on. Storing the exact solution is the best any relaxation of that form can do
(a relaxation in that type also has to get there), so a plateau counted here is one the
paper's form cannot avoid. ``w`` itself is counted the same way.

Run: ``python -m sim.harmonic_bench replan --backend cuda --grid 400,2000 --json out.json``,
``python -m sim.harmonic_bench plateau --backend cuda --grid 100,400,2000 --json out.json``.
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from collections.abc import Callable

import numpy as np

from daemon.planning import make_planner
from daemon.planning.harmonic import relax as rx

from .courtyard import dilate
from .numba_loads import numba_signatures
from .scenarios import make_scenario
from .walk import paper_settings, walk


def _pcts(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"median": None, "p99": None, "max": None}
    return {"median": round(float(np.median(values)), 4),
            "p99": round(float(np.percentile(values, 99)), 4),
            "max": round(float(values.max()), 4)}  # fmt: skip


def _navigator(scenario, name: str, backend: str, step: str = "", smooth: bool = False):
    """The walk's navigator; ``step`` sets the harmonic planner's replanning stop: ``full``
    relaxes every step to the tolerance, a number N stops after N sweeps on a field without
    a pit, ``N/M`` also fills the pits' basins after M sweeps, not the planner's 20 ("": the
    planner's default); ``smooth`` asks guidance for the planner's smoothing model."""
    from daemon.guidance.guide import Guidance
    from daemon.navigation import Navigator

    settings = paper_settings(scenario, name, backend, "fast")
    factory = None
    if name == "harmonic" and step:
        from daemon.planning.harmonic import make_harmonic

        def factory(b: str):
            planner = make_harmonic(b)
            sweeps, _, cap = step.partition("/")
            planner.step_sweeps = None if step == "full" else int(sweeps)
            planner.step_cap = int(cap) if cap else planner.step_cap
            return planner

    guidance = Guidance(cell_m=settings.cell_m, radius_m=settings.user_radius_m,
                        arrive_m=settings.arrive_m, smooth=smooth)  # fmt: skip
    return Navigator("walk", settings, guidance=guidance, planner_factory=factory)


def replan_rows(grids: list[int], backend: str, max_steps: int | None, unknown: float = 0.4,
                planners: tuple[str, ...] = ("harmonic", "eds"),
                steps: tuple[str, ...] = ("",),
                overlap: bool | None = None) -> list[dict]:  # fmt: skip
    """``steps``: the harmonic planner's replanning stops to measure in turn (``_navigator``).
    Each row's ``residual`` is the field's after each step (what an early stop left).
    ``overlap``: the harmonic planner's ``overlap`` (None: its own, on for the CUDA engine);
    False, it never starts a relaxation before its reach search ends."""
    from daemon.navigation.warm import warm_up

    for name in planners:
        # As the daemon does before READY: every compiled path (a fill, a whole-map reach
        # search) loaded once, not on the first walk step that needs it.
        warm_up(name, backend)
    rows = []
    for grid in grids:
        scenario = make_scenario("courtyard", grid, unknown, 0)
        runs = [(n, k) for n in planners for k in (steps if n == "harmonic" else ("",))]
        for name, step in runs:
            nav = _navigator(scenario, name, backend, step)
            walk(scenario, backend=backend, mode=name, max_steps=3, navigator=nav)  # warm
            t0 = time.perf_counter()
            nav = _navigator(scenario, name, backend, step)
            if overlap is not None and hasattr(nav.route.planner, "overlap"):
                nav.route.planner.overlap = overlap
            residuals: list[float] = []
            filled: list[int] = []
            passes: list[int] = []
            searches: list[int] = []
            cuts: list[int] = []
            faults: list[int] = []
            loaded: list[list[str]] = []
            off_cpu: list[float] = []

            def note(n_faults: int, new: list[str], off_ms: float, nav=nav,
                     residuals=residuals, filled=filled, passes=passes, searches=searches,
                     cuts=cuts, faults=faults, loaded=loaded, off_cpu=off_cpu) -> None:  # fmt: skip
                faults.append(n_faults)
                loaded.append(new)
                off_cpu.append(off_ms)
                planner = nav.route.planner
                residuals.append(float(getattr(planner, "residual", 0.0)))
                filled.append(int(getattr(planner, "filled", 0)))
                passes.append(int(getattr(getattr(planner, "engine", None), "fill_passes", 0)))
                reach = getattr(planner, "reach", None)
                searches.append(int(getattr(reach, "full_searches", 0)))
                cuts.append(int(getattr(reach, "cut_searches", 0)))

            _watch_reads(nav.route, note)
            r = walk(scenario, backend=backend, mode=name, max_steps=max_steps, navigator=nav)
            changed = r.changed > 0
            skip = len(loaded) - len(r.changed)  # the plan's read: no step of the trace
            rows.append({
                "planner": name, "step": step or "default", "backend": backend,
                "grid": grid, "unknown": unknown,
                "arrived": r.arrived, "reason": r.reason, "steps": int(r.steps),
                "walked_m": round(r.walked_m, 2), "init_ms": round(float(r.init_ms), 2),
                "step_ms": _pcts(r.step_ms), "step_ms_changed": _pcts(r.step_ms[changed]),
                "sweeps": _pcts(r.iterations.astype(float)),
                "residual": _pcts(np.array(residuals)),
                # Steps that ended with a fill, and the basin cells each filled (every path
                # read of the navigator, the plan included).
                "fills": int(np.count_nonzero(filled)), "filled": _pcts(np.array(filled, float)),
                # The device fill's passes on the steps that ran one (cuda).
                "fill_passes": _pcts(np.array([p for p in passes if p], float)),
                # The steps (indices into trace) whose reach needed the whole-map search.
                "full_searches": _new_searches(searches, len(r.changed)),
                # ... and those whose cut-off cells were found from the change (cut_off.cut_off).
                "cut_searches": _new_searches(cuts, len(r.changed)),
                # Each step's minor page faults inside its replanning step (fresh pages the
                # kernel mapped and zeroed, ~µs each): where a large step's time went.
                "plan_faults": faults[skip:],
                # The steps whose read compiled or loaded a numba function of the product
                # (after the warm-up, none should): {step: names}.
                "loaded": {str(i - skip): new for i, new in enumerate(loaded)
                           if new and i >= skip},
                # Each step's wall time off the CPU (wall clock less the thread's CPU time):
                # a step slow for want of the CPU, not for more work (the host's other load).
                "off_cpu_ms": [round(x, 3) for x in off_cpu[skip:]],
                "wall_s": round(time.perf_counter() - t0, 1),
                # Steps whose relaxation ran beside the host's search and stood, and those
                # undone (cells cut off).
                "overlap": bool(getattr(nav.route.planner, "overlap", False)),
                "overlaps": int(getattr(nav.route.planner, "overlaps", 0)),
                "undone": int(getattr(nav.route.planner, "undone", 0)),
                # Each step's flipped cells, sweeps and ms: which changes cost the tail.
                "trace": [[int(c), int(i), round(float(m), 3)] for c, i, m
                          in zip(r.changed, r.iterations, r.step_ms, strict=True)],
            })  # fmt: skip
    return rows


def _watch_reads(route, note: Callable[[int, list[str], float], None]) -> None:
    """Wrap ``route``'s path read (one a navigator step that plans or replans: the plan, then
    one per entry of the walk's trace) to call ``note`` after each with what happened inside
    it: the minor page faults, the numba functions that compiled or loaded (``numba_signatures``
    grew), and the ms its thread was off the CPU (wall clock less ``time.thread_time``). The
    counting is outside the window of ``step_ms``. Per read, not per walk step: the walk's
    ``on_step`` does not follow its last step, so notes taken there put the plan's faults
    (25 k at 2000², H100) in step 0's slot and each step's in the next one's."""
    read = route.path_from
    seen = numba_signatures()

    def watched(*args, **kwargs):
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        wall, cpu = time.perf_counter(), time.thread_time()
        out = read(*args, **kwargs)
        cpu, wall = time.thread_time() - cpu, time.perf_counter() - wall
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
        now = numba_signatures()
        new = sorted(k for k, n in now.items() if n > seen.get(k, 0))
        seen.update(now)
        note(faults, new, max(0.0, wall - cpu) * 1e3)
        return out

    route.path_from = watched


def _new_searches(counts: list[int], steps: int) -> list[int]:
    """The walk steps whose reach ran the whole-map search, from the planner's running count
    after every path read (``counts``; the plan first, which the walk's trace of ``steps``
    leaves out)."""
    skip = len(counts) - steps
    return [i - skip for i in range(skip, len(counts)) if counts[i] > (counts[i - 1] if i else 0)]


def _timed(fn, n: int = 30) -> dict:
    fn()  # compile and warm
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return _pcts(np.array(times))


def band_rows(grids: list[int], backend: str, max_steps: int | None,
              unknown: float = 0.4) -> list[dict]:  # fmt: skip
    """The smoothing model's cost per guidance call: the harmonic walk with guidance smoothing
    by the planner's band (``guide_ms``, wall clock) and without, then the band alone on the
    known map's whole path from the start, on ``backend`` and in numba, 30 times each."""
    from daemon.planning.harmonic.rubber_band import rubber_band

    rows = []
    for grid in grids:
        scenario = make_scenario("courtyard", grid, unknown, 0)
        row: dict = {"grid": grid, "backend": backend, "unknown": unknown}
        for smooth in (True, False):
            walk(scenario, backend=backend, mode="harmonic", max_steps=3,
                 navigator=_navigator(scenario, "harmonic", backend, "", smooth))  # fmt: skip
            nav = _navigator(scenario, "harmonic", backend, "", smooth)
            r = walk(scenario, backend=backend, mode="harmonic", max_steps=max_steps, navigator=nav)
            key = "smooth" if smooth else "plain"
            row[f"guide_ms_{key}"] = _pcts(r.guide_ms)
            row[f"arrived_{key}"], row[f"steps_{key}"] = r.arrived, int(r.steps)
        blocked = dilate(scenario.true == 1, scenario.radius_cells)
        planner = make_planner("harmonic", backend)
        planner.plan(blocked, scenario.goal)
        path = planner.path(scenario.start)
        field = planner.field()
        row["band_ms"] = _timed(lambda: planner.band(path, blocked))  # noqa: B023
        row["band_numba_ms"] = _timed(lambda: rubber_band(path, field, blocked))  # noqa: B023
        row["path_cells"] = len(path)
        rows.append(row)
    return rows


def _stuck(values: np.ndarray, width: int, reach: np.ndarray, goal: int) -> int:
    return int(rx.stuck_cells(values, width, reach, goal))


def plateau_row(blocked: np.ndarray, goal: tuple[int, int], backend: str, label: str) -> dict:
    planner = make_planner("harmonic", backend)
    t0 = time.perf_counter()
    stats = planner.plan(blocked, goal)
    h, w = blocked.shape
    width = w + 2
    wfield = np.full((h + 2, width), rx.BLOCKED_W)
    wfield[1:-1, 1:-1] = planner.field()
    flat = wfield.reshape(-1)
    reach = np.where(planner.reach.reach, 1, -1).astype(np.int64)
    g = (goal[0] + 1) * width + goal[1] + 1
    finite = flat < rx.BLOCKED_W
    row = {"map": label, "grid": int(max(h, w)), "backend": backend,
           "cold_sweeps": stats.iterations, "cold_ms": round(stats.ms, 1),
           "reachable": int(planner.reach.count),
           "max_w": round(float(flat[finite].max()), 2),
           "plan_s": round(time.perf_counter() - t0, 2)}  # fmt: skip
    for dtype in (np.float32, np.float64):
        v = np.where(finite, np.exp(-np.minimum(flat, 800.0)), 0.0)
        # u stored: obstacles 1, the goal 0; 1 - u stored: obstacles 0, the goal 1 (negated so
        # that "lower" still means "towards the goal" for the count).
        u = np.where(finite, 1.0 - v, 1.0).astype(dtype)
        row[f"stuck_u_{dtype.__name__}"] = _stuck(u, width, reach, g)
        row[f"stuck_1mu_{dtype.__name__}"] = _stuck(-(v.astype(dtype)), width, reach, g)
        row[f"stuck_w_{dtype.__name__}"] = _stuck(flat.astype(dtype), width, reach, g)
    return row


def plateau_rows(grids: list[int], backend: str) -> list[dict]:
    rows = []
    for grid in grids:
        scenario = make_scenario("courtyard", grid, 0.4, 0)
        blocked = dilate(scenario.true == 1, scenario.radius_cells)
        rows.append(plateau_row(blocked, scenario.goal, backend, "courtyard"))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("what", choices=("replan", "plateau", "band"))
    parser.add_argument("--backend", default="cpu")
    parser.add_argument("--grid", default="100,400")
    parser.add_argument("--max-steps", type=int, default=None)
    parser.add_argument("--json", default=None)
    parser.add_argument("--steps", default="", help="replan: harmonic step stops, e.g. full,20")
    parser.add_argument(
        "--no-overlap", action="store_true", help="replan: relax only after the reach search"
    )
    a = parser.parse_args()
    grids = [int(x) for x in a.grid.split(",")]
    if a.what == "replan":
        rows = replan_rows(grids, a.backend, a.max_steps, steps=tuple(a.steps.split(",")),
                           overlap=False if a.no_overlap else None)  # fmt: skip
    elif a.what == "band":
        rows = band_rows(grids, a.backend, a.max_steps)
    else:
        rows = plateau_rows(grids, a.backend)
    text = json.dumps(rows, indent=1)
    print(text)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    print("\n".join(summary(rows)))


def summary(rows: list[dict]) -> list[str]:
    """One line a replanning row, printed after the JSON: the device check keeps only a log's
    tail, which the JSON's last trace fills (round 15's A/B figures were lost so). It ends
    with the steps that loaded compiled code and the longest time a step was off the CPU: what
    tells a slow step's own work from a first use or the host's other load."""
    lines = []
    for r in rows:
        if "step_ms" not in r or "planner" not in r:
            continue
        ms, trace = r["step_ms"], r.get("trace", [])
        top = sorted(trace, key=lambda t: -t[2])[:2]
        off = r.get("off_cpu_ms") or [0.0]
        worst = int(np.argmax(off))
        lines.append(f"{r['planner']} {r['grid']}² median {ms['median']} p99 {ms['p99']} "
                     f"max {ms['max']} total {sum(t[2] for t in trace):.2f} largest {top} "
                     f"full {r.get('full_searches')} cut {r.get('cut_searches')} "
                     f"early {r.get('overlaps', 0)} undone {r.get('undone', 0)} "
                     f"loaded {sorted(int(k) for k in r.get('loaded', {}))} "
                     f"off-cpu max {off[worst]} at {worst}")  # fmt: skip
    return lines


if __name__ == "__main__":
    main()
