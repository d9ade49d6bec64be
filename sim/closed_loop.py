"""A walk in one process: the world and the daemon's own ``Navigator``, on a simulated clock.

Each action: what the sensor saw since the last one (a map delta) and the user's pose go to
the navigator in one step, as the daemon's runner coalesces them (and the world's snapshot
when the navigator asked for one); the walker acts on the path
and the belt pattern the step produced; the clock moves on by ``step_s``. The walk ends when
the navigator says ARRIVED, when it has no path and the walker stands still, or at a limit.

The benchmark, the paper's walk, the belt walks and the studies all run through here, so each
figure they give is the figure of the navigator the daemon runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from daemon.navigation import Inbox, Navigator, StepReport
from daemon.runtime import gc_policy
from protocol.messages import BeltPattern, Goal, GoalCell, NavState, PatternKind, Pose, Proximity

from .world import World

STEP_S = 0.6
"""Simulated seconds per walker action (one step or one turn on the spot)."""


@dataclass
class Walk:
    """What one walk did, one entry per navigator step."""

    arrived: bool
    reason: str
    """``arrived``, ``no path``, ``left the map``, ``step limit`` or ``action limit``."""
    walked: list[tuple[int, int]] = field(default_factory=list)
    """The user's cell after every step taken, start first."""
    track: list[tuple[float, float]] = field(default_factory=list)
    """The walker's position in metres (x, y) after every action, start first."""
    reports: list[StepReport] = field(default_factory=list)
    belts: list[BeltPattern] = field(default_factory=list)
    """The last pattern of every step (what the user felt while acting)."""
    cues: int = 0
    route_changes: int = 0
    """Steps whose route left the last guided route ahead of the user (``route_departs``)."""
    reroutes_announced: int = 0
    """Of those, announced in words in that step or the next."""
    actions: dict[str, int] = field(default_factory=dict)
    final_state: NavState = NavState.IDLE

    @property
    def steps(self) -> int:
        return max(0, len(self.walked) - 1)


ANNOUNCING = frozenset({"new_route", "off_route", "reroute"})
"""Cue kinds that tell the user the route changed."""
UNGUIDED = frozenset({PatternKind.WAIT, PatternKind.NO_PATH, PatternKind.ARRIVED, PatternKind.OFF})


def route_departs(
    last: np.ndarray, new: np.ndarray, cell_m: float, ahead_m: float = 3.0, by_m: float = 1.1
) -> bool:
    """True when a cell of ``new`` within ``ahead_m`` (along it) of its start lies more than
    ``by_m`` from every cell of ``last``: the way ahead changed, not just its first cell.
    (Written here apart from the daemon's own test, ``guidance/route_watch.py``, so the walks
    check the daemon rather than repeat it. The daemon announces a route that leaves the last
    by more than 1 m, comparing points 10 cm apart; ``by_m`` 1.1 m leaves that sampling room,
    so a change counted here is one the daemon must have announced.)"""
    if len(last) == 0 or len(new) < 2:
        return False
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(new, axis=0).T))]) * cell_m
    near = new[along <= ahead_m].astype(np.float64)
    gap = np.hypot(near[:, None, 0] - last[None, :, 0], near[:, None, 1] - last[None, :, 1])
    return bool(gap.min(axis=1).max() * cell_m > by_m)


PoseSource = Callable[[World, float], Pose | None]
"""``(world, now) -> pose`` the navigator is given; the true pose unless a localiser stands in."""
Mover = Callable[[World, float], None]
"""Changes the world's true map as time goes on (a person who walks into a doorway)."""


def true_pose(world: World, now: float) -> Pose:
    return world.pose(now)


def run_walk(
    world: World,
    navigator: Navigator,
    *,
    max_actions: int,
    max_steps: int | None = None,
    step_s: float = STEP_S,
    pose_source: PoseSource = true_pose,
    mover: Mover | None = None,
    stop_on_no_path: bool = True,
    map_first: bool = False,
    on_step: Callable[[Walk], None] | None = None,
    proximity_source: Callable[[World, float], Proximity | None] | None = None,
) -> Walk:
    """Walk ``world.scenario`` from its start to its goal with ``navigator`` guiding.

    ``stop_on_no_path``: end the walk the first time the navigator finds no path (in a static
    world nothing will change that); a walker in a changing world may wait instead.
    ``map_first``: give each action's map delta a step of its own before the pose's, as the
    zenoh sim node does (it waits for the daemon's answer to a delta before the next pose).
    ``proximity_source``: the camera's nearest obstacles with each pose (the STOP before
    contact); None: the walk has no such input.
    """
    now = 0.0
    goal = Goal(target=GoalCell(row=world.scenario.goal[0], col=world.scenario.goal[1]), stamp=now)
    deltas = world.first_deltas(now)
    walk = Walk(arrived=False, reason="action limit", walked=[world.cell()],
                track=[(world.walker.x, world.walker.y)])  # fmt: skip
    inbox = Inbox(deltas=deltas, goal=goal)
    if not deltas or deltas[0].seq != 0:  # the known map did not fit in delta 0: a snapshot
        inbox = Inbox(snapshot=world.snapshot(now), goal=goal)
    belt: BeltPattern | None = None
    guided = np.empty((0, 2), np.int64)  # the route the user was last guided on
    owed = False  # a route change not yet announced, from the step before
    for _ in range(max_actions):
        if map_first and inbox.deltas and inbox.goal is None:
            navigator.step(inbox, now)
            navigator.between_steps()
            gc_policy.after_step()
            inbox = Inbox()
        inbox.pose = pose_source(world, now)
        if proximity_source is not None:
            inbox.proximity = proximity_source(world, now)
        out = navigator.step(inbox, now)
        walk.reports.append(navigator.last)
        walk.cues += len(out.voice)
        if out.belt:
            belt = out.belt[-1]
            walk.belts.append(belt)
        navigator.between_steps()  # as the runner does once the step's output is put
        gc_policy.after_step()
        said = any(cue.kind in ANNOUNCING for cue in out.voice)
        if owed:
            walk.reroutes_announced += said
            owed = False
        if (
            belt is not None
            and belt.kind not in UNGUIDED
            and out.path_cells is not None
            and len(out.path_cells)
        ):
            if route_departs(guided, out.path_cells, world.scenario.cell_m):
                walk.route_changes += 1
                if said:
                    walk.reroutes_announced += 1
                else:
                    owed = True  # the next step may still say it
            guided = np.asarray(out.path_cells)
        if navigator.state == NavState.ARRIVED:
            walk.arrived, walk.reason = True, "arrived"
            break
        action = world.act(out.path_cells, belt, now, tuple(out.voice))
        walk.actions[action] = walk.actions.get(action, 0) + 1
        walk.track.append((world.walker.x, world.walker.y))
        if action == "step":
            walk.walked.append(world.cell())
            if max_steps is not None and walk.steps >= max_steps:
                walk.reason = "step limit"
                break
        if not _on_map(world):
            walk.reason = "left the map"
            break
        if stop_on_no_path and navigator.state == NavState.NO_PATH:
            walk.reason = "no path"
            break
        if on_step is not None:
            on_step(walk)
        now += step_s
        if mover is not None:
            mover(world, now)
        inbox = Inbox(deltas=world.sense(now))
        if out.want_snapshot:  # as the sim node's map source answers the daemon's query
            inbox.snapshot = world.snapshot(now)
    walk.final_state = navigator.state
    return walk


def _on_map(world: World) -> bool:
    r, c = world.cell()
    h, w = world.shape
    return 0 <= r < h and 0 <= c < w
