"""EDS steps that skip the repair (``deferred_blocks.py``): the contract still holds.

After every ``update_and_path`` the path is ``reference_path`` of the current map, cell for
cell, whether the step repaired or deferred its delta; after ``settle()`` the whole field is
Dijkstra's. A user walks the returned paths and sometimes jumps off them; deltas block cells
off the path (which defer), on it, free cells, or mix both. The cuda cases (``-m gpu``) run
the same walk on ``CudaPlanner`` and compare its paths with the CPU's.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.planning import cuda_available, make_planner
from daemon.planning.cpu.fast import FastCpuPlanner
from daemon.planning.deferred_blocks import DeferredBlocks
from daemon.planning.dijkstra import dijkstra_field, reference_path
from daemon.planning.grid import INF, path_cost

PROPERTY = settings(
    max_examples=int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "40")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

KINDS = ("off_path", "off_path", "on_path", "free", "mixed", "none")


def _cuda_inner():
    from daemon.planning.cuda.planner import CudaPlanner

    return CudaPlanner("fast")


INNERS: dict[str, Callable[[], object]] = {
    "cpu-fast": lambda: FastCpuPlanner(),
    "cpu-fast-repair": lambda: FastCpuPlanner(cut_over=1e6),  # never a plan from scratch
    "cpu-paper": lambda: make_planner("eds", "cpu", "paper").inner,
    "cuda-fast": _cuda_inner,
}
CASES = [
    pytest.param("cpu-fast", id="cpu-fast"),
    pytest.param("cpu-fast-repair", id="cpu-fast-repair"),
    pytest.param("cpu-paper", id="cpu-paper"),
    pytest.param("cuda-fast", id="cuda-fast", marks=pytest.mark.gpu),
]


def wrapped(inner_name: str) -> DeferredBlocks:
    if inner_name.startswith("cuda") and not cuda_available():
        pytest.skip("no usable CUDA device")
    return DeferredBlocks(INNERS[inner_name]())  # type: ignore[arg-type]


@st.composite
def worlds(draw):
    h, w = draw(st.integers(4, 48)), draw(st.integers(4, 48))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    truth = rng.random((h, w)) < draw(st.sampled_from([0.0, 0.1, 0.2]))
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    user = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    truth[goal] = truth[user] = False
    return truth, goal, user


def draw_delta(data, truth: np.ndarray, path: np.ndarray, kind: str):
    """(flat cells, values) of one kind; no repeated cell."""
    h, w = truth.shape
    on = path[:, 0].astype(np.int64) * w + path[:, 1] if len(path) else np.empty(0, np.int64)
    if kind == "none":
        return np.empty(0, np.int64), np.empty(0, bool)
    if kind == "on_path" and on.size:
        pick = data.draw(st.lists(st.integers(0, on.size - 1), min_size=1, max_size=3), label="at")
        cells = np.unique(on[pick])
        return cells, np.ones(cells.size, bool)
    seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    pool = np.setdiff1d(np.arange(h * w), on) if kind == "off_path" else np.arange(h * w)
    if kind == "free":
        pool = np.flatnonzero(truth.reshape(-1))
    if pool.size == 0:
        return np.empty(0, np.int64), np.empty(0, bool)
    cells = rng.choice(pool, size=min(pool.size, int(rng.integers(1, 12))), replace=False)
    if kind == "mixed":
        return cells.astype(np.int64), rng.random(cells.size) < 0.5
    return cells.astype(np.int64), np.full(cells.size, kind != "free")


def walk_and_check(planner: DeferredBlocks, world, data, twin: DeferredBlocks | None = None):
    """The walk of the module's docstring; ``twin`` (another backend) must read the same
    paths. Returns the steps deferred."""
    truth, goal, user = world
    truth = truth.copy()
    for p in (planner, twin):
        if p is not None:
            p.plan(truth, goal)
    path = np.empty((0, 2), np.int32)
    deferred = 0
    for step in range(data.draw(st.integers(2, 14), label="steps")):
        # the first step reads a path; the second blocks cells off it, from its next cell:
        # the deferral is exercised in every run that has a path
        kind = "none" if step == 0 else "off_path" if step == 1 else None
        kind = kind or data.draw(st.sampled_from(KINDS), label="kind")
        if len(path) > 1 and data.draw(st.integers(0, 4), label="move") > 0:
            user = tuple(int(v) for v in path[min(len(path) - 1, 1 + (step % 3 == 0))])
        elif step > 1 and data.draw(st.booleans(), label="jump"):
            user = (data.draw(st.integers(0, truth.shape[0] - 1), label="r"),
                    data.draw(st.integers(0, truth.shape[1] - 1), label="c"))  # fmt: skip
        had_path = len(path) > 0 and bool((path == np.array(user)).all(axis=1).any())
        cells, values = draw_delta(data, truth, path, kind)
        truth.reshape(-1)[cells] = values
        before = planner.deferred_steps
        stats, path = planner.update_and_path(cells, values, user)
        g = dijkstra_field(truth, goal)
        ref = reference_path(g, truth, user)
        np.testing.assert_array_equal(path, ref, err_msg=f"step {step} ({kind}), user {user}")
        if len(path):
            assert path_cost(path) == int(g[user])
        if step == 1 and had_path:
            assert planner.deferred_steps == before + 1, "blocks off the path did not defer"
        if planner.deferred_steps > before:
            deferred += 1
            assert (stats.iterations, stats.cells_touched) == (0, 0)
        if twin is not None:
            _, twin_path = twin.update_and_path(cells, values, user)
            np.testing.assert_array_equal(twin_path, path)
        if data.draw(st.integers(0, 5), label="read") == 0:  # a read flushes what is pending
            cell = (data.draw(st.integers(0, truth.shape[0] - 1), label="rr"),
                    data.draw(st.integers(0, truth.shape[1] - 1), label="rc"))  # fmt: skip
            assert planner.cost_at(cell) == (int(INF) if truth[cell] else int(g[cell]))
            assert planner.pending_blocks() == 0
    settle = getattr(planner, "settle", None)  # the fast planners' (paper's field is exact)
    if settle is not None:
        settle()
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, goal))
    assert planner.pending_blocks() == 0 and getattr(planner, "pending", lambda: 0)() == 0
    return deferred


@pytest.mark.timeout(600)
@pytest.mark.parametrize("inner", CASES)
@PROPERTY
@given(world=worlds(), data=st.data())
def test_every_step_reads_the_reference_path_deferred_or_not(inner, world, data):
    walk_and_check(wrapped(inner), world, data)


@pytest.mark.gpu
@pytest.mark.timeout(600)
@PROPERTY
@given(world=worlds(), data=st.data())
def test_cuda_and_cpu_read_the_same_paths(world, data):
    walk_and_check(wrapped("cuda-fast"), world, data, twin=wrapped("cpu-fast"))


@pytest.mark.parametrize("inner", CASES)
def test_the_bench_walks_defer_and_read_the_reference(inner):
    """A seeded 60² walk with the sensor's own deltas (most blocks fall off the path)."""
    planner = wrapped(inner)
    rng = np.random.default_rng(7)
    truth = np.zeros((60, 60), bool)
    hidden = rng.random((60, 60)) < 0.15
    goal, user = (2, 30), (57, 30)
    hidden[goal] = hidden[user] = False
    planner.plan(truth, goal)
    _, path = planner.update_and_path(np.empty(0, np.int64), np.empty(0, bool), user)
    for _ in range(200):
        if len(path) < 2:
            break
        user = (int(path[1][0]), int(path[1][1]))
        r, c = user
        seen = np.zeros_like(truth)
        seen[max(0, r - 4) : r + 5, max(0, c - 4) : c + 5] = True
        new = np.flatnonzero((seen & hidden & ~truth).reshape(-1))
        truth.reshape(-1)[new] = True
        _, path = planner.update_and_path(new, np.ones(new.size, bool), user)
        ref = reference_path(dijkstra_field(truth, goal), truth, user)
        np.testing.assert_array_equal(path, ref)
    assert planner.deferred_steps > 0
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(truth, goal))


# -- the rule, case by case ---------------------------------------------------------------


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
    planner = DeferredBlocks(FastCpuPlanner(cut_over=1e6))
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


def test_the_routes_per_step_reads_are_answered_without_a_lookup_miss():
    # ``getattr(planner, "max_open", None)`` and ``search_stats`` at every step: class
    # attributes, so ``__getattr__`` (and its flush) never runs for them
    assert "max_open" in vars(DeferredBlocks) and "search_stats" in vars(DeferredBlocks)
    planner = make_planner("eds", "cpu")
    assert isinstance(planner, DeferredBlocks) and planner.name == "eds-cpu-fast"
    assert not isinstance(make_planner("dss", "cpu"), DeferredBlocks)
