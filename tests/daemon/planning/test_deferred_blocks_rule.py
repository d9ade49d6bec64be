"""The rule of ``deferred_blocks.py`` case by case: what defers, what repairs, what flushes.

A 20 x 20 open map whose path is one column: cells on it, off it and behind the user are
known, so each test says exactly which steps reach the inner planner (a ``Spy``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from daemon.planning import make_planner, registry
from daemon.planning.cpu.fast import FastCpuPlanner
from daemon.planning.deferred_blocks import DeferredBlocks
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF


class Spy:
    """Counts the inner planner's steps and updates, and keeps their deltas."""

    def __init__(self, inner: FastCpuPlanner) -> None:
        self.steps: list[tuple[np.ndarray, np.ndarray]] = []
        self.updates: list[tuple[np.ndarray, np.ndarray]] = []
        step, update = inner.update_and_path, inner.update

        def spied_step(cells, blocked, start):
            self.steps.append((np.asarray(cells).copy(), np.asarray(blocked).copy()))
            return step(cells, blocked, start)

        def spied_update(cells, blocked):
            self.updates.append((np.asarray(cells).copy(), np.asarray(blocked).copy()))
            return update(cells, blocked)

        inner.update_and_path = spied_step  # type: ignore[method-assign]
        inner.update = spied_update  # type: ignore[method-assign]


N = 20
GOAL, USER = (1, 10), (18, 10)  # a straight column: the path is (18..1, 10)
OFF = 5 * N + 3  # a cell far off the path
ON = 9 * N + 10  # a cell on the path ahead of the user


def walking() -> tuple[DeferredBlocks, Spy, np.ndarray, np.ndarray]:
    truth = np.zeros((N, N), bool)
    planner = DeferredBlocks(FastCpuPlanner(cut_over=1e6), defer=True)
    spy = Spy(planner.inner)  # type: ignore[arg-type]
    planner.plan(truth, GOAL)
    _, path = planner.update_and_path(np.empty(0, np.int64), np.empty(0, bool), USER)
    assert len(spy.steps) == 1 and path[0].tolist() == list(USER)
    return planner, spy, truth, path


def reference(truth: np.ndarray, start) -> np.ndarray:
    return reference_path(dijkstra_field(truth, GOAL), truth, start)


def test_a_block_off_the_path_defers():
    planner, spy, truth, path = walking()
    user = tuple(int(v) for v in path[1])
    stats, got = planner.update_and_path(np.array([OFF]), np.array([True]), user)
    assert len(spy.steps) == 1 and not spy.updates  # no inner call
    assert (stats.iterations, stats.cells_touched) == (0, 0) and stats.ms >= 0
    assert planner.deferred_steps == 1 and planner.pending_blocks() == 1
    np.testing.assert_array_equal(got, path[1:])
    assert not planner.inner.blocked().reshape(-1)[OFF]  # type: ignore[attr-defined]
    truth.reshape(-1)[OFF] = True
    np.testing.assert_array_equal(got, reference(truth, user))


def test_a_block_on_the_suffix_repairs_with_the_pending_blocks_merged():
    planner, spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    _stats, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(path[2]))
    assert len(spy.steps) == 2 and planner.deferred_steps == 1
    assert sorted(spy.steps[1][0].tolist()) == sorted([OFF, ON]) and spy.steps[1][1].all()
    truth.reshape(-1)[[OFF, ON]] = True
    np.testing.assert_array_equal(got, reference(truth, tuple(path[2])))
    assert planner.pending_blocks() == 0


def test_between_steps_the_pending_blocks_go_and_the_path_stays_for_the_next_step():
    planner, spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    planner.between_steps()
    # a step of the inner planner from the user's cell (the device posts it with others')
    assert planner.pending_blocks() == 0 and not spy.updates and len(spy.steps) == 2
    assert spy.steps[1][0].tolist() == [OFF] and spy.steps[1][1].all()
    assert planner.inner.blocked().reshape(-1)[OFF]  # type: ignore[attr-defined]
    _, got = planner.update_and_path(np.array([OFF + 1]), np.array([True]), tuple(path[2]))
    assert len(spy.steps) == 2 and planner.deferred_steps == 2  # P kept: it defers again
    truth.reshape(-1)[[OFF, OFF + 1]] = True
    np.testing.assert_array_equal(got, reference(truth, tuple(path[2])))
    _, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(path[3]))
    assert spy.steps[2][0].tolist() == [OFF + 1, ON]  # the repair carries one step's blocks
    truth.reshape(-1)[ON] = True
    np.testing.assert_array_equal(got, reference(truth, tuple(path[3])))
    planner.between_steps()  # nothing pending: no call
    assert len(spy.steps) == 3 and not spy.updates


def test_the_pending_step_is_taken_from_the_users_cell_on_the_path():
    planner, spy, truth, path = walking()
    assert planner.pending_step() is None  # nothing pending
    planner.update_and_path(np.array([OFF, OFF + 1]), np.array([True, True]), tuple(path[2]))
    step = planner.pending_step()
    assert step is not None and planner.pending_blocks() == 0
    inner, cells, blocked, start = step
    assert inner is planner.inner and sorted(cells.tolist()) == [OFF, OFF + 1]
    assert blocked.all() and start == tuple(int(v) for v in path[2])
    _, got = inner.update_and_path(cells, blocked, start)
    np.testing.assert_array_equal(got, path[2:])  # the rule's proof: P's suffix
    truth.reshape(-1)[[OFF, OFF + 1]] = True
    np.testing.assert_array_equal(got, reference(truth, start))
    assert len(spy.steps) == 2


def test_a_block_behind_the_user_defers_and_one_under_the_user_repairs():
    planner, spy, _truth, path = walking()
    behind = int(path[0][0]) * N + int(path[0][1])
    planner.update_and_path(np.array([behind]), np.array([True]), tuple(path[1]))
    assert len(spy.steps) == 1
    under = int(path[2][0]) * N + int(path[2][1])
    _, got = planner.update_and_path(np.array([under]), np.array([True]), tuple(path[2]))
    assert len(spy.steps) == 2 and len(got) == 0  # the user stands in an obstacle: no path


def test_a_free_repairs():
    planner, spy, truth, _path = walking()
    truth.reshape(-1)[ON] = True
    planner.update(np.array([ON]), np.array([True]))
    _, got = planner.update_and_path(np.array([ON]), np.array([False]), USER)
    assert len(spy.steps) == 2 and planner.deferred_steps == 0
    truth.reshape(-1)[ON] = False
    np.testing.assert_array_equal(got, reference(truth, USER))


def test_a_user_off_the_path_repairs():
    planner, spy, truth, _path = walking()
    _, got = planner.update_and_path(np.array([OFF]), np.array([True]), (18, 2))
    assert len(spy.steps) == 2 and planner.deferred_steps == 0
    truth.reshape(-1)[OFF] = True
    np.testing.assert_array_equal(got, reference(truth, (18, 2)))


def test_a_pending_block_freed_again_leaves_no_trace():
    planner, spy, truth, path = walking()
    planner.update_and_path(np.array([OFF, OFF + 1]), np.array([True, True]), tuple(path[1]))
    _, got = planner.update_and_path(np.array([OFF]), np.array([False]), tuple(path[2]))
    cells, values = spy.steps[1]
    # the pending block of OFF is gone; its free reaches the inner planner as a no-op
    assert sorted(cells.tolist()) == [OFF, OFF + 1]
    assert dict(zip(cells.tolist(), values.tolist(), strict=True)) == {OFF: False, OFF + 1: True}
    truth.reshape(-1)[OFF + 1] = True
    inner = planner.inner
    assert inner.blocked().reshape(-1)[OFF] == False  # noqa: E712
    np.testing.assert_array_equal(got, reference(truth, tuple(path[2])))
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, GOAL))


READS: dict[str, Callable[[DeferredBlocks], object]] = {
    "path": lambda p: p.path((18, 2)),
    "cost_at": lambda p: p.cost_at((5, 4)),
    "costs": lambda p: p.costs(),
    "costs_within": lambda p: p.costs_within(3, 8, 1, 6),
    "settle": lambda p: p.settle(),
    "pending": lambda p: p.pending(),
    "blocked": lambda p: p.blocked(),
    "update": lambda p: p.update(np.array([OFF + 2]), np.array([True])),
}


@pytest.mark.parametrize("read", READS)
def test_each_read_flushes_the_pending_blocks_first(read):
    planner, _spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    assert planner.pending_blocks() == 1
    READS[read](planner)
    assert planner.pending_blocks() == 0
    assert planner.inner.blocked().reshape(-1)[OFF]  # type: ignore[attr-defined]
    truth.reshape(-1)[OFF] = True
    if read == "update":
        truth.reshape(-1)[OFF + 2] = True
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, GOAL))
    assert planner.cost_at((5, 3)) == int(INF)


def test_a_plan_discards_what_was_pending_and_the_path():
    planner, spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    planner.plan(truth, GOAL)  # the whole map, without OFF
    assert planner.pending_blocks() == 0 and not spy.updates
    planner.update_and_path(np.array([OFF + 1]), np.array([True]), tuple(path[2]))
    assert len(spy.steps) == 2  # no P after a plan: the step repairs
    truth.reshape(-1)[OFF + 1] = True
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, GOAL))


def test_a_delta_outside_the_map_is_refused_and_keeps_what_is_pending():
    planner, _spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    with pytest.raises(IndexError):
        planner.update_and_path(np.array([N * N]), np.array([True]), tuple(path[2]))
    assert planner.pending_blocks() == 1
    truth.reshape(-1)[OFF] = True
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, GOAL))


def test_the_routes_per_step_reads_are_answered_without_a_lookup_miss(monkeypatch):
    # ``getattr(planner, "max_open", None)`` and ``search_stats`` at every step: class
    # attributes, so ``__getattr__`` (and its flush) never runs for them
    assert "max_open" in vars(DeferredBlocks) and "search_stats" in vars(DeferredBlocks)
    assert isinstance(make_planner("eds", "cuda"), DeferredBlocks)  # built before any cupy
    assert not isinstance(make_planner("eds", "cpu"), DeferredBlocks)  # the device's only
    monkeypatch.setattr(registry, "DEFER_BLOCKS_ON_DEVICE", False)  # a bench's comparison
    assert not isinstance(make_planner("eds", "cuda"), DeferredBlocks)


def test_on_the_host_by_default_every_call_is_the_inner_planners_own():
    inner = FastCpuPlanner()
    planner = DeferredBlocks(inner)
    planner.plan(np.zeros((N, N), bool), GOAL)
    assert not planner.defers and planner.name == "eds-cpu-fast"
    assert planner.update_and_path == inner.update_and_path and planner.path == inner.path
    _, path = planner.update_and_path(np.array([OFF]), np.array([True]), USER)
    _, path = planner.update_and_path(np.array([OFF + 1]), np.array([True]), tuple(path[1]))
    assert planner.deferred_steps == 0 and planner.pending_blocks() == 0


def test_a_path_read_from_the_suffix_keeps_the_pending_blocks_and_one_elsewhere_is_one_step():
    planner, spy, truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    truth.reshape(-1)[OFF] = True
    got = planner.path(tuple(path[3]))  # the route's read at a step that changed nothing
    np.testing.assert_array_equal(got, path[3:])
    np.testing.assert_array_equal(got, reference(truth, tuple(path[3])))
    assert len(spy.steps) == 1 and not spy.updates and planner.pending_blocks() == 1
    got = planner.path((18, 2))  # off P: the pending blocks and the read in one inner step
    assert len(spy.steps) == 2 and not spy.updates and planner.pending_blocks() == 0
    assert spy.steps[1][0].tolist() == [OFF]
    np.testing.assert_array_equal(got, reference(truth, (18, 2)))


def test_deltas_of_any_array_form_defer_alike_through_one_compiled_check():
    from daemon.planning import deferred_check

    planner, spy, _truth, path = walking()
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    compiled = list(deferred_check.defer_step.signatures)
    assert len(compiled) == 1  # the route's form: int64 cells, bool values, both writeable
    readonly = np.array([OFF + 1])
    readonly.flags.writeable = False
    strided = np.array([OFF + 2, -1, OFF + 3])[::2]
    forms = [
        (np.array([OFF + 4], dtype=np.int32), np.array([True])),
        (readonly, np.array([True])),
        (strided, np.array([True, True])),
        ([OFF + 5], True),  # a list and one value for every cell
        (np.array([[OFF + 6]]), np.ones((1, 1), dtype=np.uint8)),
    ]
    for step, (cells, values) in enumerate(forms, start=2):
        _stats, got = planner.update_and_path(cells, values, tuple(path[step]))
        np.testing.assert_array_equal(got, path[step:])
    assert len(spy.steps) == 1 and planner.deferred_steps == 1 + len(forms)
    assert planner.pending_blocks() == 1 + 1 + 1 + 2 + 1 + 1
    assert list(deferred_check.defer_step.signatures) == compiled  # nothing compiled in a step
    # the same forms with a cell on the suffix repair
    _stats, got = planner.update_and_path([ON], True, tuple(path[7]))
    assert len(spy.steps) == 2


def test_the_warm_up_runs_the_compiled_check_with_the_routes_array_form(monkeypatch):
    from daemon.planning import deferred_blocks, deferred_check
    from daemon.planning.warm import exercise

    seen: list[tuple] = []
    learned: list[tuple] = []

    def spy_on(check, into):
        def spied(*args):
            into.append(tuple((a.dtype, a.ndim, a.flags.c_contiguous, a.flags.writeable)
                              for a in args if isinstance(a, np.ndarray)))  # fmt: skip
            return check(*args)

        return spied

    class TwoParts(FastCpuPlanner):  # as the cuda backend's EDS lists its planners
        def parts(self) -> list[FastCpuPlanner]:
            return [FastCpuPlanner(), FastCpuPlanner()]

    monkeypatch.setattr(deferred_blocks, "defer_step", spy_on(deferred_check.defer_step, seen))
    learn = spy_on(deferred_check.misses_suffix, learned)
    monkeypatch.setattr(deferred_blocks, "misses_suffix", learn)
    exercise(DeferredBlocks(FastCpuPlanner(), defer=True))
    alone = len(seen)
    assert alone > 0
    exercise(DeferredBlocks(TwoParts()))  # each part is exercised behind the rule
    assert len(seen) == 3 * alone
    flag, index = (np.dtype(bool), 1, True, True), (np.dtype(np.int64), 1, True, True)
    # P's cells, its marks, the delta's cells and values, the pending marks and cells
    assert set(seen) == {(index, flag, index, flag, flag, index)}
    # and, after a step that repaired unchecked: P's suffix, its marks, the delta
    assert learned and set(learned) == {(index, flag, index, flag)}


def test_while_the_device_is_shared_every_step_is_the_inner_planners_own(monkeypatch):
    from daemon.planning import deferred_blocks

    planner, spy, truth, path = walking()
    shared = [True]
    planner.inner.shared_now = lambda: shared[0]  # type: ignore[attr-defined]
    planner.update_and_path(np.array([OFF]), np.array([True]), tuple(path[1]))
    planner.between_steps()  # other users' steps meet ours: no post of its own
    assert planner.pending_blocks() == 1 and len(spy.steps) == 1 and not spy.updates
    checks: list[int] = []
    check = deferred_blocks.defer_step
    monkeypatch.setattr(deferred_blocks, "defer_step", lambda *a: checks.append(1) or check(*a))
    user = tuple(path[2])
    _, got = planner.update_and_path(np.array([OFF + 1]), np.array([True]), user)
    assert spy.steps[1][0].tolist() == [OFF, OFF + 1] and not checks  # no rule: a step
    truth.reshape(-1)[[OFF, OFF + 1]] = True
    np.testing.assert_array_equal(got, reference(truth, user))
    shared[0] = False
    planner.between_steps()  # the device alone again: the next repair's path is P
    _, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(got[1]))
    planner.between_steps()
    assert len(spy.steps) == 3 and checks == []  # no P to check against
    _, later = planner.update_and_path(np.array([OFF + 2]), np.array([True]), tuple(got[1]))
    assert checks == [1] and planner.deferred_steps == 2 and len(spy.steps) == 3
    planner.between_steps()
    assert planner.pending_blocks() == 0 and spy.steps[3][0].tolist() == [OFF + 2]
    np.testing.assert_array_equal(later, got[1:])


def test_between_steps_marks_the_path_a_repair_returned_so_the_next_step_need_not():
    planner, _spy, _truth, path = walking()
    _, got = planner.update_and_path(np.array([ON]), np.array([True]), tuple(path[1]))
    assert planner._fresh is not None  # P's marks wait for the answer to be out
    planner.between_steps()  # nothing pending: only the marks
    assert planner._fresh is None and planner._flat is not None
    assert planner._on.reshape(-1)[planner._flat].all() and planner._on.sum() == len(got)
