"""How well the localiser finds a user walking the simulated courtyard.

The user walks the shortest route of the true courtyard (inflated by their radius) at a
steady speed — not on the cell centres: the whole route is shifted by ``offset`` and the
user sways ``sway_m`` to either side every ``sway_period_s``, so that the floor tags'
lattice and the walk do not line up by construction. The reader polls its LF antenna
every ``1/round_hz`` s and runs a UHF inventory every ``uhf_every`` polls, drawn from the
RSSI model (as ``MockReader`` does); the localiser estimates at ``pose_hz``; the error is
the distance from each estimate to where the user truly was at that moment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import OCCUPIED, cell_to_xy
from drivers.rfid.localiser import Localiser
from drivers.rfid.pose_filter import FilterParams, PoseFilter
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tags import TagMap, generate

from .pedometer import Imu


@dataclass(frozen=True)
class Setting:
    """Where the tags are and how far the UHF reader reaches."""

    name: str
    uhf_range_m: float
    edge_spacing_m: float
    """UHF tags along straight obstacle edges this far apart (inf: corners only)."""
    lf_layouts: tuple[str, ...]


PAPER = Setting("paper", 1.5, math.inf, ("crossings",))
"""Chen et al.: a reader field of ~1.5 m radius, UHF tags on the obstacles' feature points
(their corners), LF patches at the intersections (Figure 4)."""
DENSE = Setting("dense", 5.0, 2.0, ("none", "corners", "floor"))
"""guidebelt's first set-up: 5 m reads, a tag every 2 m of wall, LF over the whole floor."""
SETTINGS = {s.name: s for s in (PAPER, DENSE)}


def tags_for(
    scenario, lf_layout: str = "floor", seed: int = 0, edge_spacing_m: float = 2.0
) -> TagMap:
    """Tags placed on the scenario's known obstacles (what a venue would survey); with
    ``crossings``, a patch at the scenario's goal too (the landmark the user asks for)."""
    known_occupied = scenario.known == OCCUPIED
    goal = np.array([cell_to_xy(scenario.shape, scenario.goal, scenario.cell_m)])
    return generate(known_occupied, scenario.cell_m, seed=seed, lf_layout=lf_layout,
                    edge_spacing_m=edge_spacing_m, landmarks_xy=goal)  # fmt: skip


def true_route(scenario) -> np.ndarray:
    """(k, 2) metres: the cell centres of the shortest route in the true, inflated map."""
    from sim.courtyard import dilate

    blocked = dilate(scenario.true == OCCUPIED, scenario.radius_cells)
    g = dijkstra_field(blocked, scenario.goal)
    cells = reference_path(g, blocked, scenario.start)
    if len(cells) == 0:
        raise ValueError("the scenario's start cannot reach its goal")
    shape, cell_m = scenario.shape, scenario.cell_m
    return np.array([cell_to_xy(shape, (int(r), int(c)), cell_m) for r, c in cells])


def along(route: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``s`` along a polyline (clamped to its ends)."""
    seg = np.hypot(*np.diff(route, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.clip(s, 0.0, cum[-1])
    return np.column_stack([np.interp(s, cum, route[:, 0]), np.interp(s, cum, route[:, 1])])


def walked(
    route: np.ndarray, s: np.ndarray, offset: tuple[float, float], sway_m: float, period_m: float
) -> np.ndarray:
    """Where the user is at arc lengths ``s``: the route shifted, with a side-to-side sway."""
    centre = along(route, s)
    ahead = along(route, s + 0.15) - along(route, s - 0.15)
    norm = np.maximum(np.hypot(ahead[:, 0], ahead[:, 1]), 1e-9)
    side = np.column_stack([-ahead[:, 1], ahead[:, 0]]) / norm[:, None]
    return centre + np.asarray(offset) + side * (sway_m * np.sin(2 * np.pi * s / period_m))[:, None]


@dataclass(frozen=True)
class EvalResult:
    method: str
    lf_layout: str
    errors: np.ndarray
    """Error of each estimate made (instants with a pose only: today's figure)."""
    lf_fraction: float
    """Share of estimates from floor tags: read now, or held from one read < 0.3 s ago."""
    held_fraction: float = 0.0
    """Of those, the share held (dead-reckoned from the last floor tags)."""
    all_errors: np.ndarray = field(default_factory=lambda: np.empty(0))
    """At every scored instant: the error of the latest pose the user has (inf before any)."""
    heading_errors: np.ndarray = field(default_factory=lambda: np.empty(0))
    """|heading − true heading| (rad) at the instants with a pose."""

    @property
    def availability(self) -> float:
        return self.errors.size / max(1, self.all_errors.size)

    def row(self) -> dict:
        return summary_row(self.method, self.lf_layout, [self])


def _pct(a: np.ndarray, q: float) -> float:
    """A percentile that stays inf when it falls on an instant with no pose yet."""
    if not a.size:
        return math.nan
    v = float(np.percentile(np.where(np.isfinite(a), a, 1e9), q, method="higher"))
    return math.inf if v >= 1e9 else round(v, 4)


def summary_row(method: str, lf_layout: str, results: list[EvalResult]) -> dict:
    """One row over several walks: today's figures and those over all instants."""
    errors = np.concatenate([r.errors for r in results])
    every = np.concatenate([r.all_errors for r in results])
    head = np.degrees(np.concatenate([r.heading_errors for r in results]))
    n = max(1, errors.size)
    lf = sum(r.lf_fraction * r.errors.size for r in results) / n
    held = sum(r.held_fraction * r.errors.size for r in results) / n
    return {
        "method": method,
        "lf_tags": lf_layout != "none",
        "lf_layout": lf_layout,
        "availability": round(errors.size / max(1, every.size), 4),
        "median_m": _pct(errors, 50),
        "p95_m": _pct(errors, 95),
        "all_median_m": _pct(every, 50),
        "all_p95_m": _pct(every, 95),
        "heading_median_deg": _pct(head, 50),
        "heading_p95_deg": _pct(head, 95),
        "samples": int(every.size),
        "lf_fraction": round(lf, 3),
        "held_fraction": round(held, 3),
    }


def _angle(a: float) -> float:
    return abs((a + math.pi) % (2 * math.pi) - math.pi)


def evaluate(
    tag_map: TagMap,
    route: np.ndarray,
    *,
    method: str,
    lf_layout: str,
    seed: int = 0,
    speed_mps: float = 1.0,
    round_hz: float = 50.0,
    uhf_every: int = 5,
    pose_hz: float = 10.0,
    offset: tuple[float, float] = (0.0, 0.0),
    sway_m: float = 0.05,
    sway_period_s: float = 2.0,
    step_m: float = 0.5,
    filter_params: FilterParams | None = None,
    **read_kw,
) -> EvalResult:
    """Walk ``route`` once with the reader; score every pose instant after the first second.

    ``method`` ``filter``: the pose filter, fed the reads and a belt IMU's steps (one every
    ``step_m`` walked) and compass; its start prior is the route's start, the place the user
    is known to set out from. Otherwise the localiser with that method (no IMU).
    """
    model = ReadModel.for_tags(tag_map, seed=seed, **read_kw)
    fused = method == "filter"
    loc = None if fused else Localiser(tag_map, method=method)
    imu = Imu(seed=seed + 7919)
    filt = (
        PoseFilter(tag_map, filter_params, start=tuple(route[0]), pedometer=True) if fused else None
    )
    length = float(np.hypot(*np.diff(route, axis=0).T).sum())
    duration = length / speed_mps
    t_rounds = np.arange(0.0, duration, 1.0 / round_hz)
    s_arc = t_rounds * speed_mps
    truth = walked(route, s_arc, offset, sway_m, sway_period_s * speed_mps)
    ahead = along(route, s_arc + 0.15) - along(route, s_arc - 0.15)
    true_heading = np.arctan2(ahead[:, 1], ahead[:, 0])
    every = max(1, round(round_hz / pose_hz))
    errors, all_errors, heading_errors, lf, held = [], [], [], 0, 0
    last_xy: tuple[float, float] | None = None
    stepped_at = truth[0]
    for k, (t, (x, y)) in enumerate(zip(t_rounds, truth, strict=True)):
        uhf = k % uhf_every == 0
        for read in model.round(float(x), float(y), float(t), int(t * 1000), uhf=uhf):
            (filt.add if filt is not None else loc.add)(read)  # type: ignore[union-attr]
        if filt is not None:
            moved = float(np.hypot(x - stepped_at[0], y - stepped_at[1]))
            if moved >= step_m:
                # The IMU's heading over the stride: the direction the step went.
                way = math.atan2(y - stepped_at[1], x - stepped_at[0])
                filt.step(float(t), imu.step(moved), imu.compass(way))
                stepped_at = truth[k]
            elif k % every == 0:
                filt.compass(float(t), imu.compass(float(true_heading[k])))
        if k % every or t < 1.0:  # the first second fills the median windows
            continue
        if filt is not None:
            pose = filt.pose(float(t))
            est = None if pose is None else (pose.x, pose.y, pose.heading, pose.source)
        else:
            e = loc.estimate(float(t))  # type: ignore[union-attr]
            est = None if e is None else (e.x, e.y, e.heading, e.source)
        if est is not None:
            last_xy = (est[0], est[1])
            errors.append(float(np.hypot(est[0] - x, est[1] - y)))
            heading_errors.append(_angle(est[2] - float(true_heading[k])))
            lf += est[3] in ("lf", "lf-hold")
            held += est[3] == "lf-hold"
        all_errors.append(
            math.inf if last_xy is None else float(np.hypot(last_xy[0] - x, last_xy[1] - y))
        )
    errs = np.array(errors)
    n = max(1, errs.size)
    return EvalResult(method, lf_layout, errs, lf / n, held / n, np.array(all_errors),
                      np.array(heading_errors))  # fmt: skip
