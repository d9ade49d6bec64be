"""Admission control's settings (``daemon.service.admission``), each with the measurement
behind it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class AdmissionSettings:
    lag_budget_ms: float = 50.0
    """The delay every guided user should stay within (the p99 the daemon promises)."""
    percentile: float = 99.0
    """The percentile of the lag judged: the one the promise is made on. The p95 judged before
    let a served p99 of 50-100 ms through (dev VM, 100 users, two workers, load16's traces):
    in seconds where the map deltas' step lags had a p99 of 100-140 ms the judged p95 was
    12-25 ms, under its 30 ms threshold, and nobody was shed for 3 s."""
    unseen_ms: float = 10.0
    """The part of a user's delay the daemon cannot see, kept as headroom: the map delta's
    way to the worker and the belt pattern's way back through zenoh (the router in the parent
    included) and the client's own receive. The load generator's delta→belt latency less the
    daemon's lag for the same delta, p99 (dev VM, quiet, two workers, TLS): 8.2 and 11.7 ms
    at 100 users, 5.3 ms at 50; 29 ms at 50 on the VM with another engineer's process taking
    a core. The daemon judges its own lags against ``lag_budget_ms`` less this (at most half
    the budget)."""
    cpu_budget_ms: float = 600.0
    """CPU ms per second all guided users' steps may take together."""
    window_s: float = 1.0
    shed_fraction: float = 1.0
    """Of the budget the daemon sees (``lag_budget_ms`` − ``unseen_ms``): the lag's p99 past
    it sheds. The p99 is the tail itself, so the whole of it (the p95 was judged against 60 %
    for the tail it did not see)."""
    readmit_fraction: float = 0.3
    """Of the budget the daemon sees: a p99 under it is calm, and readmits. At 100 users
    (dev VM, quiet) the deltas' p99 was 12-22 ms a second with 35-45 guided, and over the
    budget within seconds of a readmission of 6 in each worker at a p95 of 5."""
    sustain_s: float = 0.5
    settle_s: float = 1.0
    calm_s: float = 2.0
    min_shed_s: float = 5.0
    min_samples: int = 20
    """Fewer lags than this in a window say nothing about the lag (a quiet daemon)."""
    max_shed_share: float = 0.5
    """The most of the guided users one lag-driven decision sheds: the lag is a queue's, not
    linear in the load, so the next round measures again rather than trusting one ratio."""
    capacity_memory_s: float = 30.0
    readmit_share: float = 0.0
    """The most users guided again at once, as a share of those guided (at least one; 0: one
    at a time): each comes back with a snapshot to take and a whole path to plan. At 100 users
    (dev VM, quiet, two workers) a quarter (7-10 at once) took a worker from a p99 of 5-11 ms
    to 56-105 ms, whatever its own lag said: the other worker shares the cores."""
    drain_ratio: float = 0.8
    """The newer half-window's lag p95 under this share of the older half's: the lag is
    draining (a burst that passes), not a load the daemon cannot carry."""
    drain_patience_s: float = 2.0
    """How long a draining lag over the threshold is waited out before shedding anyway. A lag
    that grows or holds sheds after ``sustain_s`` as before."""
    drain_memory_s: float = 5.0
    """A lag over the threshold within this of one waited out as draining is not waited out
    again: bursts that come back are the load. At 100 users (dev VM, quiet) a worker's p99
    went over the line 1.2, 6, 1.3 and 3.8 s apart, each time draining; at 50 users the
    stalls waited out came 20 s apart."""
    overshoot_s: float = 10.0
    """A lag-driven shedding this soon after a readmission was that readmission's doing: at 100
    users on two workers (dev VM, quiet) sheds of 8-25 users came 1-9 s after readmissions of
    5-7, every 2-3 s."""
    max_calm_s: float = 16.0
    """The longest calm wanted before a readmission, however often readmissions overshot."""
    overshoot_memory_s: float = 60.0
    """How long an overshoot is remembered: until then the calm wanted stays doubled, and once
    the capacity it measured is forgotten users come back one at a time."""
