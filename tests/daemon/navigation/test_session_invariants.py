"""The session's safety invariants under any sequence of inputs (hypothesis stateful testing).

After every step of a navigator fed goals, fresh/stale/future poses, deltas in and out of
sequence, snapshots, refusals and ticks in any order:

1. a STOP or WAIT decided in a step is never followed by GUIDE (or a turn) in the same step;
2. a pose stale or from the future is refused (``stale_pose``) and that step guides no one;
3. while the map is out of date (a sequence gap, no snapshot yet) nothing guides: WAIT;
4. never silence: a user with a goal, a map and a fresh pose gets a belt pattern every step;
5. a user the daemon sheds (``overloaded``) is never guided in that step, and hears why;
6. every move of the session is one ``TRANSITIONS`` allows (a move outside it raises), and
   guidance resumes only once its cause is cleared: after a stale pose, a fresh pose.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.outcomes import Rejection
from daemon.navigation.session_state import GUIDED, TRANSITIONS
from protocol.messages import (
    Goal,
    GoalCell,
    MapDelta,
    MapSnapshot,
    PatternKind,
    Pose,
    StatusCode,
)

SHAPE = (24, 24)
MOVING = {PatternKind.GUIDE, PatternKind.TURN_AROUND}
HALTING = {PatternKind.STOP, PatternKind.WAIT}
REFUSALS = [StatusCode.MALFORMED, StatusCode.INVALID, StatusCode.OVERSIZED,
            StatusCode.UNKNOWN_FIELD, StatusCode.WRONG_TYPE]  # fmt: skip


class Session(RuleBasedStateMachine):
    def __init__(self) -> None:
        super().__init__()
        self.nav = Navigator("s", NavigatorSettings(backend="cpu", stale_pose_s=1.0))
        self.now = 1000.0
        self.seq = 0
        self.truth = np.zeros(SHAPE, np.uint8)
        self.truth[0, :] = self.truth[-1, :] = self.truth[:, 0] = self.truth[:, -1] = 1
        self.gap = False
        self.fresh_pose = False
        self.stale_pose = False
        self.shed = False
        self.pose_fresh_since_stale = True
        self.out = None
        # A session under way: a map, a goal, a fresh pose; then anything may happen.
        self._step(Inbox(deltas=[self._delta(np.flatnonzero(self.truth), 1)],
                         goal=Goal(target=GoalCell(row=8, col=12), stamp=self.now),
                         pose=Pose(x=1.25, y=0.65, heading=1.57, stamp=self.now)))  # fmt: skip

    # -- inputs -----------------------------------------------------------------------------

    def _delta(self, cells: np.ndarray, value: int) -> MapDelta:
        d = MapDelta.from_arrays(self.seq, SHAPE, cells, np.full(cells.size, value, np.uint8),
                                 self.now)  # fmt: skip
        self.seq += 1
        return d

    def _step(self, inbox: Inbox) -> None:
        age = None if inbox.pose is None else self.now - inbox.pose.stamp
        self.fresh_pose = age is not None and -0.5 <= age <= 1.0
        self.stale_pose = age is not None and not self.fresh_pose
        self.shed = inbox.overloaded
        if inbox.snapshot is not None:
            self.gap = False
        self.out = self.nav.step(inbox, self.now)
        if self.out.want_snapshot:
            self.gap = True
        if StatusCode.STALE_POSE in [st.code for st in self.out.statuses]:
            self.pose_fresh_since_stale = False
        elif self.fresh_pose:
            self.pose_fresh_since_stale = True

    @rule(row=st.integers(5, 18), col=st.integers(5, 18))
    def goal(self, row, col):
        self._step(Inbox(goal=Goal(target=GoalCell(row=row, col=col), stamp=self.now)))

    @rule(row=st.integers(1, 22), col=st.integers(1, 22),
          age=st.sampled_from([0.0, 0.0, 0.0, 0.3, 0.9, 5.0, -5.0]),
          heading=st.floats(-3.1, 3.1))  # fmt: skip
    def pose(self, row, col, age, heading):
        x, y = (col + 0.5) / 10, (SHAPE[0] - row - 0.5) / 10
        self._step(Inbox(pose=Pose(x=x, y=y, heading=heading, stamp=self.now - age)))

    @rule(cells=st.lists(st.integers(0, SHAPE[0] * SHAPE[1] - 1), min_size=1, max_size=12),
          value=st.sampled_from([0, 1]), skip=st.booleans())  # fmt: skip
    def delta(self, cells, value, skip):
        if skip:
            self.seq += 1  # a delta lost on the way: the next one leaves a gap
        cells = np.unique(np.array(cells))
        self.truth.reshape(-1)[cells] = value
        self._step(Inbox(deltas=[self._delta(cells, value)]))

    @rule()
    def snapshot(self):
        snap = MapSnapshot.from_array(self.seq - 1, self.truth, self.now)
        self._step(Inbox(snapshot=snap))

    @rule(code=st.sampled_from(REFUSALS))
    def refusal(self, code):
        self._step(Inbox(rejections=[Rejection(code, "fuzzed")]))

    @rule()
    def shed(self):
        self._step(Inbox(overloaded=True, tick=True))

    @rule(dt=st.sampled_from([0.1, 0.6, 2.0]))
    def tick(self, dt):
        self.now += dt
        self._step(Inbox(tick=True))

    # -- invariants -------------------------------------------------------------------------

    @invariant()
    def a_halt_is_not_undone_in_the_same_step(self):
        kinds = [b.kind for b in self.out.belt]
        for i, kind in enumerate(kinds):
            if kind in HALTING:
                assert not MOVING & set(kinds[i + 1 :]), kinds

    @invariant()
    def a_stale_or_future_pose_is_refused_and_guides_no_one(self):
        if self.stale_pose:
            assert StatusCode.STALE_POSE in [s.code for s in self.out.statuses]
            assert not MOVING & {b.kind for b in self.out.belt}

    @invariant()
    def no_guidance_on_a_map_out_of_date(self):
        if self.gap and self.nav.maps.stale:
            assert not MOVING & {b.kind for b in self.out.belt}

    @invariant()
    def a_shed_user_is_not_guided_and_hears_overloaded(self):
        if self.shed:
            assert not MOVING & {b.kind for b in self.out.belt}
            assert StatusCode.OVERLOADED in [s.code for s in self.out.statuses]

    @invariant()
    def moves_are_the_machines_and_guidance_waits_for_a_fresh_pose(self):
        assert all(b in TRANSITIONS[a] for a, b in self.nav.session.moves)
        if self.nav.state in GUIDED and MOVING & {b.kind for b in self.out.belt}:
            assert self.pose_fresh_since_stale

    @invariant()
    def never_silent_with_a_goal_a_map_and_a_fresh_pose(self):
        if self.fresh_pose and self.nav.goal is not None and self.nav.maps.map is not None:
            assert self.out.belt, (self.nav.state, self.out.statuses)


TestSession = Session.TestCase
TestSession.settings = settings(
    max_examples=120, stateful_step_count=25, deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)  # fmt: skip
