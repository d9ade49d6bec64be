"""``guidebelt bench``: the paper's closed-loop walk as a benchmark (Tables 1 and 2, Figure 9).

The walks run the daemon's own navigator, so they need what it needs (pydantic for its
messages; scripts/device_env.sh carries the wheels to the GPU machine). Only typer and the
standard library are imported at the top, the rest inside the command.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from cli.options import PLANNER_NAMES, Backend, Scenarios, Unknowns, comma_list, walk_progress


def bench(
    scenario: Scenarios = "courtyard",
    grid: Annotated[str, typer.Option(help="Grid sides, comma separated (100: 10 cm).")] = (
        "100,200,400"
    ),
    unknown: Unknowns = "0.2,0.4,0.6",
    backend: Backend = "cpu",
    variant: Annotated[str, typer.Option(help="fast, or paper (its Figure 4 form).")] = "fast",
    planner: Annotated[
        str,
        typer.Option("--planner", "--modes", help=f"Planners to walk with: {PLANNER_NAMES}."),
    ] = "eds,dss",
    seed: Annotated[int, typer.Option(help="Scenario seed.")] = 0,
    repeats: Annotated[int, typer.Option(min=1, help="Walks per table cell, times pooled.")] = 1,
    fov: Annotated[float, typer.Option(help="Sensor field of view, degrees.")] = 80.0,
    max_steps: Annotated[
        int | None, typer.Option(min=1, help="Stop each walk after N steps (rows say capped).")
    ] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the rows here.")] = None,
    plot: Annotated[Path | None, typer.Option(help="Save a Figure 9-like plot.")] = None,
    users: Annotated[
        str | None,
        typer.Option(help="N users (comma separated: a row each), each its own EDS walk."),
    ] = None,
    rate: Annotated[
        float | None, typer.Option(min=0.1, help="--users: every user steps at HZ (open loop).")
    ] = None,
    seconds: Annotated[float, typer.Option(min=0.1, help="--rate: how long.")] = 10.0,
    threads: Annotated[
        bool, typer.Option(help="--rate: each user on a thread of its own, as the daemon.")
    ] = False,
    walks: Annotated[int, typer.Option(min=1, help="--users: distinct walks recorded.")] = 16,
    walks_file: Annotated[
        Path | None, typer.Option(help="--users: recorded walks read from (or written to) here.")
    ] = None,
) -> None:
    """Walk the simulated scenarios with each planner; print Steps, Iter_avg and ms per step."""
    if users is not None:
        how = {"seed": seed, "walks": walks, "max_steps": max_steps, "hz": rate,
               "seconds": seconds, "cache": walks_file, "threads": threads}  # fmt: skip
        bench_users(scenario, grid, unknown, backend, users, how, json_out)
        return
    from rich import box
    from rich.console import Console
    from rich.table import Table

    from sim.benchmark import TABLE1_HEADS, TABLE2_HEADS, BenchConfig, run_bench, table_rows
    from sim.scenarios import scenario_list
    from sim.walk import MODES

    mode_list = [m.strip() for m in planner.split(",") if m.strip()]
    if not mode_list or any(m not in MODES for m in mode_list):
        raise typer.BadParameter(f"{planner!r}: choose from {', '.join(MODES)}", "--planner")
    try:
        scenarios = scenario_list(scenario)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--scenario") from exc
    config = BenchConfig(
        grids=comma_list(grid, int),
        unknowns=comma_list(unknown, float),
        scenarios=scenarios,
        backend=backend,
        variant=variant,
        modes=mode_list,
        seed=seed,
        repeats=repeats,
        fov_deg=fov,
        max_steps=max_steps,
    )
    try:
        config.check()
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--grid") from exc
    console = Console()
    with walk_progress(console) as progress:
        task = progress.add_task("walks", total=config.total_walks())
        result = run_bench(
            config,
            on_walk=lambda label: progress.update(task, advance=1, description=label),
            on_start=lambda label: progress.update(task, description=label),
        )

    t1, t2 = table_rows(result.rows)
    table1 = Table(
        title=f"Steps and Iter_avg ({result.rows[0]['backend']}, {variant})", box=box.SIMPLE_HEAD
    )
    for name in TABLE1_HEADS:
        table1.add_column(name, justify="right")
    table2 = Table(title="ms per replanning step (update or replan + path)", box=box.SIMPLE_HEAD)
    for name in TABLE2_HEADS:  # "DSS med" → "DSS\nmed": narrow columns
        table2.add_column(name.replace(" ", "\n").replace("/", "/\n"), justify="right",
                          no_wrap=True)  # fmt: skip
    for cells in t1:
        table1.add_row(*cells)
    for cells in t2:
        table2.add_row(*cells)
    console.print(table1)
    console.print(table2)
    if any(m not in ("eds", "dss") for m in mode_list):  # the paper's tables show only those two
        from sim.benchmark import PLANNER_HEADS, planner_rows

        table3 = Table(title="ms per replanning step, by planner", box=box.SIMPLE_HEAD)
        for name in PLANNER_HEADS:
            table3.add_column(name, justify="right", no_wrap=True)
        for cells in planner_rows(result.rows):
            table3.add_row(*cells)
        console.print(table3)
    console.print(f"device: {result.device}")
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(result.rows, indent=1) + "\n")
        console.print(f"rows written to {json_out}")
    if plot is not None:
        from sim.benchmark import plot_steps

        plot.parent.mkdir(parents=True, exist_ok=True)
        plot_steps(result, plot)
        console.print(f"plot written to {plot}")


def bench_users(
    scenario: str,
    grid: str,
    unknown: str,
    backend: str,
    users: str,
    how: dict,
    json_out: Path | None,
) -> None:
    """``--users N``: per-user step latency of N users replaying their walks (sim/users.py)."""
    from rich.console import Console

    from sim.users import run_users

    counts = comma_list(users, int)
    if not counts or min(counts) < 1:
        raise typer.BadParameter(f"{users!r}: user counts of 1 or more", param_hint="--users")
    rows = [
        run_users(scenario, g, u, backend, n, **how)
        for g in comma_list(grid, int)
        for u in comma_list(unknown, float)
        for n in counts
    ]
    console = Console()
    for r in rows:
        console.print(
            f"{r['backend']} {r['scenario']} {r['grid']}² {r['unknown']:.0%} users {r['users']} "
            f"{r['mode']}: steps {r['steps']}, ms median {r['median']:.3f} p99 {r['p99']:.3f} "
            f"max {r['max']:.3f}, {r['steps_per_s']:.0f} steps/s, "
            f"device MB/user {r['device_bytes'] / 1e6:.2f}"
        )
    console.print(f"device: {rows[0]['device']}")
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(rows, indent=1) + "\n")
        console.print(f"rows written to {json_out}")


def register(app: typer.Typer) -> None:
    app.command("bench")(bench)
