"""The daemon-backed demo: daemon, simulated world and mock drivers, each its own zenoh node.

All in this process, on separate zenoh sessions joined over 127.0.0.1 (no multicast): the
daemon on its uvloop thread listening on a free port, the world (``SimNode``) and the
recording belt and voice drivers connecting to it — the same messages a deployment sends.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim.courtyard import USER_RADIUS_M, Scenario, dilate, make_courtyard
from sim.node import SimResult


def render_sim(scenario: Scenario, result: SimResult, out: Path) -> Path:
    """The picture of a walk over zenoh, drawn by the same code as the in-process walk."""
    from sim.render import render_walk
    from sim.walk import WalkPicture

    known = result.known if result.known is not None else scenario.known
    walk = WalkPicture(
        mode="eds",
        arrived=result.arrived,
        reason=result.reason,
        walked=np.array(result.walked, dtype=np.int32).reshape(-1, 2),
        known=known,
        blocked=dilate(known == 1, scenario.radius_cells),
        cell_m=scenario.cell_m,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    return render_walk(scenario, walk, out)


def _camera_summary(console, node, belt) -> None:
    """The camera's part of the walk: frames mapped, refused, time per frame, STOPs felt."""
    ms = np.array(node.frame_ms) if node.frame_ms else np.array([math.nan])
    stops = sum(1 for k in belt.kinds() if k == "stop")
    walker = node.walker
    console.print(
        f"camera: {len(node.frame_ms)} frames, {node.mapper.frames} mapped, "
        f"{sum(node.mapper.refused.values())} refused; mapper {np.median(ms):.1f} ms per frame "
        f"(median, p99 {np.percentile(ms, 99):.1f}, backend {node.mapper.backend}); "
        f"{len(node.movers.people)} people walking; {stops} STOP patterns; "
        f"{getattr(walker, 'collisions', 0)} collisions"
    )


def run_with_daemon(
    grid: int, unknown: float, seed: int, backend: str, follow: str, out: Path,
    belt_kind: str = "none", pace_s: float = 0.0, planner: str = "eds", sensor: str = "map",
    people: int = 3, guide_hz: float | None = None,
) -> bool:
    """One user guided across the courtyard by the real daemon; True when they arrived.

    ``pace_s`` is the time the walker takes per step (0: as fast as the daemon answers).
    Paced like a person, the voice cues' rate limit and the hold timer see real time.
    ``guide_hz`` overrides the daemon's pose re-guide rate (None: the config's): at the
    default 10 Hz an unpaced walk waits 0.1 s a step for it.
    """
    import threading
    import time

    from rich.console import Console

    from daemon.service.embedded import DaemonThread
    from daemon.service.logs import setup_logging
    from drivers.belt.hil import belt_in_loop
    from drivers.belt.hil import summary as belt_summary
    from drivers.belt.recorder import BeltRecorder
    from drivers.voice.recorder import VoiceRecorder
    from protocol import codec
    from protocol import session as wire
    from protocol import topics as T
    from protocol.messages import Goal, GoalCell
    from sim.node import SimNode

    setup_logging("WARNING")
    console = Console()
    scenario = make_courtyard(grid=grid, unknown=unknown, seed=seed)
    console.print(
        f"courtyard {grid}x{grid} ({scenario.cell_m * 100:g} cm cells), {unknown:.0%} unknown "
        f"obstacles, seed {seed}; daemon on zenoh, backend {backend}, walker follows {follow}"
    )
    user = "demo"
    rate = {} if guide_hz is None else {"guide_hz": guide_hz}
    with DaemonThread(
        planner=planner, backend=backend, cell_m=scenario.cell_m, user_radius_m=USER_RADIUS_M,
        **rate,
    ) as daemon:
        drivers, world, client = daemon.peer(), daemon.peer(), daemon.peer()
        belt, voice = BeltRecorder(drivers, user), VoiceRecorder(drivers, user)
        # The camera's walk stops for obstacles ahead (a real second each): give it longer.
        timeout_s = 300.0 if sensor == "camera" else 120.0
        if sensor == "camera":  # world → RGB-D frames → mapper node → daemon
            from sim.camera_node import CameraSimNode

            node: SimNode = CameraSimNode(world, user, scenario, walker=follow, seed=seed,
                                          people=people, step_period_s=pace_s)  # fmt: skip
        else:
            node = SimNode(world, user, scenario, walker=follow, step_period_s=pace_s)
        box: dict[str, SimResult] = {}
        stop = threading.Event()
        try:
            # --belt simavr|mock: the belt firmware (simulated Nano) and its driver in the loop.
            with (
                belt_in_loop(belt_kind, user, daemon.port) as nano,
                console.status("starting") as line,
            ):

                def progress(r: SimResult) -> None:
                    r0, c0 = r.walked[-1]
                    left = math.hypot(r0 - scenario.goal[0], c0 - scenario.goal[1])
                    line.update(
                        f"step {r.steps}: at {r.walked[-1]}, {left * scenario.cell_m:.1f} m to "
                        f"the goal, {r.step_ms[-1]:.1f} ms pose → path, "
                        f"{len(belt.received)} belt patterns, {len(voice.received)} cues"
                    )

                walker = threading.Thread(
                    target=lambda: box.setdefault(
                        "r", node.run(stop, on_step=progress, timeout_s=timeout_s)
                    )
                )
                walker.start()
                time.sleep(0.3)
                goal = Goal(
                    target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=time.time()
                )
                wire.put(client, T.GOAL, user, codec.encode(goal))
                walker.join()
        except KeyboardInterrupt:
            stop.set()
            walker.join(5)
            raise
        finally:
            for closable in (belt, voice, drivers, world, client):
                closable.close()
    result = box["r"]
    status = result.last_status
    ms = np.array(result.step_ms) if result.step_ms else np.array([math.nan])
    console.print(
        f"{'arrived' if result.arrived else 'did not arrive (' + result.reason + ')'}: "
        f"{result.steps} steps, {status.replans if status else 0} replans (a new obstacle cut "
        f"the path), {np.median(ms):.1f} ms per step (median pose → path, p95 "
        f"{np.percentile(ms, 95):.1f}), backend {status.backend if status else '?'}"
    )
    console.print(
        f"belt driver got {len(belt.received)} patterns "
        f"({', '.join(sorted(set(belt.kinds())))}); voice driver got "
        f"{len(voice.received)} cues, last: {voice.texts()[-1] if voice.received else '-'!r}"
    )
    if nano is not None:
        console.print(belt_summary(nano), soft_wrap=True)
    if sensor == "camera":
        _camera_summary(console, node, belt)
    render_sim(scenario, result, out)
    console.print(f"picture: {out}")
    return result.arrived
