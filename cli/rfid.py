"""``guidebelt rfid`` (the RFID node), ``rfid-eval`` (its accuracy), ``rfid-tags`` (a tag map)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from .peer import ZenohConfig, node_settings

METHODS = ("centroid", "lsq", "filter")


def rfid_eval(
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the rows here.")] = None,
    seeds: Annotated[int, typer.Option(min=1, help="Courtyards (seeds 0..n-1).")] = 5,
    walks: Annotated[int, typer.Option(min=1, help="Walks per courtyard, each shifted.")] = 4,
    unknown: Annotated[float, typer.Option(help="Fraction of free area unknown.")] = 0.4,
    speed: Annotated[float, typer.Option(help="Walking speed, m/s.")] = 1.0,
    setting: Annotated[
        str, typer.Option(help="paper (1.5 m reads, corner tags, LF at crossings) or dense.")
    ] = "paper",
    uhf_range: Annotated[
        float | None, typer.Option(min=0.1, help="UHF read radius, m (default: the setting's).")
    ] = None,
) -> None:
    """Position and heading error walking the simulated courtyard: every method and LF layout
    of the setting; availability, and the error over all instants (the last pose held)."""
    import numpy as np
    from rich.console import Console
    from rich.table import Table

    from sim.courtyard import make_courtyard
    from sim.rfid_eval import SETTINGS, evaluate, summary_row, tags_for, true_route

    if setting not in SETTINGS:
        raise typer.BadParameter(f"setting {setting!r}: choose one of {', '.join(SETTINGS)}")
    chosen = SETTINGS[setting]
    reach = uhf_range if uhf_range is not None else chosen.uhf_range_m
    console = Console()
    pooled: dict[tuple[str, str], list] = {}
    for seed in range(seeds):
        scenario = make_courtyard(100, unknown, seed)
        route = true_route(scenario)
        # Each walk is shifted by up to half an LF tag spacing, so the walks pass the
        # floor lattice at every phase and not only along its lines.
        offsets = np.random.default_rng(seed).uniform(-0.1, 0.1, size=(walks, 2))
        for layout in chosen.lf_layouts:
            tag_map = tags_for(scenario, layout, seed, edge_spacing_m=chosen.edge_spacing_m)
            for w, offset in enumerate(offsets):
                for method in METHODS:
                    res = evaluate(
                        tag_map,
                        route,
                        method=method,
                        lf_layout=layout,
                        seed=seed * 1000 + w,
                        speed_mps=speed,
                        uhf_range_m=reach,
                        offset=(float(offset[0]), float(offset[1])),
                    )
                    pooled.setdefault((method, layout), []).append(res)
    rows = [dict(summary_row(m, lay, rs), setting=setting, uhf_range_m=reach)
            for (m, lay), rs in pooled.items()]  # fmt: skip
    title = (f"RFID pose error ({setting}: UHF {reach} m), {seeds} courtyards x {walks} walks"
             f" at {speed} m/s")  # fmt: skip
    table = Table(title=title)
    cols = ("method", "LF tags", "avail.", "median m", "p95 m", "all: median m", "all: p95 m",
            "heading med °", "heading p95 °", "samples")  # fmt: skip
    for col in cols:
        table.add_column(col)
    for r in rows:
        table.add_row(r["method"], r["lf_layout"], f"{r['availability']:.0%}",
                      f"{r['median_m']:.3f}", f"{r['p95_m']:.3f}", f"{r['all_median_m']:.3f}",
                      f"{r['all_p95_m']:.3f}", f"{r['heading_median_deg']:.1f}",
                      f"{r['heading_p95_deg']:.1f}", str(r["samples"]))  # fmt: skip
    console.print(table)
    console.print("all: the error of the latest pose the user has at every instant (inf before "
                  "the first); heading: 'filter' is the compass less its estimated bias, the "
                  "others eq. 3 over successive positions")  # fmt: skip
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(rows, indent=1) + "\n")
        console.print(f"rows written to {json_out}")


def rfid_tags(
    out: Annotated[Path, typer.Option(help="Tag map file to write (JSON).")],
    seed: Annotated[int, typer.Option(help="Courtyard seed.")] = 0,
    lf_layout: Annotated[str, typer.Option(help="none, corners or floor.")] = "floor",
) -> None:
    """Write the tag map of the simulated courtyard (UHF on corners, LF floor tags)."""
    from sim.courtyard import make_courtyard
    from sim.rfid_eval import tags_for

    tag_map = tags_for(make_courtyard(100, 0.4, seed), lf_layout, seed)
    tag_map.dump(out)
    typer.echo(f"{out}: {len(tag_map.uhf_ids)} UHF tags, {len(tag_map.lf_ids)} LF tags")


def rfid(
    user: Annotated[str, typer.Option(help="User whose pose this reader gives.")],
    port: Annotated[str | None, typer.Option(help="Serial port of the reader.")] = None,
    tags: Annotated[Path | None, typer.Option(help="Tag map file (default: the sim's).")] = None,
    method: Annotated[
        str, typer.Option(help="lsq (default), centroid (the paper's) or filter (with σ).")
    ] = "lsq",
    rate: Annotated[float, typer.Option(min=10.0, help="Poses per second.")] = 20.0,
    listen: Annotated[list[str] | None, typer.Option(help="Zenoh listen endpoint.")] = None,
    connect: Annotated[list[str] | None, typer.Option(help="Zenoh endpoint to join.")] = None,
    scouting: Annotated[bool, typer.Option(help="Zenoh multicast scouting.")] = False,
    mock: Annotated[bool, typer.Option(help="A mock reader on a pty walks the sim.")] = False,
    duration: Annotated[float, typer.Option(help="Stop after this many s (0: never).")] = 0.0,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Run the RFID node: reader on PORT → localiser → Pose on zenoh."""
    import asyncio
    import contextlib
    import logging
    import signal
    import time

    from drivers.rfid.node import RfidNode
    from drivers.rfid.tags import TagMap
    from protocol.session import open_session

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if port is None and not mock:
        raise typer.BadParameter("give --port, or --mock for a simulated reader")
    mock_reader = None
    if mock or tags is None:
        from sim.courtyard import make_courtyard
        from sim.rfid_eval import along, tags_for, true_route

        scenario = make_courtyard(100, 0.4, 0)
        tag_map = TagMap.load(tags) if tags else tags_for(scenario, "floor")
    else:
        tag_map = TagMap.load(tags)
    if mock:
        from drivers.rfid.mock_reader import MockReader
        from drivers.rfid.rssi import ReadModel

        route, t0 = true_route(scenario), time.time()
        mock_reader = MockReader(
            ReadModel.for_tags(tag_map),
            lambda t: tuple(along(route, [(t - t0) * 1.0])[0]),
        ).start()
        port = mock_reader.path
        typer.echo(f"mock reader on {port}, walking the courtyard route")
    session = open_session(node_settings(zenoh_config, connect, listen, scouting))
    node = RfidNode(session, user, tag_map, port, method=method, rate_hz=rate)

    async def main() -> None:
        task = asyncio.create_task(node.run())
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(sig, task.cancel)
        if duration > 0:
            loop.call_later(duration, task.cancel)
        with contextlib.suppress(asyncio.CancelledError):
            await task

    try:
        asyncio.run(main())
    finally:
        typer.echo(node.stats().model_dump_json())
        node.close()
        session.close()
        if mock_reader is not None:
            mock_reader.stop()


REGISTERS = ("true", "estimate", "tags")


def _one_of_registers(value: str) -> str:
    if value not in REGISTERS:
        raise typer.BadParameter(f"{value!r}: choose one of {', '.join(REGISTERS)}")
    return value


def _one_of_matches(value: str) -> str:
    from sim.rfid_belt_walk import MATCHES

    if value not in MATCHES:
        raise typer.BadParameter(f"{value!r}: choose one of {', '.join(MATCHES)}")
    return value


def rfid_walks(
    runs: Annotated[int, typer.Option(min=1, help="Walks per clutter level (seeds 0..n-1).")] = 50,
    unknown: Annotated[list[float] | None, typer.Option(help="Clutter levels.")] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the rows here.")] = None,
    match: Annotated[
        str,
        typer.Option(
            help="Map matching besides the tags: camera, contact or none.",
            callback=_one_of_matches,
        ),
    ] = "camera",
    proximity: Annotated[
        bool,
        typer.Option(
            help="A worn obstacle sensor's STOP before contact, seen from where the walker "
            "truly is, and no GUIDE back into what it saw (--no-proximity: none).",
        ),
    ] = True,
    map_from: Annotated[
        str,
        typer.Option(
            "--map",
            help="The daemon's map: true (survey + camera), estimate (camera at the RFID "
            "pose) or tags (no survey: the UHF tags' memory + camera).",
            callback=_one_of_registers,
        ),
    ] = "true",
) -> None:
    """Closed-loop belt walks of the 100² courtyard guided by the RFID pose filter (tags,
    steps and compass, and with ``--match`` the bumps and the camera's nearest obstacle
    matched against the map)."""
    import numpy as np

    from sim.courtyard import make_courtyard
    from sim.rfid_belt_walk import rfid_belt_walk

    rows = []
    for level in unknown or [0.2, 0.4, 0.6]:
        res = [
            rfid_belt_walk(
                make_courtyard(100, level, s),
                seed=s,
                match=match,
                proximity=proximity,
                register=map_from,
            )
            for s in range(runs)
        ]
        errors = np.concatenate([r.pose_errors for r in res])
        heading = np.degrees(np.concatenate([r.heading_errors for r in res]))
        row = {
            "unknown": level,
            "runs": runs,
            "match": match,
            "proximity": proximity,
            "map": map_from,
            "success": round(sum(r.arrived for r in res) / runs, 4),
            "collisions": int(sum(r.collisions for r in res)),
            "walks_with_collision": int(sum(r.collisions > 0 for r in res)),
            "waits": int(sum(r.waits for r in res)),
            "pose_median_m": round(float(np.median(errors)), 3),
            "pose_p95_m": round(float(np.percentile(errors, 95)), 3),
            "heading_median_deg": round(float(np.median(heading)), 1),
            "final_error_median_m": round(float(np.median([r.final_error_m for r in res])), 3),
            "failures": [
                (s, r.reason, r.collisions)
                for s, r in enumerate(res)
                if not r.arrived or r.collisions
            ],
        }
        rows.append(row)
        typer.echo(json.dumps(row))
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(rows, indent=1) + "\n")


def register(app: typer.Typer) -> None:
    app.command("rfid-walks")(rfid_walks)
    app.command("rfid-eval")(rfid_eval)
    app.command("rfid-tags")(rfid_tags)
    app.command("rfid")(rfid)
