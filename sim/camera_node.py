"""The camera in the loop: the simulated world seen through an RGB-D camera and the mapper.

``CameraSimNode`` is ``SimNode`` with the map producer swapped: instead of writing the
truth into map deltas, the world renders what a chest camera sees (``camera.RgbdCamera``)
and hands the frame to a ``MapperNode`` (``mapper.node``), which publishes the deltas,
answers the daemon's snapshot queries and publishes the frame's proximity. People walk
(``people.Movers``) while the user does. One frame goes with every pose, so the map, the
proximity and the position the daemon steps on are always those of the same moment.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import zenoh
from zenoh.handlers import Callback

from daemon.planning.grid import UNKNOWN
from mapper.node import MapperNode
from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltPattern, NavPath

from .camera import SEED000_INTRINSICS, RgbdCamera
from .courtyard import Scenario
from .node import SimNode
from .people import Movers
from .scene3d import BOX, FLOOR, PERSON, TABLE, WALL, scene_from_scenario

DEMO_SCALE = 0.5
"""The walks render 320 x 240 (seed 000's camera at half resolution), so a 2-core machine
walks in real time; the mapper's own benchmark takes 640 x 480."""
STEP_DT_S = 0.5
"""Simulated seconds per walker action: a 0.5 m step at a cautious 1 m/s."""
KINDS = {FLOOR: "floor", WALL: "wall", BOX: "box", TABLE: "table", PERSON: "person"}


class CameraSimNode(SimNode):
    def __init__(self, session: zenoh.Session, user: str, scenario: Scenario, *,
                 walker: str = "belt", seed: int = 0, people: int = 3,
                 camera: RgbdCamera | None = None, backend: str = "cpu",
                 step_period_s: float = 0.0, known: bool = True) -> None:  # fmt: skip
        super().__init__(session, user, scenario, walker=walker, seed=seed,
                         step_period_s=step_period_s)  # fmt: skip
        self.camera = camera or RgbdCamera(SEED000_INTRINSICS.scaled(DEMO_SCALE))
        self.rng = np.random.default_rng([seed, 11])
        static = scene_from_scenario(scenario, seed)
        ends = [scenario.start, scenario.goal]
        self.movers = Movers(static, scenario.true, scenario.known, ends, people, seed)
        self.world.true[...] = self.movers.true_static
        start = scenario.known if known else np.full(scenario.shape, UNKNOWN, np.uint8)
        settings = MapperSettings(shape=scenario.shape, cell_m=scenario.cell_m, backend=backend)
        self.mapper = OccupancyMapper(settings, start)
        self.world.known = self.mapper.occupancy  # the picture shows what the camera mapped
        self.map_node: MapperNode | None = None
        self.frame_ms: list[float] = []
        self._last_frame = 0.0
        self._depth: np.ndarray | None = None
        self._frame_seq = -1
        """The mapper's last delta once the latest frame was mapped."""
        self.bumps: list[dict] = []
        """Every collision with what the world, the frame and the belt were then (``_bumped``)."""

    def _declare(self) -> None:
        s, u = self.session, self.user
        self.map_node = MapperNode(s, u, self.mapper)
        self._pub_pose = wire.declare_publisher(s, T.POSE, u)
        self._entities = [
            self._pub_pose,
            wire.declare_subscriber(s, T.PATH, Callback(self._on_path, indirect=False), u),
            wire.declare_subscriber(s, T.BELT, Callback(self._on_belt, indirect=False), u),
            wire.declare_subscriber(s, T.STATUS, Callback(self._on_status, indirect=False), u),
        ]

    def close(self) -> None:
        super().close()
        if self.map_node is not None:
            self.map_node.close()
            self.map_node = None

    def _start_map(self) -> None:
        assert self.map_node is not None
        self.map_node.start()
        self._frame()

    def _frame(self) -> None:
        """People walk on, the camera takes a frame, the mapper publishes what it saw."""
        assert self.map_node is not None
        w = self.walker
        self.movers.advance(STEP_DT_S, (w.x, w.y))
        self.movers.stamp(self.world.true)
        stamp = max(time.time(), self._last_frame + 1e-3)  # strictly after the last frame
        self._last_frame = stamp
        pose = self.camera.pose(w.x, w.y, w.heading)
        k = self.camera.intrinsics
        if self._depth is None:  # rendered straight into what the mapper's pass uploads
            self._depth = self.mapper.depth_buffer(k.height, k.width)
        frame = self.camera.render(self.movers.scene, pose, stamp, self.rng, out=self._depth)
        t0 = time.perf_counter()
        self.map_node.feed(frame)
        self.frame_ms.append((time.perf_counter() - t0) * 1e3)
        self._frame_seq = self.map_node.seq

    def _send_pose(self) -> float:
        self._frame()
        return super()._send_pose()

    def _bumped(self, path: NavPath, belt: BeltPattern | None) -> None:
        """What the step ran into (its kind; a person's distance), what the camera's map held
        there, the pattern the walker stepped on and how old it and the frame were, the
        frame's own proximity, and whether the daemon's step had that frame's delta."""
        bumps = getattr(self.walker, "bumps", None)
        if not bumps:
            return
        b = bumps[-1]
        r, c = b.cell
        inside = 0 <= r < self.shape[0] and 0 <= c < self.shape[1]
        now = time.time()
        framed = self._last_frame > 0.0
        people = [math.hypot(x - b.x, y - b.y) for x, y in (p.where() for p in self.movers.people)]
        last = self.map_node.last if self.map_node is not None else None
        prox = last.proximity if last is not None else None
        self.bumps.append({
            "xy": [round(b.x, 3), round(b.y, 3)], "heading_deg": round(math.degrees(b.heading), 1),
            "to": [round(b.to_x, 3), round(b.to_y, 3)], "cell": [r, c],
            "kind": KINDS.get(int(self.movers.scene.kind[r, c]), "?") if inside else "edge",
            "mapped": int(self.mapper.occupancy[r, c]) if inside else None,
            "person_m": round(min(people), 3) if people else None,
            "pattern": {"kind": b.kind, "motors": list(b.motors), "period_ms": b.period_ms,
                        "age_ms": None if belt is None else round((now - belt.stamp) * 1e3, 1)},
            "frame_age_ms": round((now - self._last_frame) * 1e3, 1) if framed else None,
            "frame_to_pattern_ms": round((belt.stamp - self._last_frame) * 1e3, 1)
            if framed and belt is not None else None,
            "frame_proximity": None if prox is None
            else {k: None if v is None else round(v, 3)
                  for k, v in (("ahead_m", prox.ahead_m), ("nearest_m", prox.nearest_m))},
            "step_had_frame_delta": path.map_seq >= self._frame_seq,
        })  # fmt: skip

    def _sense(self, stop: threading.Event) -> None:
        """The frame goes with the next pose (``_send_pose``): nothing to do here."""


def heading_to(scenario: Scenario) -> float:
    """The bearing from start to goal: where the user faces at the start."""
    (r0, c0), (r1, c1) = scenario.start, scenario.goal
    return math.atan2(-(r1 - r0), c1 - c0)
