"""``gc_policy``: set-up frozen, the automatic threshold out of a step's reach, the young
generation collected between steps when due, and the generation CPython's schedule would pick."""

from __future__ import annotations

import gc

import pytest

from daemon.runtime import gc_policy


@pytest.fixture
def collections():
    seen: list[int] = []

    def note(phase: str, info: dict) -> None:
        if phase == "stop":
            seen.append(info["generation"])

    gc.callbacks.append(note)
    yield seen
    gc.callbacks.remove(note)


def litter(n: int) -> list:
    return [[i] for i in range(n)]  # n tracked objects that stay alive


def test_settle_freezes_what_set_up_built_and_installs_the_threshold(
    collector_restored, collections
):
    gc.unfreeze()
    gc.set_threshold(700, 10, 10)
    gc_policy.settle()
    assert collections == [2] and gc.get_freeze_count() > 0
    assert gc.get_threshold() == (gc_policy.CEILING, gc_policy.MIDDLE_EVERY, gc_policy.OLD_EVERY)


def test_the_young_generation_is_collected_between_steps_when_due(collector_restored, collections):
    gc_policy.after_step()
    assert gc.get_threshold()[0] == gc_policy.CEILING
    gc.collect(0)
    collections.clear()
    kept = litter(gc_policy.YOUNG_DUE // 2)
    gc_policy.after_step()
    assert collections == []  # not due yet
    kept += litter(gc_policy.YOUNG_DUE)
    assert collections == []  # the automatic threshold is far above a step's allocations
    gc_policy.after_step()
    assert collections and collections[-1] in (0, 1, 2)
    assert gc.get_count()[0] < gc_policy.YOUNG_DUE // 10


def test_the_older_generations_follow_cpythons_schedule(collector_restored, collections):
    gc_policy.install()
    gc.collect()
    collections.clear()
    kept = []
    # A middle collection once MIDDLE_EVERY young ones are done, an old one once OLD_EVERY
    # middle ones are: one whole round, each step leaving a collection due.
    for _ in range((gc_policy.MIDDLE_EVERY + 1) * gc_policy.OLD_EVERY + 1):
        kept += litter(gc_policy.YOUNG_DUE)
        gc_policy.after_step()
    assert collections[-1] == 2 and collections.count(2) == 1
    assert collections.count(1) == gc_policy.OLD_EVERY
    assert collections.count(0) == gc_policy.MIDDLE_EVERY * gc_policy.OLD_EVERY
