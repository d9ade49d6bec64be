"""The paper's closed-loop walk with the user's cell for planning taken from RFID poses.

As ``sim.walk`` — sense, inflate, repair the field, step one cell — except that the
planner never sees the true position: the reader's rounds are drawn at the user's true
position as they walk, the localiser turns them into a pose, and the path is read from
the pose's cell. The user then takes the step the belt asks for (the path's first move)
from where they truly stand. A step into a truly occupied cell is a collision: the user
stays put. Guidance ends when the *estimated* cell is the goal; the true distance to the
goal at that moment is what the test judges.

The obstacle sensor still reveals cells around the true position (its own registration,
as a camera-based mapper has); only the planning cell comes from RFID.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from daemon.planning import make_planner
from daemon.planning.grid import (
    INF,
    OCCUPIED,
    Cell,
    cell_to_xy,
    in_bounds,
    xy_to_cell,
)
from daemon.planning.inflation import InflatedMap
from daemon.planning.interface import GlobalPlanner
from drivers.rfid.localiser import DEFAULT_METHOD, Localiser
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tags import TagMap
from sim.sensor import Sensor


@dataclass
class RfidWalkResult:
    arrived: bool
    reason: str
    steps: int
    collisions: int
    final_error_m: float
    """True distance from the user to the goal's centre when guidance ended."""
    pose_errors: np.ndarray = field(repr=False)
    walked: np.ndarray = field(repr=False)

    @property
    def pose_error_median_m(self) -> float:
        return float(np.median(self.pose_errors)) if self.pose_errors.size else math.nan


def planning_cell(planner: GlobalPlanner, cell: Cell, reach: int = 3) -> Cell | None:
    """``cell``, or the nearest cell within ``reach`` that has a path to the goal.

    A pose error can put the estimate inside an inflated obstacle; the user is not there,
    so plan from the closest cell they could be in (nearest first, then cheapest).
    """
    if in_bounds(planner.shape, cell) and planner.cost_at(cell) < INF:
        return cell
    best: tuple[int, int, Cell] | None = None
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            n = (cell[0] + dr, cell[1] + dc)
            g = planner.cost_at(n)
            if g < INF:
                key = (dr * dr + dc * dc, g, n)
                best = key if best is None or key < best else best
    return None if best is None else best[2]


def rfid_walk(
    scenario,
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
    shape, cell_m = scenario.shape, scenario.cell_m
    max_steps = max_steps if max_steps is not None else 6 * (shape[0] + shape[1])
    planner = make_planner("eds", backend)
    sensor = Sensor(scenario.sensor_range_cells)
    inflated = InflatedMap(scenario.known, scenario.radius_cells)
    planner.plan(inflated.blocked, scenario.goal)
    model = ReadModel.for_tags(tag_map, seed=seed)
    loc = Localiser(tag_map, method=method)
    goal_xy = np.array(cell_to_xy(shape, scenario.goal, cell_m))
    off = np.asarray(offset_m, dtype=float)
    if np.any(np.abs(off) >= cell_m / 2):
        raise ValueError("offset_m must stay within half a cell")

    def where(cell: Cell) -> np.ndarray:
        return np.array(cell_to_xy(shape, cell, cell_m)) + off

    true_cell = scenario.start
    heading = math.pi / 2
    t, k = 0.0, 0
    errors, walked = [], [true_cell]
    collisions, reason = 0, "step limit"

    def listen(p0: np.ndarray, p1: np.ndarray, dt: float) -> None:
        """Reader rounds while the user moves from p0 to p1 over dt seconds."""
        nonlocal t, k
        n = max(1, round(dt * round_hz))
        for i in range(1, n + 1):
            x, y = p0 + (p1 - p0) * i / n
            t += dt / n
            for read in model.round(float(x), float(y), t, int(t * 1000), k % uhf_every == 0):
                loc.add(read)
            k += 1

    p = where(true_cell)
    listen(p, p, 1.0)  # standing at the start while the median windows fill
    steps = 0
    for steps in range(1, max_steps + 1):  # noqa: B007 (the count is reported)
        est = loc.estimate(t)
        if est is None:
            listen(p, p, 0.1)  # no pose: the belt says wait
            continue
        errors.append(math.hypot(est.x - p[0], est.y - p[1]))
        if math.hypot(est.x - goal_xy[0], est.y - goal_xy[1]) <= arrive_m:
            reason = "arrived"
            break
        cells, values = sensor.sense(scenario.true, inflated.occupancy, true_cell, heading)
        flipped, now = inflated.apply(cells, values)
        planner.update(flipped, now)
        start = planning_cell(planner, xy_to_cell(shape, est.x, est.y, cell_m))
        path = planner.path(start) if start is not None else np.empty((0, 2))
        if len(path) < 2:
            if start == scenario.goal:  # on the goal cell but not yet within arrive_m
                path = np.array([start, start])
            else:
                listen(p, p, 0.1)
                continue
        dr, dc = int(path[1][0] - path[0][0]), int(path[1][1] - path[0][1])
        if dr == 0 and dc == 0:
            # Estimated on the goal cell: head for the goal centre from the estimate.
            v = goal_xy - np.array([est.x, est.y])
            dc, dr = int(np.sign(round(v[0] / cell_m))), -int(np.sign(round(v[1] / cell_m)))
        nxt = (true_cell[0] + dr, true_cell[1] + dc)
        heading = math.atan2(-dr, dc) if (dr or dc) else heading
        dt = math.hypot(dr, dc) * cell_m / speed_mps if (dr or dc) else 0.1
        if not in_bounds(shape, nxt) or scenario.true[nxt] == OCCUPIED:
            collisions += 1
            listen(p, p, dt)
            continue
        p1 = where(nxt)
        listen(p, p1, dt)
        p, true_cell = p1, nxt
        walked.append(true_cell)
    final = float(math.hypot(*(p - goal_xy)))
    return RfidWalkResult(
        arrived=reason == "arrived",
        reason=reason,
        steps=steps,
        collisions=collisions,
        final_error_m=final,
        pose_errors=np.array(errors),
        walked=np.array(walked, dtype=np.int32),
    )
