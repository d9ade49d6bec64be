"""The interpreter's garbage collector kept out of the navigator's steps.

CPython collects its youngest generation when the tracked objects allocated since the last
collection (less those freed) pass a threshold (700 by default), in whatever code is running
then: a replanning step, on the walk a user feels. The usual policy of real-time Python
services is applied here:

* ``settle()`` once set-up is done (the daemon when it is ready, the bench before a walk):
  collect, then ``gc.freeze()``: what start-up built (~116,000 tracked objects: modules,
  compiled code, the warm-up) moves to the permanent generation, which no collection scans;
* the automatic young threshold raised to ``CEILING``, which no ordinary step reaches (a step
  leaves about ten tracked objects behind: a 400² walk's ~560 steps passed 700 eight times;
  the ceiling only bounds memory should something allocate without end);
* ``after_step()`` between steps, once the step's output is put: as soon as ``YOUNG_DUE``
  objects wait, a collection of the generation CPython's own schedule would take: the
  default's pace, so memory is held as before, and each collection as short as before.

A user's set-up is not frozen: it adds ~40 tracked objects (its maps and fields are numpy
arrays, which the collector does not track), and a navigator is a reference cycle (its
guidance asks it for the planner), so one frozen while alive would never be freed once the
daemon forgets the user, arrays and all.

With several users stepping on worker threads, one user's collection between its steps still
holds the interpreter while it runs, so another's step may wait for it; what the policy
removes is the collection's place inside the step that triggered it.

``after_step()`` is made by the daemon's runner after every step and by the simulator's walks
(``sim.closed_loop``) too, so the benchmark measures what the daemon runs.
"""

from __future__ import annotations

import gc

YOUNG_DUE = 700
"""Tracked objects waiting before a between-step collection: CPython's default threshold 0."""
MIDDLE_EVERY = 10
OLD_EVERY = 10
"""Young (middle) collections between middle (old) ones: CPython's thresholds 1 and 2."""
CEILING = 50_000
"""The automatic young threshold: only a step that allocates this many tracked objects
collects inside itself."""


def install() -> None:
    """Raise the automatic threshold (idempotent; ``settle`` and ``after_step`` do it)."""
    if gc.get_threshold()[0] != CEILING:
        gc.set_threshold(CEILING, MIDDLE_EVERY, OLD_EVERY)


def settle() -> None:
    """Once set-up is done: collect everything, then freeze what survives, and install the
    threshold so every step after it runs under the policy."""
    install()
    gc.collect()
    gc.freeze()


def after_step() -> None:
    """Between two steps: collect if a collection is due, the generation CPython would."""
    install()
    young, middle, old = gc.get_count()
    if young < YOUNG_DUE:
        return
    gc.collect(2 if old >= OLD_EVERY else 1 if middle >= MIDDLE_EVERY else 0)
