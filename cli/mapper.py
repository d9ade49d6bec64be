"""``guidebelt mapper``: depth frames from a folder → map deltas and proximity over zenoh."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from cli.peer import Connect, Scout, ZenohConfig, open_peer


def mapper(
    frames: Annotated[Path, typer.Option("--frames", help="Folder of NAME.png + NAME.json.")],
    user: Annotated[str, typer.Option(help="Whose map this is.")],
    size: Annotated[str, typer.Option(help="Map height,width in cells.")] = "100,100",
    cell_m: Annotated[float, typer.Option(help="Cell side, metres.")] = 0.10,
    backend: Annotated[str, typer.Option(help="auto, cpu or cuda.")] = "auto",
    floor_every: Annotated[
        int, typer.Option(min=1, help="Refit the floor every N frames (4 keeps cuda under 1 ms).")
    ] = 4,
    floor_async: Annotated[
        bool,
        typer.Option(
            help="Fit a due floor on a worker thread once the frame is out, taken by the "
            "next frame (--no-floor-async: on the frame's path)."
        ),
    ] = True,
    birdseye: Annotated[
        bool,
        typer.Option(
            help="Seed 004's colour map instead of depth: the frames' colour images to a "
            "bird's-eye map, the green target sent as the goal (turn and look until seen)."
        ),
    ] = False,
    rate: Annotated[
        float, typer.Option(help="Frames per second to replay at (0: as fast as mapped).")
    ] = 0.0,
    restamp: Annotated[
        bool, typer.Option(help="Stamp frames with the time they are sent (replaying old files).")
    ] = True,
    connect: Connect = None,
    scout: Scout = False,
    zenoh_config: ZenohConfig = None,
) -> None:
    """Map a folder of depth frames for USER and publish the deltas, as a camera would."""
    import dataclasses
    import time

    from rich.console import Console

    from mapper.frame import FrameRejected, Refusal
    from mapper.frames_io import read_frames
    from mapper.node import MapperNode
    from mapper.occupancy_mapper import MapperSettings, OccupancyMapper

    try:
        h, w = (int(v) for v in size.split(","))
    except ValueError as exc:
        raise typer.BadParameter(f"--size must be HEIGHT,WIDTH, not {size!r}") from exc
    console = Console()
    settings = MapperSettings(shape=(h, w), cell_m=cell_m, backend=backend,
                              floor_every=floor_every, floor_async=floor_async)  # fmt: skip
    view = None
    if birdseye:
        from mapper.birdseye.node import BirdsEyeMapper, BirdsEyeSettings
        from mapper.frames_io import frame_files, read_frame

        files = frame_files(frames)
        try:
            view = BirdsEyeMapper.for_frame(read_frame(files[0]), BirdsEyeSettings((h, w), cell_m))
        except (IndexError, FrameRejected) as exc:
            raise typer.BadParameter(f"--birdseye needs a readable first frame: {exc}") from exc
    session = open_peer(connect, scout, zenoh_config)
    if view is not None:
        from mapper.birdseye.node import BirdsEyeNode

        node: MapperNode = BirdsEyeNode(session, user, view)
    else:
        node = MapperNode(session, user, OccupancyMapper(settings))
    try:
        node.start()
        mapped, last_own = 0, None
        # Each frame is read into the buffer the mapper's pass uploads from (cuda): no copy
        # on its path. The bird's-eye mapper reads the colour image: no buffer there.
        m = node.mapper
        into = m.depth_buffer if isinstance(m, OccupancyMapper) and m.lends_depth else None
        for item in read_frames(frames, into):
            t0 = time.monotonic()
            if isinstance(item, Exception):
                node.refuse(item)
                continue
            if restamp:  # fresh stamps for the daemon, but the files' own order still holds
                if last_own is not None and item.stamp <= last_own:
                    why = f"stamp {item.stamp:.3f} is not after the last frame's {last_own:.3f}"
                    node.refuse(FrameRejected(Refusal.STALE, why))
                    continue
                last_own = item.stamp
                item = dataclasses.replace(item, stamp=time.time())
            if node.feed(item) is not None:
                mapped += 1
            if rate > 0:
                time.sleep(max(0.0, 1.0 / rate - (time.monotonic() - t0)))
        refused = ", ".join(f"{k} {v}" for k, v in sorted(node.refused.items())) or "none"
        console.print(
            f"{mapped} frames mapped, {node.published} deltas published (last seq {node.seq}), "
            f"refused: {refused}; backend {node.mapper.backend}"
        )
    finally:
        node.close()
        session.close()


def register(app: typer.Typer) -> None:
    app.command("mapper")(mapper)
