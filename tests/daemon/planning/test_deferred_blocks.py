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

from daemon.planning import cuda_available, make_planner, registry
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
    "cpu-paper": lambda: make_planner("eds", "cpu", "paper"),
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
    # the rule on the host too (the registry applies it to device-served maps only)
    return DeferredBlocks(INNERS[inner_name](), defer=True)  # type: ignore[arg-type]


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
        if data.draw(st.booleans(), label="idle"):  # the answer out: the pending blocks go
            planner.between_steps()
            assert planner.pending_blocks() == 0
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


@pytest.mark.gpu
@pytest.mark.timeout(300)
def test_a_batch_answers_deferred_steps_on_the_host_and_posts_the_others(monkeypatch):
    """``batch.step_many`` with wrapped planners of device-served maps: a step whose blocks
    miss the path is never posted; one whose blocks cut it posts them with what was pending;
    every path is the reference's."""
    if not cuda_available():
        pytest.skip("no usable CUDA device")
    from daemon.planning.cuda import batch, resident

    monkeypatch.setattr(resident, "IDLE_MS", 60_000.0)  # slow Python references between steps
    posted: list[int] = []
    post_steps = batch.post_steps

    def counted(posts):
        posted.append(len(posts))
        return post_steps(posts)

    monkeypatch.setattr(batch, "post_steps", counted)
    shape, goal = (210, 200), (3, 100)
    monkeypatch.setattr(registry, "DEFER_BLOCKS_ON_DEVICE", True)
    users = [make_planner("eds", "cuda") for _ in range(3)]
    truths = [np.zeros(shape, bool) for _ in users]
    starts = [(200, 100), (200, 60), (180, 150)]
    paths = []
    for p, truth, start in zip(users, truths, starts, strict=True):
        assert isinstance(p, DeferredBlocks)
        p.plan(truth, goal)
        paths.append(p.update_and_path(np.empty(0, np.int64), np.empty(0, bool), start)[1])
    was_cut = [False] * len(users)
    for rnd in range(6):
        steps, cut = [], []
        for k, (p, truth, path) in enumerate(zip(users, truths, paths, strict=True)):
            start = tuple(int(v) for v in path[1])
            ahead = path[min(len(path) - 1, 20)]
            if (k + rnd) % 3 == 0:  # blocks beside the path's end: cut it
                cells = np.array([int(ahead[0]) * shape[1] + int(ahead[1])])
            else:  # blocks far off every path
                cells = np.array([(100 + rnd) * shape[1] + 5, (100 + rnd) * shape[1] + 6])
            truth.reshape(-1)[cells] = True
            steps.append((p, cells, np.ones(cells.size, bool), start))
            cut.append((k + rnd) % 3 == 0)
        # right after a cut a step repairs unchecked; the one after checks, and defers
        defers = [not c and not w for c, w in zip(cut, was_cut, strict=True)]
        before = [(p.deferred_steps, p.unchecked_steps) for p in users]
        posted.clear()
        results = batch.step_many(steps)
        for k, ((p, _, _, start), res) in enumerate(zip(steps, results, strict=True)):
            assert not isinstance(res, BaseException), res
            ref = reference_path(dijkstra_field(truths[k], goal), truths[k], start)
            np.testing.assert_array_equal(res[1], ref)
            assert p.deferred_steps == before[k][0] + defers[k]
            assert p.unchecked_steps == before[k][1] + was_cut[k]
            paths[k] = res[1]
        assert sum(posted) == defers.count(False)  # the deferred steps were never posted
        was_cut = cut
        if rnd % 2:  # the blocks deferred, given between steps: every user's in one post
            posted.clear()
            waiting = sum(p.pending_blocks() > 0 for p in users)
            assert batch.between_steps_many(users) == [None] * len(users)
            assert [p.pending_blocks() for p in users] == [0] * len(users)
            assert posted == ([waiting] if waiting else [])
    for p, truth in zip(users, truths, strict=True):
        np.testing.assert_array_equal(p.costs(), dijkstra_field(truth, goal))
