"""One camera-in-the-loop walk through the daemon, quietly, for tests and the 20-run table.

World → RGB-D frames → mapper node → daemon → belt, each on its own zenoh session over
127.0.0.1 (``CameraSimNode`` and ``DaemonThread``), the belt walker feeling the patterns.
``guidebelt demo --sensor camera`` is the same walk with progress, drivers and a picture;
``scripts/camera_walks.py`` runs it over seeds and prints the table.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from daemon.service.embedded import DaemonThread
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltPattern, Goal, GoalCell

from .camera_node import CameraSimNode
from .courtyard import USER_RADIUS_M, make_courtyard

CAMERA_UNKNOWN = 0.2
"""The camera walks' share of unknown obstacles. At the paper's 40 % the courtyard's 30 cm
blobs leave gaps a truth sensor finds but a camera, which sees no further than the first
face, cannot tell from dead ends."""


@dataclass
class CameraWalk:
    arrived: bool
    reason: str
    steps: int
    collisions: int
    stops: int
    """STOP patterns the belt got (proximity and refusals)."""
    frames: int
    refused: int
    mapper_ms: np.ndarray
    walk_s: float
    people: int
    actions: dict[str, int]
    """The walker's actions by kind (step, turn, stand, bump)."""
    bumps: list[dict]
    """What each collision ran into and what the walker, the frame and the belt knew then
    (``CameraSimNode._bumped``)."""


def camera_walk(seed: int, unknown: float = CAMERA_UNKNOWN, people: int = 3,
                timeout_s: float = 300.0, max_steps: int | None = None,
                backend: str = "cpu") -> CameraWalk:  # fmt: skip
    scenario = make_courtyard(100, unknown, seed)
    user = "walker"
    stops: list[int] = [0]

    def on_belt(sample) -> None:
        if codec.decode(BeltPattern, sample.payload.to_bytes()).kind == "stop":
            stops[0] += 1

    with DaemonThread(planner="eds", backend=backend, cell_m=scenario.cell_m,
                      user_radius_m=USER_RADIUS_M) as daemon:  # fmt: skip
        world, client = daemon.peer(), daemon.peer()
        sub = wire.declare_subscriber(client, T.BELT, on_belt, user)
        node = CameraSimNode(world, user, scenario, walker="belt", seed=seed, people=people,
                             backend=backend)  # fmt: skip
        box: dict = {}
        t0 = time.monotonic()
        try:
            walker = threading.Thread(
                target=lambda: box.setdefault(
                    "r", node.run(max_steps=max_steps, timeout_s=timeout_s)
                )
            )
            walker.start()
            time.sleep(0.3)
            goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]),
                        stamp=time.time())  # fmt: skip
            wire.put(client, T.GOAL, user, codec.encode(goal))
            walker.join()
        finally:
            sub.undeclare()
            world.close()
            client.close()
    result = box["r"]
    return CameraWalk(
        arrived=result.arrived, reason=result.reason, steps=result.steps,
        collisions=int(getattr(node.walker, "collisions", 0)), stops=stops[0],
        frames=len(node.frame_ms), refused=sum(node.mapper.refused.values()),
        mapper_ms=np.array(node.frame_ms), walk_s=time.monotonic() - t0,
        people=len(node.movers.people), actions=dict(result.actions), bumps=node.bumps,
    )  # fmt: skip
