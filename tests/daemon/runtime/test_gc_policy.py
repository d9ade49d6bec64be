"""``gc_policy.after_step``: a planner's set-up frozen once, the young generation collected
between steps when due, and the generation CPython's own schedule would pick."""

from __future__ import annotations

import gc
from types import SimpleNamespace

import pytest

from daemon.runtime import gc_policy


@pytest.fixture
def collector_restored():
    threshold = gc.get_threshold()
    yield
    gc.set_threshold(*threshold)
    gc.unfreeze()


@pytest.fixture
def collections():
    seen: list[int] = []

    def note(phase: str, info: dict) -> None:
        if phase == "stop":
            seen.append(info["generation"])

    gc.callbacks.append(note)
    yield seen
    gc.callbacks.remove(note)


class Nav:
    """What the policy reads of a ``Navigator``: its planner and whether the step planned."""

    def __init__(self) -> None:
        self.route = SimpleNamespace(planner=object())
        self.last = SimpleNamespace(plan=SimpleNamespace(planned=True))


def litter(n: int) -> list:
    return [[i] for i in range(n)]  # n tracked objects that stay alive


def test_the_set_up_is_frozen_once_per_planner(collector_restored, collections):
    gc.unfreeze()
    nav = Nav()
    kept = litter(100)
    gc_policy.after_step(nav)
    assert collections == [2] and gc.get_freeze_count() > 0
    frozen = gc.get_freeze_count()
    gc_policy.after_step(nav)  # planned again (a new goal), same planner: nothing
    assert collections == [2] and gc.get_freeze_count() == frozen
    nav.route.planner = object()  # a new planner (the move to the CPU): its set-up too
    gc_policy.after_step(nav)
    assert collections == [2, 2]
    assert kept


def test_the_young_generation_is_collected_between_steps_when_due(collector_restored, collections):
    nav = Nav()
    gc_policy.after_step(nav)  # the set-up
    nav.last.plan.planned = False
    collections.clear()
    assert gc.get_threshold()[0] == gc_policy.CEILING
    gc.collect(0)
    collections.clear()
    kept = litter(gc_policy.YOUNG_DUE // 2)
    gc_policy.after_step(nav)
    assert collections == []  # not due yet
    kept += litter(gc_policy.YOUNG_DUE)
    assert collections == []  # the automatic threshold is far above a step's allocations
    gc_policy.after_step(nav)
    assert collections and collections[-1] in (0, 1, 2)
    assert gc.get_count()[0] < gc_policy.YOUNG_DUE // 10


def test_the_older_generations_follow_cpythons_schedule(collector_restored, collections):
    nav = Nav()
    gc_policy.after_step(nav)
    nav.last.plan.planned = False
    gc.collect()
    collections.clear()
    kept = []
    # A middle collection once MIDDLE_EVERY young ones are done, an old one once OLD_EVERY
    # middle ones are: one whole round, each step leaving a collection due.
    for _ in range((gc_policy.MIDDLE_EVERY + 1) * gc_policy.OLD_EVERY + 1):
        kept += litter(gc_policy.YOUNG_DUE)
        gc_policy.after_step(nav)
    assert collections[-1] == 2 and collections.count(2) == 1
    assert collections.count(1) == gc_policy.OLD_EVERY
    assert collections.count(0) == gc_policy.MIDDLE_EVERY * gc_policy.OLD_EVERY
