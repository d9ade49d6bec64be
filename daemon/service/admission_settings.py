"""Admission control's settings (``daemon.service.admission``), each with the measurement
behind it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class AdmissionSettings:
    lag_budget_ms: float = 50.0
    """The delay every guided user should stay within (the p99 the daemon promises)."""
    cpu_budget_ms: float = 600.0
    """CPU ms per second all guided users' steps may take together."""
    window_s: float = 1.0
    shed_fraction: float = 0.6
    readmit_fraction: float = 0.3
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
    readmit_share: float = 0.25
    """The most users guided again at once, as a share of those guided (at least one): each
    comes back with a snapshot to take and a whole path to plan."""
    drain_ratio: float = 0.8
    """The newer half-window's lag p95 under this share of the older half's: the lag is
    draining (a burst that passes), not a load the daemon cannot carry."""
    drain_patience_s: float = 2.0
    """How long a draining lag over the threshold is waited out before shedding anyway. A lag
    that grows or holds sheds after ``sustain_s`` as before."""
    overshoot_s: float = 10.0
    """A lag-driven shedding this soon after a readmission was that readmission's doing: at 100
    users on two workers (dev VM, quiet) sheds of 8-25 users came 1-9 s after readmissions of
    5-7, every 2-3 s."""
    max_calm_s: float = 16.0
    """The longest calm wanted before a readmission, however often readmissions overshot."""
    overshoot_memory_s: float = 60.0
    """How long an overshoot is remembered: until then the calm wanted stays doubled, and once
    the capacity it measured is forgotten users come back one at a time."""
