"""How often each user is stepped and its belt pattern put: the step slots and periods the
runners share, and an unchanged GUIDE pattern put again only as its TTL needs."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from protocol.messages import BeltPattern, PatternKind

BELT_REFRESH = 0.5
"""A GUIDE pattern equal to the last one put (motors, pulse, TTL) is put again only once
this share of its TTL has passed: the belt driver keeps showing a pattern until ``ttl_ms``
after it arrived (``drivers/belt/driver.py`` repeats it to the firmware every 100 ms with the
TTL left), so half the TTL plus one step period still lands well inside it, and a dead daemon
still goes quiet within one TTL of its last put."""


class Pacing:
    """What the daemon's runners share: the step slots (one per core) and the lag record
    admission control reads, with each user's step periods."""

    def __init__(
        self,
        slots: int = 1,
        guide_hz: float = 20.0,
        shed_period_s: float = 0.5,
        record: Callable[[str, float, float, float, bool], None] | None = None,
    ) -> None:
        self.slots = threading.Semaphore(slots)
        """Taken by a user's worker thread for its step: held for the step alone, never for
        the loop's round trip; waiting threads are let in first come, first served."""
        self.shed_gate = threading.Semaphore(1)
        """Taken by a shed user's worker before a slot: one shed user at a time queues for
        the slots, so a guided user's step waits behind one shed step at most (at 100 users,
        93 shed users' twice-a-second steps queued ahead of the 7 guided ones' and kept
        their lag over the budget: shed again, and again)."""
        self.guide_period_s = 1.0 / guide_hz
        self.shed_period_s = shed_period_s
        self._record = record
        self._steps: deque[tuple[str, float, float, float, bool]] = deque()
        self.behind = False
        """The daemon's loop is late on its inputs: a pose missing now may be ours to blame."""

    def record(self, user: str, lag_ms: float, cpu_ms: float, urgent: bool = True) -> None:
        """One step's lag and CPU (``urgent``: it answered an input, not a pose alone), from
        the user's worker thread: kept until the loop ``flush``es them into ``record(user,
        lag_ms, cpu_ms, monotonic time, urgent)``, so admission control's records are only ever
        touched on the loop (a deque's append is atomic)."""
        if self._record is not None:
            self._steps.append((user, lag_ms, cpu_ms, time.monotonic(), urgent))

    def flush(self) -> None:
        """On the loop, before admission control reads its records."""
        steps, record = self._steps, self._record
        while steps and record is not None:
            record(*steps.popleft())


class BeltRefresh:
    """One user's last belt pattern put (kind, motors, pulse, TTL) and when (monotonic)."""

    def __init__(self) -> None:
        self._shape: tuple | None = None
        self._put_at = 0.0

    def due(self, pattern: BeltPattern, force: bool = False) -> bool:
        """Whether ``pattern`` must be put (``force``, an event, a direction that differs
        from the last one put, or that one's TTL half gone); what is put is remembered. Most
        10 Hz steps of a user walking straight on repeat the GUIDE pattern (hysteresis holds
        the direction), and each put is an encode and a zenoh put. Events (STOP, WAIT, a
        refusal's pattern, ...) are always put: each one says something happened again."""
        shape = (pattern.kind, pattern.motors, pattern.period_ms, pattern.ttl_ms)
        now = time.monotonic()
        if (
            not force
            and pattern.kind == PatternKind.GUIDE
            and shape == self._shape
            and now - self._put_at < pattern.ttl_ms / 1e3 * BELT_REFRESH
        ):
            return False
        self._shape, self._put_at = shape, now
        return True
