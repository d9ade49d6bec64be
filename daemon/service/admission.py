"""Who is guided now, when the daemon cannot guide everyone in time.

Two budgets, both from measurements of the steps themselves:

- **CPU**: each step's worker-thread CPU time is recorded per user; over the last window a
  guided user costs ``cost`` ms of CPU per second. The guided users together may cost at most
  ``cpu_budget_ms`` per second (a share of the one core Python's GIL gives the steps'
  Python parts; the compiled planners run beside it on the other cores).
- **Lag**: each step's delay from its first urgent input (a map delta, a goal, a refusal, a
  button) arriving to its outputs being published, and how late the loop woke for its tick.
  This is what a user feels, whatever the cause (cores, GIL, GPU, the loop). Judged: its
  ``percentile`` (p99, the promise's) over the window, against the budget the daemon can see,
  ``lag_budget_ms`` less ``unseen_ms`` (zenoh's way in and out, the client's receive). A pose
  alone answers no input (its lag counts from when its turn came, the step's own time): those
  lags are judged only when too few urgent ones say anything (a map that does not change).

Every review (the daemon's tick):

- guided users over the CPU budget: the most recently admitted are shed until the rest fit
  in 90 % of it; or the judged lag above its threshold (``shed_fraction`` × the budget it
  sees) for ``sustain_s``: a share of them in proportion to the excess, 1 − threshold / lag
  (at least one, at most half; while users join, whose first whole-map steps are a burst, the
  p95 against the whole budget and at most a tenth), so a lag ten times the threshold halves
  the guided users at once rather than taking ten rounds of a tenth. A lag that is draining
  (the window's newer half's lag under ``drain_ratio`` of its older half's: a burst passing, a
  queue the daemon is emptying) is waited out for up to ``drain_patience_s``. Then no
  decision for ``settle_s``;
- the judged lag below ``readmit_fraction`` × the budget it sees for ``calm_s``: the users shed
  longest ago are guided again, as many as fit (up to ``readmit_share`` of the guided, by
  default one at a time) in 80 % of the CPU budget and in 90 % of the CPU the steps were
  taking when the lag last forced a shedding (what the machine could give them then; not
  measured while users join, whose first steps are a burst; late again while it is
  remembered, the lower of the two).
  That measured capacity is forgotten after ``capacity_memory_s``, as the machine's other
  load comes and goes. Each comes back priced at the more of what they cost when last guided
  and what a guided user costs now (a user measured while late, their inputs batched, cost
  less then than they will);
- a lag over the threshold within ``overshoot_s`` of a readmission says that readmission
  overshot: at the first review past ``settle_s`` (no ``sustain_s``, no waiting out a
  drain) it sheds only those that readmission brought back, the capacity becomes at most
  the CPU the guided users took, calm, just before it, and the calm wanted before the next
  readmission doubles (up to ``max_calm_s``). Until the lag has forced no shedding for
  ``overshoot_memory_s``, users come back one at a time once that capacity is forgotten.

A shed user hears ``overloaded`` and feels WAIT (never a false ``stale_pose``); their map,
goal and pose are kept, so guidance resumes where it was. Users admitted first stay guided
longest: someone half-way across a station keeps the guidance they are walking on. A new
user joins behind those already waiting. A user stays shed at least ``min_shed_s``, so nobody
is told "overloaded", "resumed", "overloaded" in a row.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .admission_settings import AdmissionSettings

__all__ = ["Admission", "AdmissionSettings"]


class Admission:
    def __init__(self, settings: AdmissionSettings | None = None) -> None:
        self.s = settings or AdmissionSettings()
        self._admitted: list[str] = []
        """In order of admission: the last ones are shed first."""
        self._shed: dict[str, float] = {}
        """Shed user → when; in order of shedding."""
        self._lags: deque[tuple[float, float, bool]] = deque()
        """(when, lag ms, whether it answered an input) of each step and each tick's wake."""
        self._cpu: deque[tuple[float, str, float]] = deque()
        self._cost: dict[str, float] = {}
        """Each user's CPU ms per second over the last window (kept while shed)."""
        self._quiet_until = 0.0
        self._decided_at = -math.inf
        """When users were last shed."""
        self._joined_at = -math.inf
        """When a user was last admitted: their first steps (a whole map, a whole plan) are a
        burst, not what the machine gives steady guidance."""
        self._capacity: tuple[float, float] | None = None
        """(CPU ms per second the guided users' steps took when the lag last forced a
        shedding, when): the machine's measured capacity for them, for readmission."""
        self._over_since: float | None = None
        self._readmitted_at = -math.inf
        self._readmitted = 0
        """How many the last readmission brought back."""
        self._calm_cpu = 0.0
        """The guided users' CPU ms per second, calm, at the last readmission (before it)."""
        self._shed_at = -math.inf
        """When the lag last forced a shedding."""
        self.overshoots = 0
        """Readmissions a lag-driven shedding followed within ``overshoot_s`` since the last
        long calm: each doubles the calm wanted before the next."""
        self._calm_since: float | None = None
        self.sheddings = 0
        self.draining = False
        """The lag's newer half-window is well under its older half (``drain_ratio``)."""
        self.recent_p95_ms = 0.0
        """The judged lag over the newer half-window (0: too few samples to say)."""
        self.drain_waits = 0
        """Lags over the threshold for ``sustain_s`` that were draining, so nobody was shed
        then (one count per lag, however many reviews it was waited out)."""
        self._waited: float | None = None
        self._waited_at = -math.inf
        """When a lag was last waited out as draining."""
        self.last_p95_ms = 0.0
        """The window's lag p95 (health reports it; the judged lag is ``last_lag_ms``)."""
        self.last_lag_ms = 0.0
        """The window's judged lag: its ``percentile`` (0: too few samples to say)."""
        self.last_cpu_ms = 0.0

    # -- users ----------------------------------------------------------------------------

    def join(self, user: str, now: float) -> bool:
        """A new user: guided (True) unless others wait already or there is no room."""
        if user in self._admitted or user in self._shed:
            return user in self._admitted
        if self._shed or not self._room(self._typical_cost(), 1.0, now):
            self._shed[user] = now
            return False
        self._admitted.append(user)
        self._joined_at = now
        return True

    def leave(self, user: str) -> None:
        if user in self._admitted:
            self._admitted.remove(user)
        self._shed.pop(user, None)
        self._cost.pop(user, None)

    def is_shed(self, user: str) -> bool:
        return user in self._shed

    @property
    def shed(self) -> list[str]:
        return list(self._shed)

    # -- measurements ---------------------------------------------------------------------

    def record(
        self, user: str, lag_ms: float, cpu_ms: float, now: float, urgent: bool = True
    ) -> None:
        """One step of ``user``'s: its lag and its worker's CPU time; ``urgent``: it answered an
        input (a map delta, a goal, ...), not a pose alone."""
        if user in self._shed:
            return  # a shed user's steps are not the guided users' load
        self._cpu.append((now, user, cpu_ms))
        self._lag(lag_ms, now, urgent)

    def record_loop(self, late_ms: float, now: float) -> None:
        """How late the daemon's loop woke for its tick: a delay every user's inputs feel,
        counted as one more lag (the steps' own lags miss it when inputs queue on the loop)."""
        self._lag(late_ms, now, True)

    def _lag(self, lag_ms: float, now: float, urgent: bool) -> None:
        """Only the lags of inputs that came after the last shedding judge it: a backlog queued
        before it drains with long lags for a while, and read as still too many users it
        would shed again and again (at 100 users: down to 6 of a capacity of ~30)."""
        if now - lag_ms / 1e3 >= self._decided_at:
            self._lags.append((now, lag_ms, urgent))

    def _measure(self, now: float) -> None:
        start = now - self.s.window_s
        while self._lags and self._lags[0][0] < start:
            self._lags.popleft()
        while self._cpu and self._cpu[0][0] < start:
            self._cpu.popleft()
        spent: dict[str, float] = {}
        for _, user, ms in self._cpu:
            spent[user] = spent.get(user, 0.0) + ms
        for user in self._admitted:
            self._cost[user] = spent.get(user, 0.0) / self.s.window_s
        self.last_cpu_ms = sum(self._cost.get(u, 0.0) for u in self._admitted)
        self.draining, self.recent_p95_ms = False, 0.0
        if len(self._lags) < self.s.min_samples:
            self.last_p95_ms = self.last_lag_ms = 0.0
            return
        n = len(self._lags)
        at = np.fromiter((t for t, _, _ in self._lags), float, n)
        lags = np.fromiter((lag for _, lag, _ in self._lags), float, n)
        self.last_p95_ms = float(np.percentile(lags, 95))
        # The urgent steps' lags are the promise's (delta→belt); a pose alone's counts from its
        # turn and fills the lower part: at 100 users a third of the steps, which put the p95
        # of all at 8-17 ms in seconds where the deltas' p99 was 15-40 (load16's traces).
        urgent = np.fromiter((u for _, _, u in self._lags), bool, n)
        if urgent.sum() >= self.s.min_samples:
            at, lags = at[urgent], lags[urgent]
        q = 95.0 if self._joining(now) else self.s.percentile
        self.last_lag_ms = float(np.percentile(lags, q))
        # A burst (users joining or coming back with whole maps to take and whole paths to
        # plan, a stall of the machine) keeps the window's p95 over the threshold for a whole
        # window after it has passed; the halves tell a passing burst from a lasting load.
        # Dev VM, 50 users, two workers, quiet: with every user guided again at a p95 of 5-10
        # ms, one decision shed 11-12 users at 118-137 ms; they were back within seconds at
        # 6-9 ms, told "overloaded" for a lag that had passed.
        newer = at >= now - self.s.window_s / 2
        half = self.s.min_samples // 2
        if newer.sum() >= half and (~newer).sum() >= half:
            self.recent_p95_ms = recent = float(np.percentile(lags[newer], q))
            self.draining = recent < self.s.drain_ratio * float(np.percentile(lags[~newer], q))

    def _typical_cost(self) -> float:
        costs = [self._cost[u] for u in self._admitted if u in self._cost]
        return float(np.median(costs)) if costs else 0.0

    # -- decisions ------------------------------------------------------------------------

    def review(self, now: float) -> tuple[list[str], list[str]]:
        """(users shed now, users guided again now)."""
        self._measure(now)
        lag_over = self.last_lag_ms > self._threshold(now)
        if not lag_over:
            self._over_since = None
        elif self._over_since is None:
            self._over_since = now
        if now < self._quiet_until:
            return [], []
        gone = self._to_shed(now)
        if gone:
            del self._admitted[-len(gone) :]
            for user in gone:
                self._shed[user] = now
            self.sheddings += len(gone)
            self._lags.clear()
            self._decided_at = now
            self._quiet_until, self._over_since, self._calm_since = (
                now + self.s.settle_s,
                None,
                None,
            )
            return gone, []
        back = self._to_readmit(now)
        if back:
            for user in back:
                del self._shed[user]
            self._admitted.extend(back)
            self._quiet_until, self._calm_since = now + self.s.settle_s, None
        return [], back

    def _to_shed(self, now: float) -> list[str]:
        """The newest guided users to shed (none: all fit)."""
        if len(self._admitted) <= 1:
            return []  # one user alone is guided however slow: there is no one to make room for
        if self.last_cpu_ms > self.s.cpu_budget_ms:
            total, n = self.last_cpu_ms, 0
            while n < len(self._admitted) - 1 and total > 0.9 * self.s.cpu_budget_ms:
                n += 1
                total -= self._cost.get(self._admitted[-n], 0.0)
            return self._admitted[-n:]
        # A lag soon after a readmission is that readmission's (each comes back with a map to
        # take and a whole path to plan): undone at once, not after sustain_s nor waited out as
        # a burst draining. Dev VM, 100 users, quiet: 7 readmitted into a worker at a p99 of
        # 11 ms put it at 56-91 ms; with the p99 going over and under the line and the halves
        # looking like a drain, they were shed 4.1 s later, the served users' p99 100 ms then.
        after = now - self._readmitted_at <= self.s.overshoot_s
        if self._over_since is not None and (after or now - self._over_since >= self.s.sustain_s):
            # A burst passes once: a lag over the line again soon after one waited out is the
            # load's. At 100 users (dev VM) a worker at 50 guided went over every 1-6 s, each
            # time draining, and was waited out for 8 s with its p99 at 45-55 ms.
            again = self._waited != self._over_since and (
                self._over_since - self._waited_at <= self.s.drain_memory_s
            )
            patient = now - self._over_since < self.s.drain_patience_s
            if self.draining and not after and not again and patient:
                if self._waited != self._over_since:
                    self._waited = self._over_since
                    self.drain_waits += 1
                self._waited_at = now
                return []  # a burst passing: those shed for it would come back in seconds
            threshold = self._threshold(now)
            # While users join, their first whole-map steps are part of the lag: a burst, not
            # the steady load, so a tenth at a time then (those who join later wait anyway);
            # also for a lag that began while they joined and outlasted the joins: otherwise a
            # worker shed 10-13 of its 25 at once in every 50-user start measured (dev VM).
            joining = self._over_since - self._joined_at <= self.s.window_s
            most = 0.1 if joining else self.s.max_shed_share
            share = min(most, 1.0 - threshold / self.last_lag_ms)
            n = min(len(self._admitted) - 1, max(1, math.ceil(share * len(self._admitted))))
            if now - self._readmitted_at <= self.s.overshoot_s:
                # The readmission overshot: the calm level before it is what the machine was
                # shown to carry. The CPU when the lag forced the shedding is past the knee:
                # at 100 users (dev VM, quiet) workers were shed at 338-363 ms/s, late from
                # ~310, calm below ~290; 90 % of 338-363 brought 5-7 back into the same lag.
                # Only those it brought back go: shedding half for a lag one readmission caused
                # left room the next readmissions overshot again.
                self.overshoots += 1
                known = self._remembered(now)
                cpu = self._calm_cpu if known is None else min(known, self._calm_cpu)
                self._capacity = (cpu, now)
                n = min(n, self._readmitted)
                # Undone once: a lag that outlasts the undoing is not that readmission's (dev
                # VM, 50 users: one readmitted user was shed three times in 3.3 s for it).
                self._readmitted_at = -math.inf
            elif self.last_cpu_ms > 0 and now - self._joined_at > self.s.window_s:
                # Late again while a capacity is remembered: the machine gives less than that
                # measure said (other work came), so the lower of the two. Readmitting up to the
                # older one sheds the same users again seconds later: at 50 users beside other
                # work (load average 7, dev VM) they flapped every 3-6 s, shed at 190-290 ms/s.
                known = self._remembered(now)
                cpu = self.last_cpu_ms if known is None else min(known, self.last_cpu_ms)
                self._capacity = (cpu, now)
            self._shed_at = now
            return self._admitted[-n:]
        return []

    @property
    def calm_wanted_s(self) -> float:
        """How long the lag must stay calm before the next readmission."""
        return min(self.s.max_calm_s, self.s.calm_s * 2.0**self.overshoots)

    def said(self) -> dict[str, float | int | bool]:
        """The measures behind a decision, as the daemon's ``load`` log line gives them."""
        return {
            "draining": self.draining, "lag_p95_ms": round(self.last_p95_ms, 1),
            "lag_judged_ms": round(self.last_lag_ms, 1),
            "lag_recent_ms": round(self.recent_p95_ms, 1), "calm_s": self.calm_wanted_s,
            "step_cpu_ms_per_s": round(self.last_cpu_ms), "overloaded_now": len(self._shed),
        }  # fmt: skip

    def _threshold(self, now: float) -> float:
        """The judged lag past which users are shed: ``shed_fraction`` of the budget the
        daemon sees, or, while users join, the p95 past the whole budget. A join's first steps
        (a whole map taken, often a snapshot asked of the map source, a whole path planned) are
        a burst that passes and is the tail while it lasts: at 50 users (dev VM, quiet) the
        deltas' p99 was 63-70 ms for a second as they joined and 3-17 after. Shed at 60 % of
        the budget on the p95 then, the newest joiners were told ``overloaded`` at p95 37–49
        ms with the steps taking 75–91 ms of CPU a second of 600 (dev VM, 50 users, two
        workers), and readmitted seconds later: told "overloaded" for nothing."""
        if self._joining(now):
            return self.s.lag_budget_ms
        return self.s.shed_fraction * self._seen_budget()

    def _joining(self, now: float) -> bool:
        return now - self._joined_at <= self.s.window_s

    def _seen_budget(self) -> float:
        """The part of the budget the daemon's own lags may take: the rest is the way through
        zenoh and the client's receive (``unseen_ms``), at most half of it."""
        return max(self.s.lag_budget_ms - self.s.unseen_ms, 0.5 * self.s.lag_budget_ms)

    def _room(self, cost: float, budget_share: float, now: float) -> bool:
        """Whether one more user costing ``cost`` fits in ``budget_share`` of the CPU budget
        and in 90 % of the capacity the lag last measured (while it is remembered)."""
        need = self.last_cpu_ms + cost
        capacity = self._remembered(now)
        if capacity is not None and need > 0.9 * capacity:
            return False
        return need <= budget_share * self.s.cpu_budget_ms

    def _remembered(self, now: float) -> float | None:
        """The capacity the lag last measured, while it is remembered."""
        if self._capacity is not None and now - self._capacity[1] > self.s.capacity_memory_s:
            self._capacity = None
        return None if self._capacity is None else self._capacity[0]

    def _to_readmit(self, now: float) -> list[str]:
        """Those shed longest ago (each for ``min_shed_s`` at least) that fit in the room, each
        priced at the more of what they cost when last guided and what a guided user costs
        now: as many at once as fit, up to ``readmit_share`` of the guided users, so a daemon
        that shed half at a burst is back in a few rounds; after ``calm_wanted_s`` of calm."""
        calm = self.last_lag_ms <= self.s.readmit_fraction * self._seen_budget()
        if not self._shed or not calm:
            self._calm_since = None
            return []
        if self._calm_since is None:
            self._calm_since = now
        if now - self._shed_at > self.s.overshoot_memory_s:
            self.overshoots = 0  # a long calm: what overshot then says little now
        if now - self._calm_since < self.calm_wanted_s:
            return []
        most = max(1, math.ceil(self.s.readmit_share * len(self._admitted)))
        if self.overshoots and self._remembered(now) is None:
            most = 1  # past what an overshoot measured, one user at a time
        back: list[str] = []
        extra = 0.0
        # A user shed while late cost less then than they will: their inputs were batched into
        # fewer steps (50 users at 363 ms/s, 7.3 each; 25 calm at 250-266, ~10.4; dev VM).
        typical = self._typical_cost()
        for user, since in self._shed.items():
            cost = max(self._cost.get(user, typical), typical)
            if len(back) == most or now - since < self.s.min_shed_s:
                break
            if not self._room(extra + cost, 0.8, now):
                break
            back.append(user)
            extra += cost
        if back:
            self._readmitted_at, self._calm_cpu, self._readmitted = now, self.last_cpu_ms, len(back)
        return back
