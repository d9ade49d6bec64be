"""The obstacle margin from how sure the user's pose is, and WAIT when it is not sure enough.

Chen et al. enlarge every obstacle by ω/2 + a, "ω the robot width and a the positional
uncertainty of the robot (currently, 15 cm)". The daemon's margin is the user's radius
(ω/2); ``PoseMargin`` adds a, read from each pose's uncertainty (``Pose.sigma_m``), rounded
up to whole cells and capped at ``a_max_m``. A pose worse than ``wait_sigma_m`` (its
``sigma_m``, or the σ its ``quality`` stands for — ``protocol.pose_quality``) gives WAIT:
the user stands until a fix arrives rather than being sent off in a direction that may be
wrong.

An exact pose (the sim's, an old sender's default quality 1) means a = 0: nothing changes.
The margin grows at once and shrinks only after ``shrink_after_s`` of better poses, so that
a pose whose quality wavers does not re-inflate the map every step. A margin that would
swallow the goal cell is held one cell short of it (a goal beside a wall stays reachable).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from daemon.planning.grid import Cell
from daemon.planning.inflation import InflatedMap
from protocol.messages import Pose
from protocol.pose_quality import pose_sigma_m

from .map_keeper import MapKeeper
from .route import Route

PAPER_A_M = 0.15
"""The paper's positional uncertainty a of its robot."""


@dataclass(frozen=True)
class MarginPolicy:
    sigmas: float = 2.0
    """a = this many σ of the pose (2: the user is inside the margin 95 % of the time)."""
    a_max_m: float = 0.30
    """The most the margin grows: twice the paper's a; beyond it the way is better waited for."""
    wait_sigma_m: float = 1.0
    """A pose this unsure (1 σ) gives WAIT instead of a direction: an error that size is
    the width of a passage, so a direction read from it may lead into a wall."""
    shrink_after_s: float = 2.0
    cap_hold_s: float = 5.0
    """After a's enlargement closed the way, it is tried again this much later (the user
    has moved on, the clutter around may be different)."""


class PoseMargin:
    def __init__(self, cell_m: float, radius_cells: int, policy: MarginPolicy | None = None):
        self.cell_m = cell_m
        self.base_cells = radius_cells
        self.policy = policy or MarginPolicy()
        self.extra_cells = 0
        self.sigma_m = 0.0
        self._better_since: float | None = None
        self.cap_cells: int | None = None
        """The most a may be while this goal stands: a larger one closed the way to it."""
        self._cap_goal: Cell | None = None
        self._cap_at = 0.0

    @property
    def max_extra_cells(self) -> int:
        return math.ceil(self.policy.a_max_m / self.cell_m - 1e-9)

    @property
    def a_m(self) -> float:
        """The a of ω/2 + a in force now, metres."""
        return self.extra_cells * self.cell_m

    def too_unsure(self, pose: Pose) -> bool:
        """True when this pose must not be guided on (WAIT).

        The WAIT reads either figure; the margin only a sender's own ``sigma_m``: the first
        RFID node's ``quality`` was never calibrated in metres, and a margin grown from it
        made its walks stall (``tests/sim/test_rfid_node.py``), so a quality-only sender
        keeps the plain ω/2."""
        self.sigma_m = pose.sigma_m if pose.sigma_m is not None else 0.0
        return pose_sigma_m(pose.quality, pose.sigma_m) > self.policy.wait_sigma_m

    def arrive_within_m(self, arrive_m: float) -> float:
        """ARRIVED once the estimate is this close to the goal: ``arrive_m`` less the pose's
        σ (never under a cell), so a user told they are there is, with σ to spare. The RFID
        walks that failed only by "arrived off the goal" (9 of 300, ARRIVED at 0.3 m on an
        estimate 0.24-0.29 m off, σ about 0.1 m: 0.52-0.56 m from the goal truly) all arrive
        within 0.5 m with 0.2 m; an exact pose (σ 0) keeps ``arrive_m``, and no pose gets more
        (a walk that must end on the goal cell asks for half a cell)."""
        return min(arrive_m, max(self.cell_m, arrive_m - self.sigma_m))

    def wanted_cells(self) -> int:
        a = min(self.policy.sigmas * self.sigma_m, self.policy.a_max_m)
        return min(self.max_extra_cells, math.ceil(a / self.cell_m - 1e-9))

    def adjust(
        self, maps: MapKeeper, route: Route, goal: Cell | None, now: float, no_way: bool = False
    ) -> int:
        """Re-inflate ``maps`` by ω/2 + a for the last pose judged; the cells that flipped are
        handed to ``route`` as a change. Returns how many flipped.

        ``no_way``: the last step found no path. With a > 0 that may be a's doing (in clutter
        the enlarged obstacles close the gaps ω/2 leaves open): a is held one cell smaller
        for ``cap_hold_s`` (down to 0, where the plain margin decides).
        """
        if maps.map is None:
            return 0
        if goal != self._cap_goal or now - self._cap_at > self.policy.cap_hold_s:
            self.cap_cells, self._cap_goal = None, goal
        if no_way and self.extra_cells > 0:
            self.cap_cells, self._cap_at = self.extra_cells - 1, now
            self._better_since = -math.inf  # shrink now, not after shrink_after_s
        want = self.wanted_cells()
        if self.cap_cells is not None:
            want = min(want, self.cap_cells)
        if want < self.extra_cells:
            if self._better_since is None:
                self._better_since = now
            if now - self._better_since < self.policy.shrink_after_s:
                return 0
        self._better_since = None
        if want == self.extra_cells:
            return 0
        grid = maps.map
        if want > 0 and goal is not None and not grid.blocked[goal]:
            # Never let the margin swallow a goal the base margin leaves free.
            free = InflatedMap(grid.occupancy, self.base_cells + want)
            while want > 0 and free.blocked[goal]:
                want -= 1
                free = InflatedMap(grid.occupancy, self.base_cells + want)
        if want == self.extra_cells:
            return 0
        self.extra_cells = want
        flipped, blocked_now = grid.reinflate(self.base_cells + want)
        maps.radius_cells = grid.radius_cells  # a snapshot is inflated the same way
        if flipped.size:
            route.change(flipped, blocked_now)
        return int(flipped.size)
