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

from dataclasses import dataclass

import numpy as np

from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import OCCUPIED, cell_to_xy
from drivers.rfid.localiser import Localiser
from drivers.rfid.rssi import ReadModel
from drivers.rfid.tags import TagMap, generate


def tags_for(scenario, lf_layout: str = "floor", seed: int = 0) -> TagMap:
    """Tags placed on the scenario's known obstacles (what a venue would survey)."""
    known_occupied = scenario.known == OCCUPIED
    return generate(known_occupied, scenario.cell_m, seed=seed, lf_layout=lf_layout)


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
    lf_fraction: float
    """Share of estimates from floor tags: read now, or held from one read < 0.3 s ago."""
    held_fraction: float = 0.0
    """Of those, the share held (dead-reckoned from the last floor tags)."""

    def row(self) -> dict:
        return {
            "method": self.method,
            "lf_tags": self.lf_layout != "none",
            "lf_layout": self.lf_layout,
            "median_m": round(float(np.median(self.errors)), 4),
            "p95_m": round(float(np.percentile(self.errors, 95)), 4),
            "samples": int(self.errors.size),
            "lf_fraction": round(self.lf_fraction, 3),
            "held_fraction": round(self.held_fraction, 3),
        }


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
    **read_kw,
) -> EvalResult:
    """Walk ``route`` once with the reader; errors of every estimate after the first second."""
    model = ReadModel.for_tags(tag_map, seed=seed, **read_kw)
    loc = Localiser(tag_map, method=method)
    length = float(np.hypot(*np.diff(route, axis=0).T).sum())
    duration = length / speed_mps
    t_rounds = np.arange(0.0, duration, 1.0 / round_hz)
    truth = walked(route, t_rounds * speed_mps, offset, sway_m, sway_period_s * speed_mps)
    every = max(1, round(round_hz / pose_hz))
    errors, lf, held = [], 0, 0
    for k, (t, (x, y)) in enumerate(zip(t_rounds, truth, strict=True)):
        uhf = k % uhf_every == 0
        for read in model.round(float(x), float(y), float(t), int(t * 1000), uhf=uhf):
            loc.add(read)
        if k % every or t < 1.0:  # the first second fills the median windows
            continue
        est = loc.estimate(float(t))
        if est is None:
            continue
        errors.append(float(np.hypot(est.x - x, est.y - y)))
        lf += est.source in ("lf", "lf-hold")
        held += est.source == "lf-hold"
    errs = np.array(errors)
    n = max(1, errs.size)
    return EvalResult(method, lf_layout, errs, lf / n, held / n)
