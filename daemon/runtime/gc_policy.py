"""The interpreter's garbage collector kept out of the navigator's steps.

CPython collects its youngest generation when the tracked objects allocated since the last
collection (less those freed) pass a threshold (700 by default), in whatever code is running
then: a replanning step, on the walk a user feels. The usual policy of real-time Python
services is applied here:

* ``gc.freeze()`` once a user's planner is set up (after the step that first planned with
  it): what start-up and the set-up built moves to the permanent generation, which no
  collection scans again;
* the automatic young threshold raised to ``CEILING``, which no ordinary step reaches (a step
  leaves about ten tracked objects behind: a 400² walk's ~560 steps passed 700 eight times;
  the ceiling only bounds memory should something allocate without end);
* a collection between steps (``after_step``, once the step's output is put), of the
  generation CPython's own schedule would collect, as soon as ``YOUNG_DUE`` objects wait: the
  default's pace, so memory is held as before, and each collection as short as before.

With several users stepping on worker threads, one user's collection between its steps still
holds the interpreter while it runs, so another's step may wait for it; what the policy
removes is the collection's place inside the step that triggered it.

One call, ``after_step(navigator)``, is the whole policy: the daemon's runner makes it after
every step and the simulator's walks (``sim.closed_loop``) do too, so the benchmark measures
what the daemon runs.
"""

from __future__ import annotations

import gc
import weakref
from typing import Any

YOUNG_DUE = 700
"""Tracked objects waiting before a between-step collection: CPython's default threshold 0."""
MIDDLE_EVERY = 10
OLD_EVERY = 10
"""Young (middle) collections between middle (old) ones: CPython's thresholds 1 and 2."""
CEILING = 50_000
"""The automatic young threshold: only a step that allocates this many tracked objects
collects inside itself."""

_frozen_for: weakref.WeakKeyDictionary[Any, int] = weakref.WeakKeyDictionary()
"""Per navigator, the planner (its ``id``) whose set-up was frozen."""


def install() -> None:
    """Raise the automatic threshold (idempotent; ``after_step`` does it)."""
    if gc.get_threshold()[0] != CEILING:
        gc.set_threshold(CEILING, MIDDLE_EVERY, OLD_EVERY)


def settle() -> None:
    """Collect everything, then freeze what survives: long-lived from now on. Installs the
    policy's threshold, so the steps after it (the set-up's own step too) run under it."""
    install()
    gc.collect()
    gc.freeze()


def after_step(navigator: Any) -> None:
    """Between two steps of ``navigator`` (a ``Navigator``): freeze its planner's set-up once,
    then collect the young generation if it is due."""
    install()
    planner = id(navigator.route.planner)
    if navigator.last.plan.planned and _frozen_for.get(navigator) != planner:
        settle()
        _frozen_for[navigator] = planner
        return
    young, middle, old = gc.get_count()
    if young < YOUNG_DUE:
        return
    gc.collect(2 if old >= OLD_EVERY else 1 if middle >= MIDDLE_EVERY else 0)
