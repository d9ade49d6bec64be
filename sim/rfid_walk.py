"""The paper's closed-loop walk with the user's pose taken from RFID, not the truth.

The loop is ``closed_loop.run_walk`` with the daemon's own ``Navigator``: the obstacle sensor
reveals what it sees from where the user truly stands (its own registration, as a camera-based
mapper has), but the pose the navigator is given comes from the localiser: the reader's rounds
are drawn at the user's true position as they walk (``RfidPoses``), and the localiser turns
them into a pose. The navigator reads the path from the pose's cell — leading out of the
inflation margin itself when a pose error puts the estimate there — and the user takes the
step that path asks for (its first move) from where they truly stand (``CellStepper``). A step
into a truly occupied cell is a collision: the user stays put. Guidance ends when the
navigator says ARRIVED on the *estimated* pose; the true distance to the goal at that moment
is what the test judges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.grid import OCCUPIED, Cell, cell_to_xy, in_bounds, xy_to_cell
from drivers.rfid.localiser import DEFAULT_METHOD, Localiser
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tags import TagMap
from protocol.messages import Pose

from .closed_loop import run_walk
from .courtyard import Scenario
from .world import WalkerView, World

WARM_UP_S = 1.0
"""Reader time the user stands at the start while the localiser's median windows fill."""


@dataclass
class RfidWalkResult:
    arrived: bool
    reason: str
    steps: int
    """Navigator steps (one per action, the arriving one included)."""
    collisions: int
    final_error_m: float
    """True distance from the user to the goal's centre when guidance ended."""
    pose_errors: np.ndarray = field(repr=False)
    walked: np.ndarray = field(repr=False)

    @property
    def pose_error_median_m(self) -> float:
        return float(np.median(self.pose_errors)) if self.pose_errors.size else math.nan


@dataclass
class CellStepper:
    """Takes the move the path asks for (``path[1] - path[0]``, planned from the *estimated*
    cell) from the cell the user truly stands on, ``offset`` metres off its centre."""

    x: float
    y: float
    heading: float
    shape: tuple[int, int]
    cell_m: float
    offset: np.ndarray
    collisions: int = 0

    def act(self, view: WalkerView) -> str:
        path = view.path
        if path is None or len(path) < 2:
            return "stand"  # no pose yet, or no path: the belt says wait
        dr, dc = int(path[1][0] - path[0][0]), int(path[1][1] - path[0][1])
        here = xy_to_cell(self.shape, self.x, self.y, self.cell_m)
        nxt = (here[0] + dr, here[1] + dc)
        self.heading = math.atan2(-dr, dc)
        if not in_bounds(self.shape, nxt) or view.true[nxt] == OCCUPIED:
            self.collisions += 1
            return "bump"
        self.x, self.y = self.where(nxt)
        return "step"

    def where(self, cell: Cell) -> tuple[float, float]:
        x, y = cell_to_xy(self.shape, cell, self.cell_m)
        return x + float(self.offset[0]), y + float(self.offset[1])


class RfidPoses:
    """The ``PoseSource``: reader rounds along the walker's true track since the last call,
    then the localiser's estimate (the last one while too few tags answer)."""

    def __init__(
        self, tag_map: TagMap, method: str, seed: int, round_hz: float, uhf_every: int
    ) -> None:
        self.model = ReadModel.for_tags(tag_map, seed=seed)
        self.loc = Localiser(tag_map, method=method)
        self.round_hz = round_hz
        self.uhf_every = uhf_every
        self.rounds = 0
        self.t = 0.0  # reader clock: the walk's clock plus the warm-up
        self.at: np.ndarray | None = None
        self.last: Pose | None = None
        self.errors: list[float] = []

    def __call__(self, world: World, now: float) -> Pose | None:
        p1 = np.array([world.walker.x, world.walker.y])
        if self.at is None:
            self._listen(p1, p1, WARM_UP_S)
        else:
            self._listen(self.at, p1, now + WARM_UP_S - self.t)
        self.at = p1
        est = self.loc.estimate(self.t)
        if est is None:
            return self.last
        self.errors.append(math.hypot(est.x - p1[0], est.y - p1[1]))
        self.last = Pose(x=est.x, y=est.y, heading=est.heading, stamp=now)
        return self.last

    def _listen(self, p0: np.ndarray, p1: np.ndarray, dt: float) -> None:
        """Reader rounds while the user moves in a straight line from p0 to p1 over dt."""
        if dt <= 0:
            return
        n = max(1, round(dt * self.round_hz))
        t0 = self.t
        for i in range(1, n + 1):
            x, y = p0 + (p1 - p0) * i / n
            self.t = t0 + dt * i / n
            uhf = self.rounds % self.uhf_every == 0
            for read in self.model.round(float(x), float(y), self.t, int(self.t * 1000), uhf):
                self.loc.add(read)
            self.rounds += 1


def rfid_walk(
    scenario: Scenario,
    tag_map: TagMap,
    *,
    backend: str = "cpu",
    method: str = DEFAULT_METHOD,
    seed: int = 0,
    speed_mps: float = 1.0,
    round_hz: float = 50.0,
    uhf_every: int = 5,
    max_steps: int | None = None,
    arrive_m: float = 0.15,
    offset_m: tuple[float, float] = (0.0, 0.0),
) -> RfidWalkResult:
    """Walk with RFID poses; ``offset_m`` (under half a cell) shifts the user off the cell
    centres, so that the floor tags' lattice and the walk do not line up by construction."""
    from daemon.navigation import Navigator, NavigatorSettings

    from .walks import user_radius_m

    shape, cell_m = scenario.shape, scenario.cell_m
    max_steps = max_steps if max_steps is not None else 6 * (shape[0] + shape[1])
    off = np.asarray(offset_m, dtype=float)
    if np.any(np.abs(off) >= cell_m / 2):
        raise ValueError("offset_m must stay within half a cell")
    walker = CellStepper(0.0, 0.0, math.pi / 2, shape, cell_m, off)
    walker.x, walker.y = walker.where(scenario.start)
    settings = NavigatorSettings(
        backend=backend,
        cell_m=cell_m,
        user_radius_m=user_radius_m(scenario),
        arrive_m=arrive_m,  # judged on the estimate, from the goal cell's centre
    )
    navigator = Navigator("rfid", settings)
    poses = RfidPoses(tag_map, method, seed, round_hz, uhf_every)
    # One action a cell at walking speed; a pose error may leave the user briefly without a
    # path (or a pose), so the walk waits instead of ending there.
    done = run_walk(World(scenario, walker), navigator, max_actions=max_steps,
                    step_s=cell_m / speed_mps, pose_source=poses,
                    stop_on_no_path=False)  # fmt: skip
    goal_xy = np.array(cell_to_xy(shape, scenario.goal, cell_m))
    return RfidWalkResult(
        arrived=done.arrived,
        reason="step limit" if done.reason == "action limit" else done.reason,
        steps=len(done.reports),
        collisions=walker.collisions,
        final_error_m=float(math.hypot(walker.x - goal_xy[0], walker.y - goal_xy[1])),
        pose_errors=np.array(poses.errors),
        walked=np.array(done.walked, dtype=np.int32),
    )
