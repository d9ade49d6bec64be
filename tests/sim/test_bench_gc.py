"""The collector policy as the benchmark's walks run it: set-up frozen, no collection inside
a step (seen by a ``gc.callbacks`` recorder, not by a clock), collections between steps, and
a walked navigator freed once dropped."""

from __future__ import annotations

import gc
import weakref

import pytest

from daemon.navigation import Navigator
from daemon.runtime import gc_policy
from sim.bench_gc import GcRecorder
from sim.benchmark import settle_heap
from sim.courtyard import make_courtyard
from sim.walk import paper_settings, walk

pytestmark = pytest.mark.timeout(120)


def recorded_walk(max_steps: int) -> tuple[GcRecorder, weakref.ref]:
    scenario = make_courtyard(grid=50, unknown=0.4, seed=6)
    settle_heap()  # as the bench does before each walk (and the daemon once it is ready)
    nav = Navigator("walk", paper_settings(scenario, "eds", "cpu", "fast"))
    rec = GcRecorder(rss_every=10)
    undo = rec.install()
    try:
        walk(scenario, navigator=nav, max_steps=max_steps)
    finally:
        undo()
    return rec, weakref.ref(nav)


def test_a_walk_collects_only_between_steps_and_frees_its_navigator(
    collector_restored, monkeypatch
):
    gc.unfreeze()
    monkeypatch.setattr(gc_policy, "YOUNG_DUE", 20)  # several collections in a short walk
    rec, nav = recorded_walk(max_steps=40)
    assert gc.get_freeze_count() > 0  # what was built before the walk
    assert gc.get_threshold()[0] == gc_policy.CEILING
    assert len(rec.plan_ms) >= 30  # the walk stepped and replanned
    inside = [c for c in rec.collections if c.in_step or c.plan_call >= 0]
    assert inside == []
    assert [c.generation for c in rec.collections].count(0) >= 3  # each time one was due
    # A navigator is a reference cycle: nothing of the walk was frozen, so it is freed.
    gc.collect()
    assert nav() is None


def test_the_recorder_sees_a_collection_inside_a_step_when_one_runs_there(
    collector_restored, monkeypatch
):
    # The control of the test above: with a ceiling a step passes, the collector runs in steps.
    monkeypatch.setattr(gc_policy, "CEILING", 5)
    rec, _ = recorded_walk(max_steps=5)
    assert any(c.in_step for c in rec.collections)
    assert any(c.plan_call >= 0 for c in rec.collections)
