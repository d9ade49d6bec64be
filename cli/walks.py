"""``guidebelt walks``: walks by a simulated user who follows the belt or the voice cues
(courtyard and others).

Only typer and the standard library at the top; numpy, the planner, guidance and matplotlib
are imported inside the command.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path
from typing import Annotated

import typer

from cli.options import PLANNER_NAMES, comma_list, walk_progress


def walks(
    follow: Annotated[
        str,
        typer.Option(
            help="Who walks: belt (the walker that feels the belt) or voice (the walker that "
            "hears the cues and never feels the belt)."
        ),
    ] = "belt",
    runs: Annotated[int, typer.Option(min=1, help="Seeded worlds per grid and density.")] = 100,
    scenario: Annotated[
        str, typer.Option(help="Scenarios, comma separated: courtyard, explore, building, streets.")
    ] = "courtyard",
    grid: Annotated[str, typer.Option(help="Grid sides, comma separated.")] = "100,200",
    unknown: Annotated[str, typer.Option(help="Fractions of free area unknown.")] = "0.2,0.4,0.6",
    backend: Annotated[str, typer.Option(help="Planner: cpu, cuda, auto or reference.")] = "cpu",
    planner: Annotated[
        str, typer.Option(help=f"A planner of the registry: {PLANNER_NAMES}.")
    ] = "eds",
    smooth: Annotated[bool, typer.Option(help="Rubber-band smoothing before guidance.")] = False,
    seed: Annotated[int, typer.Option(help="First seed; run i uses seed + i.")] = 0,
    jobs: Annotated[int, typer.Option(min=1, help="Worker processes.")] = 1,
    perception_sd: Annotated[
        float, typer.Option(help="Walker's error reading the belt direction, degrees (σ).")
    ] = 8.0,
    gait_sd: Annotated[float, typer.Option(help="Walker's veer per step, degrees (σ).")] = 4.0,
    step_m: Annotated[float, typer.Option(help="Walker's mean step length, metres.")] = 0.5,
    turn_sd: Annotated[
        float, typer.Option(help="Voice walker's error turning to a clock hour, degrees (σ).")
    ] = 20.0,
    heed_distance: Annotated[
        bool,
        typer.Option(help="Voice walker stops after the distance a cue said (else walks on)."),
    ] = False,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the rows here.")] = None,
    table: Annotated[
        bool, typer.Option(help="Run the walks table (--no-table: only the smoothing study).")
    ] = True,
    crossing: Annotated[
        bool,
        typer.Option(help="Instead: the moving-obstacle doorway, with and without the hold."),
    ] = False,
    smoothing_plot: Annotated[
        Path | None,
        typer.Option(help="Also measure smoothing: turning-angle histograms saved here (PNG)."),
    ] = None,
    movers: Annotated[
        int | None,
        typer.Option(
            min=0,
            help="Instead: Hong & DeSouza's room crossing with this many people "
            "wandering; --planner picks the planner, --trials the count.",
        ),
    ] = None,
    trials: Annotated[int, typer.Option(min=1, help="Seeded crossings for --movers.")] = 100,
) -> None:
    """Walk seeded worlds by feel or by ear; print success, length ratio, collisions, cues."""
    from rich.console import Console
    from rich.table import Table

    from sim.belt_walker import WalkerParams
    from sim.scenarios import check_grid, scenario_list
    from sim.voice_walker import VoiceWalkerParams
    from sim.walks import FOLLOW, run_table

    if follow not in FOLLOW:
        raise typer.BadParameter(
            f"{follow!r}: choose one of {', '.join(FOLLOW)}", param_hint="--follow"
        )
    if crossing and follow != "belt":
        raise typer.BadParameter("--crossing walks the belt walker only", param_hint="--follow")
    console = Console()
    if movers is not None:
        _movers(console, planner, movers, trials, seed, backend, json_out)
        return
    if crossing:
        _crossing(console, runs, seed, json_out)
        return
    grids, unknowns = comma_list(grid, int), comma_list(unknown, float)
    try:
        scenarios = scenario_list(scenario)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--scenario") from exc
    try:
        for name in scenarios:
            for g in grids:
                check_grid(name, g)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--grid") from exc
    if table:
        t0 = time.perf_counter()
        with walk_progress(console) as progress:
            # One advance per row (scenario × grid × density): each row is ``runs`` walks.
            task = progress.add_task(
                f"rows of {runs} walks", total=len(scenarios) * len(grids) * len(unknowns)
            )
            rows = run_table(
                grids, unknowns, runs, backend=backend, smooth=smooth, first_seed=seed, jobs=jobs,
                planner=planner,
                params=WalkerParams(
                    step_m=step_m, perception_sd_deg=perception_sd, gait_sd_deg=gait_sd
                ),
                on_row=lambda r: progress.update(
                    task, advance=1,
                    description=f"done {r['scenario']} {r['grid']} @ {r['unknown']:.0%}",
                ),
                scenarios=scenarios,
                follow=follow,
                voice_params=VoiceWalkerParams(
                    step_m=step_m, gait_sd_deg=gait_sd, turn_sd_deg=turn_sd,
                    heed_distance=heed_distance,
                ),
            )  # fmt: skip
        voice = follow == "voice"
        shown = Table(title=f"walks that follow the {follow} ({runs} runs each, {backend})")
        for name in ("scenario", "grid", "unknown", "runs", "success", "length ratio", "max ratio",
                     "collisions", "steps/walk", "cues/walk", "holds",
                     "route changes said"):  # fmt: skip
            shown.add_column(name, justify="right")
        if voice:
            shown.add_column("silence s, mean/max", justify="right")
        for r in rows:
            cells = [
                r["scenario"], str(r["grid"]), f"{r['unknown']:.0%}", str(r["runs"]),
                f"{r['success_rate']:.1%}", _ratio(r["length_ratio"]),
                _ratio(r["length_ratio_max"]), str(r["collisions"]),
                f"{r['steps_per_walk']:.1f}", f"{r['cues_per_walk']:.1f}", str(r["holds"]),
                f"{r['reroutes_announced']}/{r['route_changes']}",
            ]  # fmt: skip
            if voice:
                cells.append(f"{r['longest_silence_s']:.1f} / {r['longest_silence_max_s']:.1f}")
            shown.add_row(*cells)
        console.print(shown)
        took = time.perf_counter() - t0
        console.print(f"{took:.1f} s on {platform.node()} ({platform.machine()})")
        if json_out is not None:
            json_out.parent.mkdir(parents=True, exist_ok=True)
            json_out.write_text(json.dumps(rows, indent=1) + "\n")
            console.print(f"rows written to {json_out}")
    if smoothing_plot is not None:
        from sim.smoothing_study import plot_study, smoothing_study

        study = smoothing_study(grids, unknowns, runs=min(runs, 20), first_seed=seed)
        smoothing_plot.parent.mkdir(parents=True, exist_ok=True)
        plot_study(study, smoothing_plot)
        if json_out is not None and not table:
            json_out.parent.mkdir(parents=True, exist_ok=True)
            json_out.write_text(json.dumps(study, indent=1) + "\n")
        lengths = Table(title="path length (m), mean over courtyards")
        columns = ("raw", "band", "turning", "walk_raw", "walk_band")
        for name in ("grid", "unknown", "grid path", "rubber band", "turning points",
                     "walked (grid path)", "walked (rubber band)"):  # fmt: skip
            lengths.add_column(name, justify="right")
        for r in study["rows"]:
            lengths.add_row(
                str(r["grid"]), f"{r['unknown']:.0%}", *(f"{r[c + '_m']:.2f}" for c in columns)
            )
        console.print(lengths)
        console.print(f"plot written to {smoothing_plot}")


def _ratio(value: float | None) -> str:
    """A length ratio, or a dash where no walk arrived (the row has None)."""
    return "-" if value is None else f"{value:.3f}"


def _crossing(console, runs: int, seed: int, json_out: Path | None) -> None:
    """Hold against detour in the doorway scenario (``sim/crossing.py``)."""
    import numpy as np
    from rich.table import Table

    from sim.crossing import crossing_walk

    rows = []
    for hold in (True, False):
        done = [crossing_walk(hold=hold, seed=seed + i) for i in range(runs)]
        rows.append(
            {
                "hold": hold,
                "runs": runs,
                "arrived": sum(w.arrived for w in done),
                "walked_m": round(float(np.mean([w.walked_m for w in done])), 2),
                "time_s": round(float(np.mean([w.time_s for w in done])), 1),
                "backtrack_m": round(float(np.mean([w.backtrack_m for w in done])), 2),
                "collisions": sum(w.collisions for w in done),
                "holds": sum(w.holds for w in done),
            }
        )
    table = Table(title=f"a person stands in the doorway ahead ({runs} walks each)")
    for name in rows[0]:
        table.add_column(name, justify="right")
    for r in rows:
        table.add_row(*(str(v) for v in r.values()))
    console.print(table)
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(rows, indent=1) + "\n")


PAPER_MOVERS = {3: (1.0, 18.33, 2.73, 0.42), 10: (0.87, 27.08, 3.85, 2.36)}
"""Hong & DeSouza §V-A: success, time to goal (s), path length (m), interruptions."""


def _movers(console, planner: str, movers: int, trials: int, seed: int, backend: str,
            json_out: Path | None) -> None:  # fmt: skip
    """The room crossing with wandering people (``sim/movers.py``), the paper's figures beside."""
    from rich.table import Table

    from sim.movers import trials_row

    t0 = time.perf_counter()
    with console.status(f"{trials} crossings, {movers} people, {planner}…"):
        row = trials_row(planner, movers, trials, seed, backend)
    row["wall_s"] = round(time.perf_counter() - t0, 1)
    paper = PAPER_MOVERS.get(movers)
    row["paper"] = (
        None
        if paper is None
        else dict(zip(("success_rate", "time_s", "length_m", "interruptions"), paper, strict=True))
    )
    table = Table(title=f"crossing a room while {movers} people wander ({trials} trials)")
    for name in ("", "success", "time to goal s", "length m", "interruptions", "collisions"):
        table.add_column(name, justify="right")
    table.add_row(planner, f"{row['success_rate']:.0%}", str(row["time_s"]), str(row["length_m"]),
                  str(row["interruptions"]), str(row["collisions"]))  # fmt: skip
    if paper is not None:
        table.add_row("paper (harmonic + band)", f"{paper[0]:.0%}", str(paper[1]), str(paper[2]),
                      str(paper[3]), "-")  # fmt: skip
    console.print(table)
    console.print(f"{row['wall_s']} s on {platform.node()} ({platform.machine()})")
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(row, indent=1) + "\n")
        console.print(f"row written to {json_out}")


def register(app: typer.Typer) -> None:
    app.command("walks")(walks)
