"""The simulated world guided through the daemon by RFID poses instead of the true pose.

``RfidSimNode`` is the sim's zenoh node (``sim.node.SimNode``: true map, sensor
deltas, lock step with the daemon) with its localiser replaced: each pose it publishes is
what the reader would report along the user's true movement since the last pose — lines
in the reader's protocol, through the same ``ReadFilter`` as the serial driver, into the
``Localiser``. The daemon plans from that pose's cell and judges arrival from it.

The user takes the step the path asks for (from the estimated cell to the next) from
where they truly stand, as a person following the belt would; a step into an obstacle
is a bump and they stay put.
"""

from __future__ import annotations

import math
import time

import numpy as np

from daemon.planning.grid import cell_to_xy
from drivers.rfid.localiser import DEFAULT_METHOD, Estimate, Localiser
from drivers.rfid.protocol import Read, ReadFilter, format_read
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tags import TagMap
from protocol import codec
from protocol.messages import Pose
from sim.belt_walker import step_hits
from sim.node import SimNode
from sim.world import LOOKAHEAD_M, PathWalker, WalkerView, heading_along


class RelativeWalker(PathWalker):
    """Takes the path's first move relative to the true position, not to the planned cell."""

    def act(self, view: WalkerView) -> str:
        path = view.path
        if path is None or len(path) < 2:
            return "stand"
        shape = view.true.shape
        x0, y0 = cell_to_xy(shape, (int(path[0][0]), int(path[0][1])), self.cell_m)
        x1, y1 = cell_to_xy(shape, (int(path[1][0]), int(path[1][1])), self.cell_m)
        nx, ny = self.x + (x1 - x0), self.y + (y1 - y0)
        if step_hits(view.true, self.cell_m, self.x, self.y, nx, ny):
            self.collisions += 1
            return "bump"
        self.x, self.y = nx, ny
        lookahead = max(1, round(LOOKAHEAD_M / self.cell_m))
        self.heading = heading_along(path[1:], lookahead, self.heading)
        return "step"


class RfidSimNode(SimNode):
    def __init__(
        self,
        session,
        user: str,
        scenario,
        tag_map: TagMap,
        *,
        method: str = DEFAULT_METHOD,
        seed: int = 0,
        speed_mps: float = 1.0,
        round_hz: float = 50.0,
        uhf_every: int = 5,
        offset_m: tuple[float, float] = (0.0, 0.0),
        **kw,
    ) -> None:
        """``offset_m`` (under half a cell) puts the user off the cell centres, so that the
        floor tags' lattice and the walk do not line up by construction."""
        super().__init__(session, user, scenario, **kw)
        if max(abs(offset_m[0]), abs(offset_m[1])) >= scenario.cell_m / 2:
            raise ValueError("offset_m must stay within half a cell")
        w = self.walker
        self.walker = RelativeWalker(
            w.x + offset_m[0], w.y + offset_m[1], w.heading, scenario.cell_m
        )
        self.model = ReadModel.for_tags(tag_map, seed=seed)
        self.filter = ReadFilter(tag_map.ids)
        self.localiser = Localiser(tag_map, method=method)
        self.speed_mps = speed_mps
        self.round_dt = 1.0 / round_hz
        self.uhf_every = uhf_every
        self.sim_t = 0.0
        self._rounds = 0
        self._last_xy = (w.x, w.y)
        self.pose_errors: list[float] = []
        self.last_estimate: Estimate | None = None
        self._listen(1.0)  # standing at the start while the median windows fill

    def _listen(self, min_s: float) -> None:
        """Reader rounds along the move since the last pose (at least ``min_s`` of them)."""
        x0, y0 = self._last_xy
        x1, y1 = self.walker.x, self.walker.y
        dt = max(min_s, math.hypot(x1 - x0, y1 - y0) / self.speed_mps)
        n = max(1, round(dt / self.round_dt))
        for i in range(1, n + 1):
            f = i / n
            self.sim_t += dt / n
            uhf = self._rounds % self.uhf_every == 0
            self._rounds += 1
            reads = self.model.round(
                x0 + (x1 - x0) * f, y0 + (y1 - y0) * f, self.sim_t, int(self.sim_t * 1000), uhf=uhf
            )
            for r in reads:
                read = self.filter.feed(format_read(r.tag_id, r.rssi, r.reader_ms), self.sim_t)
                if isinstance(read, Read):
                    self.localiser.add(read)
        self._last_xy = (x1, y1)

    def _send_pose(self) -> float:
        self._listen(0.05)
        stamp = time.time()
        est = self.localiser.estimate(self.sim_t)
        if est is None:
            return stamp  # no pose: the daemon's staleness check stops the guidance
        self.last_estimate = est
        self.pose_errors.append(math.hypot(est.x - self.walker.x, est.y - self.walker.y))
        pose = Pose(x=est.x, y=est.y, heading=est.heading, stamp=stamp, quality=est.quality)
        self._pub_pose.put(codec.encode(pose))
        return stamp

    def true_error_to(self, cell: tuple[int, int]) -> float:
        gx, gy = cell_to_xy(self.shape, cell, self.cell_m)
        return float(np.hypot(self.walker.x - gx, self.walker.y - gy))
