"""The deferred-blocks rule right after a repair: the next step repairs without the check,
and between steps the wrapper learns whether the check would have held (``deferred_blocks.py``).

The map, path and cells of ``test_deferred_blocks_rule.py``.
"""

from __future__ import annotations

import numpy as np

from daemon.planning.deferred_blocks import DeferredBlocks

from .test_deferred_blocks_rule import GOAL, OFF, ON, USER, N, reference, walking


def cut_then(planner: DeferredBlocks, path: np.ndarray) -> np.ndarray:
    """A repair (a block on P's suffix) and its answer out: the new path."""
    _, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(path[1]))
    planner.between_steps()
    return got


def test_after_a_repair_a_step_repairs_unchecked_and_the_next_checks_if_it_would_have_held(
    monkeypatch,
):
    from daemon.planning import deferred_blocks

    planner, spy, truth, path = walking()
    got = cut_then(planner, path)
    checks: list[int] = []
    check = deferred_blocks.defer_step
    monkeypatch.setattr(deferred_blocks, "defer_step", lambda *a: checks.append(1) or check(*a))
    _, got = planner.update_and_path(np.array([OFF]), np.array([True]), tuple(got[1]))
    assert not checks and len(spy.steps) == 3 and planner.unchecked_steps == 1
    truth.reshape(-1)[[ON, OFF]] = True
    np.testing.assert_array_equal(got, reference(truth, tuple(got[0])))
    planner.between_steps()  # OFF missed the path: the next step checks, and defers
    _, later = planner.update_and_path(np.array([OFF + 1]), np.array([True]), tuple(got[1]))
    assert checks == [1] and len(spy.steps) == 3 and planner.deferred_steps == 1
    np.testing.assert_array_equal(later, got[1:])


def test_an_unchecked_step_that_cut_the_path_leaves_the_next_unchecked_too():
    planner, spy, truth, path = walking()
    got = cut_then(planner, path)
    ahead = int(got[3][0]) * N + int(got[3][1])  # on the path that went round ON
    _, got = planner.update_and_path(np.array([ahead]), np.array([True]), tuple(got[1]))
    planner.between_steps()
    _, got = planner.update_and_path(np.array([OFF]), np.array([True]), tuple(got[1]))
    assert len(spy.steps) == 4 and planner.unchecked_steps == 2 and planner.deferred_steps == 0
    truth.reshape(-1)[[ON, ahead, OFF]] = True
    np.testing.assert_array_equal(got, reference(truth, tuple(got[0])))


def test_without_between_steps_the_next_step_still_learns_whether_to_check():
    planner, spy, _truth, path = walking()
    _, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(path[1]))
    _, got = planner.update_and_path(np.array([OFF]), np.array([True]), tuple(got[1]))
    assert len(spy.steps) == 3 and planner.unchecked_steps == 1
    _, later = planner.update_and_path(np.array([OFF + 1]), np.array([True]), tuple(got[1]))
    assert len(spy.steps) == 3 and planner.deferred_steps == 1
    np.testing.assert_array_equal(later, got[1:])


def test_a_plan_makes_the_next_step_check_again():
    planner, _spy, truth, path = walking()
    cut_then(planner, path)
    planner.plan(truth, GOAL)
    _, path = planner.update_and_path(np.empty(0, np.int64), np.empty(0, bool), USER)
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    assert planner.deferred_steps == 1 and planner.unchecked_steps == 0
