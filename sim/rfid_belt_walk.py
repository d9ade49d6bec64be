"""Closed loop by RFID alone: a belt walker guided by the filtered RFID pose, never the truth.

The walker (``belt_walker.BeltWalker``) feels the belt and steps; the obstacle sensor sees
from where the walker really is (``World.sense``); the navigator — the daemon's own — is
given only the pose the filter (``drivers.rfid.pose_filter``) makes of what the reader and a
belt IMU report along the walker's true movement: reader rounds drawn from the RSSI model in
the paper's setting (1.5 m UHF field, tags on obstacle corners, LF patches at crossings), one
pedometer step per walker step and the compass (``sim.pedometer``). Its pose carries
``sigma_m``, so the daemon enlarges obstacles by ω/2 + a and says WAIT when it is unsure.

A walk succeeds when the navigator says ARRIVED (on the estimated pose) with the walker truly
within ``success_m`` of the goal, with no collision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.grid import OCCUPIED, UNKNOWN, cell_to_xy, xy_to_cell
from drivers.rfid.map_match import contact_likelihood, free_space_likelihood, obstacle_likelihood
from drivers.rfid.pose_filter import PoseFilter
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tag_payload import ObstacleBook
from drivers.rfid.tags import TagMap
from protocol.messages import Pose, Proximity

from .belt_walker import BeltWalker, WalkerParams
from .closed_loop import STEP_S, run_walk
from .courtyard import Scenario
from .pedometer import Imu
from .rfid_eval import PAPER, tags_for
from .world import World

WARM_UP_S = 1.0
"""The user stands at the start this long while the first reads come in."""
MATCHES = ("camera", "contact", "none")
"""What the filter matches against the daemon's map besides the tags: the camera's nearest
obstacle and any bump, a bump only, or nothing (``drivers.rfid.map_match``)."""
MATCH_EVERY_S = 1.0
"""The camera's nearest obstacle is matched against the map at most this often: the same
blob seen again a moment later is not a new, independent measurement."""
MATCH_WITHIN_M = 1.5
SUCCESS_M = 0.5
"""Truly this close to the goal when the navigator says ARRIVED: the user is there."""


@dataclass
class RfidBeltWalk:
    arrived: bool
    """ARRIVED on the estimated pose with the walker truly within ``SUCCESS_M``."""
    reason: str
    collisions: int
    final_error_m: float
    actions: int
    waits: int
    """Steps whose pattern was WAIT (pose too unsure, or the map out of date)."""
    pose_errors: np.ndarray = field(repr=False)
    heading_errors: np.ndarray = field(repr=False)
    sigmas: np.ndarray = field(repr=False)


class EstimatedFrameWorld(World):
    """The world whose mapper writes what the sensor sees at the *estimated* pose.

    The obstacle sensor looks from where the walker truly stands, but a real mapper places
    what it sees relative to where the localiser says the user is: a pose error shifts the
    new cells by the same error (the heading's few degrees of rotation are left out). The
    surveyed obstacles — those the tags carry — stay where the survey put them; a shifted
    view never writes over them.
    """

    def __init__(self, scenario: Scenario, walker) -> None:
        super().__init__(scenario, walker)
        self.estimate: tuple[float, float] | None = None
        self._surveyed = (scenario.known == OCCUPIED).reshape(-1)

    def sense(self, stamp: float) -> list:
        true_cell = self.cell()
        seen = self.sensor.visible(self.true.shape, true_cell, self.walker.heading)
        values = self.true.reshape(-1)[seen]
        h, w = self.shape
        dr = dc = 0
        if self.estimate is not None:
            est = xy_to_cell(self.shape, self.estimate[0], self.estimate[1], self.cell_m)
            dr, dc = est[0] - true_cell[0], est[1] - true_cell[1]
        rows, cols = seen // w + dr, seen % w + dc
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        cells = rows[inside] * w + cols[inside]
        values = values[inside]
        keep = ~self._surveyed[cells] & (self.known.reshape(-1)[cells] != values)
        return self._deltas(cells[keep], values[keep], stamp)


class TagMapWorld(World):
    """The world whose daemon is given no survey: the map is what the tags carry (the
    obstacle book of the UHF tags read so far) and what the camera sees. The outer walls
    are the building's and stay known."""

    def __init__(self, scenario: Scenario, walker, book: ObstacleBook) -> None:
        super().__init__(scenario, walker)
        self.book = book
        walls = np.zeros(self.shape, dtype=bool)
        walls[[0, -1], :] = walls[:, [0, -1]] = True
        self.known = np.where(walls, self.known, UNKNOWN).astype(self.known.dtype)

    def sense(self, stamp: float) -> list:
        got = self.book.delta(0, stamp)
        out = []
        if got is not None:
            cells = np.frombuffer(got.cells, "<u4").astype(np.int64)
            values = np.frombuffer(got.values, np.uint8)
            new = self.known.reshape(-1)[cells] != values
            out += self._deltas(cells[new], values[new], stamp)
        return out + super().sense(stamp)


class FilteredRfidPoses:
    """The ``PoseSource``: reader rounds and IMU reports along the walker's true movement
    since the last call, then the filter's pose (with its ``sigma_m``)."""

    def __init__(
        self,
        tag_map: TagMap,
        start: tuple[float, float],
        *,
        seed: int,
        uhf_range_m: float = PAPER.uhf_range_m,
        round_hz: float = 50.0,
        uhf_every: int = 5,
        pose_every: int = 5,
        match: str = "camera",
        memories: dict[str, bytes] | None = None,
        book: ObstacleBook | None = None,
    ) -> None:
        """``memories``/``book``: the UHF tags' user memory, read once per tag the first
        time it answers, into the obstacle book the walk's map is built from."""
        self.memories = memories or {}
        self.book = book
        self.model = ReadModel.for_tags(tag_map, seed=seed, uhf_range_m=uhf_range_m)
        self.imu = Imu(seed=seed + 7919)
        self.filter = PoseFilter(tag_map, start=start, pedometer=True)
        self.round_dt = 1.0 / round_hz
        self.uhf_every = uhf_every
        self.pose_every = pose_every
        self.rounds = 0
        self.bumps = 0
        self.streak = 0
        self.t = 0.0
        self.at: tuple[float, float, float] | None = None
        self.errors: list[float] = []
        self.heading_errors: list[float] = []
        self.sigmas: list[float] = []
        self.match = match
        self._matched_t = -math.inf

    def __call__(self, world: World, now: float) -> Pose | None:
        w = world.walker
        here = (w.x, w.y, w.heading)
        if getattr(w, "collisions", 0) > self.bumps:  # felt through the IMU as a jolt
            self.bumps = w.collisions
            # The n-th bump in a row without a step between adds n times the bump's
            # variance: each one says again that the pose is off by more than its margin.
            # With one each, a user pressed against a blob the estimate put 0.3-0.5 m away
            # bumped 50-200 times, the UHF fixes pulling the estimate back after each
            # contact match; with n, 9-25 times before WAIT (14 failing walks, 3 levels).
            self.streak += 1
            for _ in range(self.streak):
                self.filter.bump(self.t)
            if self.match != "none":  # and it says where: an obstacle within a step ahead
                heading = self.filter.heading
                like = contact_likelihood(world.known, world.cell_m, heading, _reach(w))
                self.filter.constrain(self.t, like)
        if self.at is None:
            self._listen(here, here, WARM_UP_S, stepped=False)
        else:
            self._listen(self.at, here, now + WARM_UP_S - self.t, stepped=True)
        if self.at is not None and here[:2] != self.at[:2]:
            self.streak = 0
        if self.match == "contact" and self.at is not None and here[:2] != self.at[:2]:
            # After each step: the user stands on free floor. Applied only when the mean
            # itself fell on an obstacle it changed nothing (40 %, seeds 0-24: 23 of 25
            # arrived, as without it); after every step 25 of 25 (22 against 24 once the
            # bump's reach followed the pulse). Not with the camera's match: the ten walks
            # of 100 at 20 and 40 % that failed with both (a bump in seven) all arrived,
            # none bumping, without it (the same map counted again each step on top of the
            # camera's pulls).
            self.filter.constrain(self.t, free_space_likelihood(world.known, world.cell_m))
        self.at = here
        pose = self.filter.pose(self.t)
        if pose is None:
            return None
        if self.match == "camera" and self.t - self._matched_t >= MATCH_EVERY_S:
            seen = camera_proximity(world, now)
            if seen.nearest_m is not None and seen.nearest_m <= MATCH_WITHIN_M:
                like = obstacle_likelihood(world.known, world.cell_m, pose.heading,
                                           seen.nearest_m, seen.bearing or 0.0)  # fmt: skip
                if self.filter.constrain(self.t, like):
                    self._matched_t = self.t
                    pose = self.filter.pose(self.t)
                    assert pose is not None
        self.errors.append(math.hypot(pose.x - w.x, pose.y - w.y))
        self.heading_errors.append(abs(_wrap(pose.heading - w.heading)))
        self.sigmas.append(pose.sigma_m)
        if isinstance(world, EstimatedFrameWorld):
            world.estimate = (pose.x, pose.y)
        return Pose(x=pose.x, y=pose.y, heading=pose.heading, stamp=now,
                    quality=pose.quality, sigma_m=min(pose.sigma_m, 100.0))  # fmt: skip

    def _listen(self, a: tuple, b: tuple, dt: float, stepped: bool) -> None:
        """Rounds along a → b over ``dt``; a step (if the walker moved) ends the stretch."""
        if dt <= 0:
            return
        n = max(1, round(dt / self.round_dt))
        t0 = self.t
        moved = math.hypot(b[0] - a[0], b[1] - a[1])
        for i in range(1, n + 1):
            f = i / n
            self.t = t0 + dt * f
            x, y = a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f
            uhf = self.rounds % self.uhf_every == 0
            for read in self.model.round(x, y, self.t, int(self.t * 1000), uhf=uhf):
                self.filter.add(read)
                memory = self.memories.pop(read.tag_id, None)
                if memory is not None and self.book is not None:
                    self.book.read(memory)
            self.rounds += 1
            if self.rounds % self.pose_every == 0 and i < n:
                # The compass follows the body as it turns; the filter folds its reads.
                heading = b[2] if moved < 1e-9 else a[2] + _wrap(b[2] - a[2]) * f
                self.filter.compass(self.t, self.imu.compass(heading))
                self.filter.pose(self.t)
        if stepped and moved > 1e-9:
            way = math.atan2(b[1] - a[1], b[0] - a[0])
            self.filter.step(self.t, self.imu.step(moved), self.imu.compass(way))
        else:
            self.filter.compass(self.t, self.imu.compass(b[2]))
            if stepped:  # an action with no step: the IMU felt the user stand
                self.filter.still(self.t)


def _reach(walker) -> float:
    """How far the bumped step would have gone: the belt's pulse shortens the user's steps
    near an obstacle (``BeltWalker``'s rule: down to a quarter at the fastest pulse), and
    the belt's driver knows the pattern it played. With the full step as the reach, a user
    pulsed to quarter steps against a blob 0.3 m from the estimate learnt nothing from 48
    bumps (40 %, seed 7): the estimate already had the blob within a step."""
    p = walker.params
    period = getattr(walker, "last_period_ms", 0)
    factor = max(p.slow_factor, min(1.0, period / 800.0)) if period > 0 else 1.0
    return (p.step_m + 2.0 * p.step_sd_m) * factor


class PulseAwareWalker(BeltWalker):
    """The belt walker, with the pulse period of the last pattern it stepped on kept (what
    the belt's own driver knows it played)."""

    last_period_ms: int = 0

    def react(self, pattern, occupancy: np.ndarray) -> str:
        if str(pattern.kind) == "guide":
            self.last_period_ms = int(pattern.period_ms)
        return super().react(pattern, occupancy)


CORRIDOR_M = 0.2
"""The camera's walking corridor either side of the heading (the mapper's ``corridor_m``)."""


def camera_proximity(world: World, now: float) -> Proximity:
    """The depth camera's nearest obstacles, as the mapper reports them, from where the walker
    truly is (what the camera sees does not depend on the RFID pose): the daemon's STOP
    before contact. Distances and the corridor as ``mapper.proximity`` measures them.

    The field of view is taken from the walker's own position, a cell in view when any of
    its corners is: the sensor's cell-centre view (``Sensor.visible``, the map's view of
    things) missed a cell 8 cm ahead of a walker standing at the corner of its own cell,
    its centre 45° off, and the walker stepped into it (20 %, seed 13, `contact`)."""
    w = world.walker
    cell = world.cell_m
    h, width = world.shape
    reach = world.sensor.range_cells * cell
    r0, r1 = (
        max(0, int((h * cell - w.y - reach) / cell)),
        min(h, int((h * cell - w.y + reach) / cell) + 1),
    )
    c0, c1 = max(0, int((w.x - reach) / cell)), min(width, int((w.x + reach) / cell) + 1)
    rows, cols = np.nonzero(world.true[r0:r1, c0:c1] == OCCUPIED)
    if rows.size == 0:
        return Proximity(frame_stamp=now, stamp=now)
    rows, cols = rows + r0, cols + c0
    left, bottom = cols * cell, (h - 1 - rows) * cell
    half = math.radians(world.sensor.fov_deg) / 2
    seen = (rows == world.cell()[0]) & (cols == world.cell()[1])  # the walker's own cell
    for cx in (0.0, cell):
        for cy in (0.0, cell):
            off = np.arctan2(bottom + cy - w.y, left + cx - w.x) - w.heading
            seen |= np.abs((off + math.pi) % (2 * math.pi) - math.pi) <= half
    # As the mapper measures (``mapper.proximity``): to the cell's centre, less half a cell.
    dx = left + cell / 2 - w.x
    dy = bottom + cell / 2 - w.y
    dist = np.maximum(np.hypot(dx, dy) - cell / 2, 0.0)
    seen &= dist <= reach
    if not seen.any():
        return Proximity(frame_stamp=now, stamp=now)
    dx, dy, dist = dx[seen], dy[seen], dist[seen]
    fwd = dx * math.cos(w.heading) + dy * math.sin(w.heading)
    side = -dx * math.sin(w.heading) + dy * math.cos(w.heading)
    i = int(np.argmin(dist))
    lane = (fwd > -cell / 2) & (np.abs(side) <= CORRIDOR_M + cell / 2)
    ahead = float(np.maximum(fwd[lane] - cell / 2, 0.0).min()) if lane.any() else None
    return Proximity(ahead_m=ahead, nearest_m=float(dist[i]),
                     bearing=math.atan2(side[i], fwd[i]), frame_stamp=now, stamp=now)  # fmt: skip


def rfid_belt_walk(
    scenario: Scenario,
    *,
    seed: int = 0,
    tag_map: TagMap | None = None,
    backend: str = "cpu",
    uhf_range_m: float = PAPER.uhf_range_m,
    max_actions: int | None = None,
    register: str = "true",
    proximity: bool = True,
    match: str = "camera",
) -> RfidBeltWalk:
    """One belt walk of ``scenario`` guided by the RFID pose filter, noise seeded by ``seed``.

    ``register``: where the mapper puts what the sensor sees — ``true`` (its own
    registration, as a camera-based mapper has: the project's walks all assume it) or
    ``estimate`` (at the RFID pose: ``EstimatedFrameWorld``), or ``tags``: no survey, the
    daemon's map is built from the UHF tags' memory as they are read (``TagMapWorld``,
    ``ObstacleBook``) and from what the camera sees, registered where it truly is.
    """
    if register not in ("true", "estimate", "tags"):
        raise ValueError(f"register {register!r}: choose true, estimate or tags")
    if match not in MATCHES:
        raise ValueError(f"match {match!r}: choose one of {MATCHES}")
    from daemon.navigation import Navigator

    from .walks import belt_settings, optimal_m

    if tag_map is None:
        tag_map = tags_for(scenario, PAPER.lf_layouts[0], seed, edge_spacing_m=PAPER.edge_spacing_m)
    settings = belt_settings(scenario, backend)
    navigator = Navigator("rfid-walker", settings)
    x, y = cell_to_xy(scenario.shape, scenario.start, scenario.cell_m)
    params = WalkerParams()
    walker = PulseAwareWalker(x=x, y=y, heading=math.pi / 2, cell_m=scenario.cell_m, params=params,
                        rng=np.random.default_rng(seed))  # fmt: skip
    book = memories = None
    if register == "tags":
        from .tag_payloads import tag_memories

        book = ObstacleBook(scenario.shape, scenario.cell_m)
        memories = tag_memories(tag_map, scenario.known, scenario.cell_m)
    poses = FilteredRfidPoses(tag_map, (x, y), seed=seed, uhf_range_m=uhf_range_m, match=match,
                              memories=memories, book=book)  # fmt: skip
    limit = max_actions or int(8 * optimal_m(scenario) / params.step_m) + 150
    if book is not None:
        world: World = TagMapWorld(scenario, walker, book)
    else:
        world = (EstimatedFrameWorld if register == "estimate" else World)(scenario, walker)
    done = run_walk(world, navigator, max_actions=limit, step_s=STEP_S, pose_source=poses,
                    stop_on_no_path=False,
                    proximity_source=camera_proximity if proximity else None)  # fmt: skip
    gx, gy = cell_to_xy(scenario.shape, scenario.goal, scenario.cell_m)
    final = math.hypot(walker.x - gx, walker.y - gy)
    ok = done.arrived and final <= SUCCESS_M
    reason = done.reason if not done.arrived or ok else "arrived off the goal"
    return RfidBeltWalk(
        arrived=ok,
        reason=reason,
        collisions=walker.collisions,
        final_error_m=final,
        actions=len(done.track) - 1,
        waits=sum(b.kind == "wait" for b in done.belts),
        pose_errors=np.array(poses.errors),
        heading_errors=np.array(poses.heading_errors),
        sigmas=np.array(poses.sigmas),
    )


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
