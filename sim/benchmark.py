"""The paper's benchmark: closed-loop walks over scenarios x grids x unknown fractions.

For every scenario (``scenarios.py``: the paper's courtyard by default), grid side and unknown
fraction one seeded world is walked with each planner (``repeats`` times) by the daemon's own
``Navigator`` (``walk.py``); a row per (scenario, grid, unknown, mode) holds Steps and
Iter_avg (the paper's Table 1) and the milliseconds per replanning step (its Table 2: repair
plus the path from the user's cell, wall clock) with its median, p95, p99, max and the whole
walk's total — a user feels the slowest step — and the navigator's whole step (map, planner,
guidance) beside it. The per-step times feed a Figure 9-like plot.

matplotlib is imported only to plot.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from daemon.navigation.warm import warm_up as warm_navigator
from daemon.planning import resolve_backend
from daemon.runtime import gc_policy

from .courtyard import make_courtyard
from .scenarios import SCENARIOS, check_grid, make_scenario, scenario_list
from .walk import MODES, walk

ROW_FIELDS = (
    "scenario", "grid", "unknown", "backend", "variant", "mode", "steps", "iter_avg",
    "ms_median", "ms_mean", "ms_p95", "ms_p99", "ms_max", "walk_ms",
    "nav_ms_median", "nav_ms_p99", "nav_ms_max", "inflate_ms_median", "idle_walk_ms", "device",
)  # fmt: skip
"""The documented fields of every JSON row (rows carry a few more, see ``run_bench``)."""


@dataclass
class BenchConfig:
    grids: list[int]
    unknowns: list[float]
    scenarios: list[str] = field(default_factory=lambda: ["courtyard"])
    """Names of ``sim.scenarios.SCENARIOS``; each is walked at every grid and fraction."""
    backend: str = "cpu"
    variant: str = "fast"
    modes: list[str] = field(default_factory=lambda: ["eds", "dss"])
    seed: int = 0
    repeats: int = 1
    fov_deg: float = 80.0
    max_steps: int | None = None
    """Stop each walk after this many steps (big grids within a time limit); rows say so."""

    def total_walks(self) -> int:
        cells = len(self.scenarios) * len(self.grids) * len(self.unknowns)
        return cells * len(self.modes) * self.repeats

    def check(self) -> None:
        """ValueError for a scenario not known or a grid it cannot be drawn at, before any walk."""
        if not self.scenarios:
            raise ValueError("no scenario to walk")
        for name in self.scenarios:
            for grid in self.grids:
                check_grid(name, grid)


@dataclass
class BenchResult:
    rows: list[dict]
    series: dict[tuple[str, int, float, str], np.ndarray]
    """Per-step ms along the walk (median over repeats) for each (scenario, grid, unknown,
    mode)."""
    device: str


def device_name(backend: str) -> str:
    """The GPU's name for cuda, else the CPU model and how many cores this process may use."""
    if backend == "cuda":
        import cupy

        props = cupy.cuda.runtime.getDeviceProperties(cupy.cuda.Device().id)
        name = props["name"]
        return name.decode() if isinstance(name, bytes) else str(name)
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{model}, {cores} cores"


def settle_heap() -> None:
    """Collect, then freeze what exists, as the daemon does once it is ready: a walk's steps
    then never wait for a full collection of the objects built before it (measured: one
    28 ms gen-2 pause in a 400² walk otherwise). The walk's own steps run under the daemon's
    collector policy (``gc_policy.after_step`` in ``closed_loop``)."""
    gc_policy.settle()


def warm_up(backend: str, variant: str, modes: list[str]) -> None:
    """Compile kernels and JIT code so no timed step pays for it: the daemon's own warm-up
    (every planner and guidance entry point), then a tiny walk for the simulator's side."""
    scenario = make_courtyard(grid=50, unknown=0.2, seed=0)
    for mode in modes:
        warm_navigator(mode, backend, variant)
        walk(scenario, backend=backend, variant=variant, mode=mode, max_steps=3)


def run_bench(
    config: BenchConfig,
    on_walk: Callable[[str], None] | None = None,
    on_start: Callable[[str], None] | None = None,
) -> BenchResult:
    """Walk every (scenario, grid, unknown, mode) ``repeats`` times; a row for each."""
    config.check()
    backend = resolve_backend(config.backend)
    device = device_name(backend)
    if on_start is not None:
        on_start("warming up")
    warm_up(backend, config.variant, config.modes)
    rows: list[dict] = []
    series: dict[tuple[str, int, float, str], np.ndarray] = {}
    cells = [(n, g, u) for n in config.scenarios for g in config.grids for u in config.unknowns]
    for name, grid, unknown in cells:
        scenario = make_scenario(name, grid, unknown, config.seed)
        walked: dict[str, np.ndarray] = {}
        for mode in config.modes:
            label = f"{name} {grid}x{grid} {unknown:.0%} {mode.upper()}"
            runs = []
            for _ in range(config.repeats):
                if on_start is not None:
                    on_start(label)
                settle_heap()
                runs.append(walk(scenario, backend=backend, variant=config.variant, mode=mode,
                                 fov_deg=config.fov_deg, max_steps=config.max_steps))  # fmt: skip
                if on_walk is not None:
                    on_walk(label)
            first = runs[0]
            walked[mode] = first.walked
            step_ms = np.concatenate([r.step_ms for r in runs])
            series[(name, grid, unknown, mode)] = np.median(
                np.stack([r.step_ms for r in runs]), axis=0
            )
            rows.append({
                "scenario": name,
                "grid": grid,
                "unknown": unknown,
                "coverage": round(scenario.coverage, 4),
                "seed": config.seed,
                "backend": backend,
                "variant": config.variant,
                "mode": mode,
                "planner": first.planner,
                "steps": first.steps,
                "arrived": first.arrived,
                "capped": config.max_steps is not None and first.reason == "step limit",
                "max_steps": config.max_steps,
                "iter_avg": float(first.iterations.mean()) if first.steps else 0.0,
                "touched_avg": float(first.cells_touched.mean()) if first.steps else 0.0,
                "ms_mean": float(np.mean(step_ms)) if step_ms.size else 0.0,
                **spread("ms", step_ms),
                "walk_ms": float(np.median([r.step_ms.sum() for r in runs])),
                **spread("nav_ms", np.concatenate([r.nav_ms for r in runs])),
                "nav_walk_ms": float(np.median([r.nav_ms.sum() for r in runs])),
                # What the planner left for after the steps (not in any step's time, nor in
                # walk_ms): the user waits for none of it, the device still does it.
                "idle_walk_ms": float(np.median([r.idle_ms.sum() for r in runs])),
                "idle_ms_max": float(max(r.idle_ms.max(initial=0.0) for r in runs)),
                "plan_ms_median": float(np.median(np.concatenate([r.plan_ms for r in runs]))),
                "inflate_ms_median": float(
                    np.median(np.concatenate([r.inflate_ms for r in runs]))
                ),
                "guide_ms_median": float(np.median(np.concatenate([r.guide_ms for r in runs]))),
                "init_ms": float(np.median([r.init_ms for r in runs])),
                # A*'s open list (issue 22); -1 for a planner that keeps a field.
                "max_open": int(first.max_open.max(initial=-1)),
                "max_open_median": float(np.median(first.max_open)) if first.steps else -1.0,
                "repeats": config.repeats,
                "fov_deg": config.fov_deg,
                "device": device,
            })
        if "eds" in walked and "dss" in walked:  # the same field: the same cells
            same = bool(np.array_equal(walked["eds"], walked["dss"]))
            for row in rows[-len(walked) :]:
                if row["mode"] in ("eds", "dss"):
                    row["same_walk"] = same
    return BenchResult(rows=rows, series=series, device=device)


def spread(prefix: str, ms: np.ndarray) -> dict[str, float]:
    """Median, p95, p99 and max of per-step times, keyed ``<prefix>_median`` etc."""
    if not ms.size:
        return {f"{prefix}_{k}": 0.0 for k in ("median", "p95", "p99", "max")}
    return {
        f"{prefix}_median": float(np.median(ms)),
        f"{prefix}_p95": float(np.percentile(ms, 95)),
        f"{prefix}_p99": float(np.percentile(ms, 99)),
        f"{prefix}_max": float(ms.max()),
    }


def table_rows(rows: list[dict]) -> tuple[list[list[str]], list[list[str]]]:
    """The paper's two tables as text cells, one line per (scenario, grid, unknown).

    Table 1: Steps and Iter_avg for DSS and EDS. Table 2: ms per replanning step (median,
    p99, max, and the walk's total) for DSS and EDS, and the DSS/EDS ratio of medians.
    Rows written before scenarios existed are the courtyard's.
    """
    by_key: dict[tuple[str, int, float], dict[str, dict]] = {}
    for row in rows:
        key = (row.get("scenario", "courtyard"), row["grid"], row["unknown"])
        by_key.setdefault(key, {})[row["mode"]] = row
    t1: list[list[str]] = []
    t2: list[list[str]] = []
    for (name, grid, unknown), modes in by_key.items():
        head = [name, f"{grid}", f"{unknown:.0%}"]
        cells1, cells2 = list(head), list(head)
        for mode in ("dss", "eds"):
            r = modes.get(mode)
            if r is None:
                cells1 += ["-", "-"]
                cells2 += ["-", "-", "-", "-"]
                continue
            steps = f"{r['steps']}" + ("" if r["arrived"] else " (not arrived)")
            if r.get("capped"):
                steps = f"{r['steps']} (capped)"
            cells1 += [steps, f"{r['iter_avg']:.1f}"]
            cells2 += [f"{r[k]:.3f}" for k in ("ms_median", "ms_p99", "ms_max")]
            cells2.append(f"{r['walk_ms']:.0f}")
        if "dss" in modes and "eds" in modes and modes["eds"]["ms_median"] > 0:
            cells2.append(f"{modes['dss']['ms_median'] / modes['eds']['ms_median']:.1f}x")
        else:
            cells2.append("-")
        t1.append(cells1)
        t2.append(cells2)
    return t1, t2


TABLE1_HEADS = ("scenario", "grid", "unknown", "DSS steps", "DSS Iter_avg", "EDS steps",
                "EDS Iter_avg")  # fmt: skip
TABLE2_HEADS = ("scenario", "grid", "unknown", "DSS med", "DSS p99", "DSS max", "DSS walk",
                "EDS med", "EDS p99", "EDS max", "EDS walk", "DSS/EDS")  # fmt: skip
"""Column heads of ``table_rows``'s two tables, for whoever prints them."""


PLANNER_HEADS = ("scenario", "grid", "unknown", "planner", "steps", "Iter_avg", "median",
                 "p99", "max", "walk", "open max")  # fmt: skip


def planner_rows(rows: list[dict]) -> list[list[str]]:
    """One line per (scenario, grid, unknown, planner), in the rows' order: Steps, Iter_avg and
    the ms per replanning step (median, p99, max, the walk's total) and the largest open list of a
    searching planner (A*; ``-`` for a field) — every planner, not only the paper's two
    (``table_rows``)."""
    out = []
    for r in rows:
        steps = f"{r['steps']}" + ("" if r["arrived"] else " (not arrived)")
        if r.get("capped"):
            steps = f"{r['steps']} (capped)"
        out.append([r.get("scenario", "courtyard"), f"{r['grid']}", f"{r['unknown']:.0%}",
                    r["mode"], steps, f"{r['iter_avg']:.1f}", *(f"{r[k]:.3f}" for k in
                    ("ms_median", "ms_p99", "ms_max")), f"{r['walk_ms']:.0f}",
                    f"{r['max_open']}" if r.get("max_open", -1) >= 0 else "-"])  # fmt: skip
    return out


def plot_steps(result: BenchResult, out: Path | str) -> Path:
    """Time per replanning step along each walk, DSS against EDS (like the paper's Figure 9)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys((k[0], k[1]) for k in result.series))  # (scenario, grid)
    unknowns = sorted({k[2] for k in result.series})
    fig, axes = plt.subplots(
        len(panels), len(unknowns), figsize=(4.2 * len(unknowns), 3.0 * len(panels)),
        squeeze=False, sharex="row",
    )  # fmt: skip
    colours = {"dss": (0.85, 0.3, 0.1), "eds": (0.1, 0.35, 0.9)}
    for i, (name, grid) in enumerate(panels):
        for j, unknown in enumerate(unknowns):
            ax = axes[i][j]
            for mode in ("dss", "eds"):
                ms = result.series.get((name, grid, unknown, mode))
                if ms is not None and ms.size:
                    ax.plot(np.arange(1, ms.size + 1), ms, color=colours[mode], linewidth=0.9,
                            label=f"{mode.upper()} (median {np.median(ms):.3g} ms)")
            ax.set_yscale("log")
            ax.set_title(f"{name} {grid}x{grid}, {unknown:.0%} unknown", fontsize=9)
            ax.set_xlabel("step")
            ax.set_ylabel("ms per replanning step")
            ax.legend(fontsize=7)
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"Time per step along the walk — {result.device}", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / fig.get_figheight()))  # room for the title
    out = Path(out)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def format_tables(rows: list[dict]) -> str:
    """Both tables as plain text, for machines without rich."""
    t1, t2 = table_rows(rows)
    out = []
    tables = [
        ("Steps and Iter_avg", TABLE1_HEADS, t1),
        ("ms per replanning step", TABLE2_HEADS, t2),
    ]
    if any(row["mode"] not in ("eds", "dss") for row in rows):
        tables.append(("ms per replanning step, by planner", PLANNER_HEADS, planner_rows(rows)))
    for title, heads, body in tables:
        widths = [max(len(h), *(len(r[i]) for r in body)) for i, h in enumerate(heads)]
        out.append(title)
        for line in (heads, *body):
            out.append("  ".join(c.rjust(w) for c, w in zip(line, widths, strict=True)))
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    """``python -m sim.benchmark``: the same benchmark with only numpy and argparse.

    For machines that lack typer and its pydantic dependency (the lent GPU machine); the
    options mirror ``guidebelt bench``.
    """
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m sim.benchmark", description=main.__doc__)
    p.add_argument("--scenario", default="courtyard", help=", ".join(SCENARIOS))
    p.add_argument("--grid", default="100,200,400")
    p.add_argument("--unknown", default="0.2,0.4,0.6")
    p.add_argument("--backend", default="cpu")
    p.add_argument("--variant", default="fast")
    p.add_argument("--modes", default="eds,dss")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--fov", type=float, default=80.0)
    p.add_argument("--max-steps", type=int, default=None)
    p.add_argument("--json", dest="json_out", type=Path)
    p.add_argument("--plot", type=Path)
    a = p.parse_args(argv)
    modes = [m for m in a.modes.split(",") if m]
    if not modes or any(m not in MODES for m in modes):
        p.error(f"--modes {a.modes!r}: choose from {', '.join(MODES)}")
    try:
        scenarios = scenario_list(a.scenario)
    except ValueError as exc:
        p.error(f"--scenario: {exc}")
    config = BenchConfig(
        grids=[int(x) for x in a.grid.split(",") if x],
        unknowns=[float(x) for x in a.unknown.split(",") if x],
        scenarios=scenarios,
        backend=a.backend, variant=a.variant, modes=modes, seed=a.seed,
        repeats=max(1, a.repeats), fov_deg=a.fov, max_steps=a.max_steps,
    )  # fmt: skip
    try:
        config.check()
    except ValueError as exc:
        p.error(str(exc))
    done = [0]

    def tick(label: str) -> None:
        done[0] += 1
        print(f"[{done[0]}/{config.total_walks()}] {label}", flush=True)

    result = run_bench(config, on_walk=tick)
    print(format_tables(result.rows))
    print(f"device: {result.device}")
    if a.json_out is not None:
        a.json_out.parent.mkdir(parents=True, exist_ok=True)
        a.json_out.write_text(json.dumps(result.rows, indent=1) + "\n")
    if a.plot is not None:
        plot_steps(result, a.plot)


if __name__ == "__main__":
    main()
