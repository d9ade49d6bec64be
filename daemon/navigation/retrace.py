"""Back along the user's own steps to where the pose was last sure, instead of a WAIT that
never clears.

A pose too unsure to guide on (``PoseMargin.too_unsure``) used to give WAIT until it got
better. With the pose from RFID alone it may never get better: after a few bumps σ passes
1 m, and a user standing where no UHF tag answers (1.5 m, the paper's reading range) and no LF
patch lies gets no fix (the reader has no antenna direction, so turning on the spot finds none).

The estimate's *relative* motion stays good while its absolute error grows: the pedometer and
compass between two poses are accurate over a few metres. So the navigator keeps the track
of the poses it guided on (a crumb every ``spacing_m``, the last ``keep_m`` of it) and marks
those sure enough to be a fix (σ ≤ ``fix_sigma_m``). Once unsure, the user is guided back
along that track, newest crumb first, to the last sure one — the place a tag or patch last
answered, where it will answer again. The belt gives the ordinary GUIDE / TURN_AROUND
patterns along the track (guidance's own checks against the known map, and the navigator's
STOP before contact, still apply), and the status says ``pose_uncertain`` with
``BACK_REASON``. It keeps leading back until σ is down to ``resume_sigma_m`` (so it does not
flip between the goal and the track at the WAIT limit), then the route to the goal resumes.
A sure crumb reached while still unsure is passed, on to the one before; no sure crumb left
means WAIT, as before.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from daemon.guidance.guide import Guidance, GuidanceOutput
from daemon.planning.grid import Cell, in_bounds, xy_to_cell
from daemon.planning.inflation import InflatedMap
from protocol.messages import PatternKind, Pose
from protocol.pose_quality import pose_sigma_m

BACK_REASON = "pose unsure: led back along your own steps to where it was last sure"


@dataclass(frozen=True)
class RetracePolicy:
    fix_sigma_m: float = 0.35
    """A pose this sure (1 σ) marks a place where the tags gave a fix."""
    resume_sigma_m: float = 0.6
    """Leading back goes on until σ is down to this."""
    spacing_m: float = 0.25
    """One crumb per this much walked."""
    keep_m: float = 10.0
    """The track kept: dead reckoning is trusted over a few metres, not further."""
    reached_m: float = 0.4
    """A crumb this near is reached (above guidance's 0.3 m arrival, which must not fire)."""


class Retrace:
    def __init__(self, policy: RetracePolicy | None = None) -> None:
        self.policy = policy or RetracePolicy()
        self.crumbs: deque[tuple[float, float, bool]] = deque()
        """(x, y, sure) of the poses guided on, oldest first."""
        self.active = False
        """Leading back now."""

    def reset(self) -> None:
        self.crumbs.clear()
        self.active = False

    def record(self, pose: Pose) -> None:
        """A pose the user is guided on: a crumb when it is ``spacing_m`` from the last."""
        p = self.policy
        sure = pose_sigma_m(pose.quality, pose.sigma_m) <= p.fix_sigma_m
        if self.crumbs:
            x, y, was_sure = self.crumbs[-1]
            if math.hypot(pose.x - x, pose.y - y) < p.spacing_m:
                if sure and not was_sure:  # the fix came here: mark the place
                    self.crumbs[-1] = (x, y, True)
                return
        self.crumbs.append((pose.x, pose.y, sure))
        while len(self.crumbs) > max(2, int(p.keep_m / p.spacing_m)):
            self.crumbs.popleft()

    def way_back(
        self, pose: Pose, unsure: bool, shape: tuple[int, int], cell_m: float, cell: Cell
    ) -> np.ndarray | None:
        """The cells back along the track from ``cell`` to the last sure crumb, or None when
        the user is not to be led back (sure enough, or no sure crumb left)."""
        sigma = pose_sigma_m(pose.quality, pose.sigma_m)
        if not unsure and not (self.active and sigma > self.policy.resume_sigma_m):
            self.active = False
            return None
        # Crumbs reached are done with, the sure one too: its tag did not answer again.
        while (
            self.crumbs
            and math.hypot(pose.x - self.crumbs[-1][0], pose.y - self.crumbs[-1][1])
            < self.policy.reached_m
        ):
            self.crumbs.pop()
        last_sure = next(
            (i for i in range(len(self.crumbs) - 1, -1, -1) if self.crumbs[i][2]), None
        )
        if last_sure is None:
            self.active = False
            return None
        cells = [cell]
        for x, y, _ in reversed(list(self.crumbs)[last_sure:]):
            c = xy_to_cell(shape, x, y, cell_m)
            if in_bounds(shape, c) and c != cells[-1]:
                cells.append(c)
        if len(cells) < 2:
            self.active = False
            return None
        self.active = True
        # Guidance reads a path of neighbouring cells (its turning points, its hold).
        legs = [_cells_between(a, b) for a, b in pairwise(cells)]
        return np.vstack([*legs, np.array([cells[-1]], np.int32)])


def lead_back(
    guidance: Guidance, path: np.ndarray, pose: Pose, grid: InflatedMap, now: float
) -> GuidanceOutput:
    """The belt's pattern along the way back: guidance's GUIDE / TURN_AROUND (its hold and
    its checks against the known map as on any path); at the crumb itself, WAIT for the tags
    (never ARRIVED: this is not the goal)."""
    g = guidance.guide(path, pose, grid.shape, now, grid.blocked, grid.occupancy)
    if g.pattern.kind == PatternKind.ARRIVED:
        return guidance.event(PatternKind.WAIT, now)
    return g


def _cells_between(a: Cell, b: Cell) -> np.ndarray:
    """Cells from ``a`` towards ``b`` (``b`` excluded), one per step of the longer axis."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1]))
    t = np.arange(n) / n
    return np.stack(
        [np.rint(a[0] + t * (b[0] - a[0])), np.rint(a[1] + t * (b[1] - a[1]))], axis=1
    ).astype(np.int32)
