"""The resident loop (``cuda/resident.py``, ``kernels/resident.cuh``) on the GPU.

Calls posted to a running loop are served without a launch and stay bit-exact with the
reference Dijkstra; a loop that ended idle starts again; calls racing the loop's own idle exit
are not lost; planners take turns in one loop; copies leave a loop running, and a launch of
the path kernel makes it stop and come back.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from daemon.planning import cuda_available
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


@pytest.fixture(autouse=True)
def _no_loop_left():
    """Each test starts and ends with no loop holding the device (another test's kernels would
    wait for its idle exit)."""
    from daemon.planning.cuda import resident as cuda_resident

    cuda_resident.evict()
    cuda_resident._SHARED = None  # a fresh loop: its launch count is this test's
    yield
    cuda_resident.evict()


def case(seed: int, shape=(70, 90), steps=24):
    """A map, a goal and steps of (cells, values, start): patches that open and close."""
    rng = np.random.default_rng(seed)
    h, w = shape
    blocked = rng.random(shape) < 0.25
    goal = (int(rng.integers(h)), int(rng.integers(w)))
    blocked[goal] = False
    out = []
    for _ in range(steps):
        cy, cx, r = int(rng.integers(h)), int(rng.integers(w)), int(rng.integers(1, 6))
        ys, xs = np.mgrid[max(cy - r, 0) : min(cy + r + 1, h), max(cx - r, 0) : min(cx + r + 1, w)]
        cells = (ys * w + xs).ravel().astype(np.int64)
        values = rng.random(cells.size) < 0.6
        out.append((cells, values, (int(rng.integers(h)), int(rng.integers(w)))))
    return blocked, goal, out


def planner():
    from daemon.planning.cuda.planner import CudaPlanner

    return CudaPlanner("fast")


def walk(p, blocked, goal, steps, between=None):
    """Run the steps through ``update_and_path`` (every third one DSS: the same planner,
    switched, so that both modes share one loop), checking each."""
    truth = blocked.copy()
    for i, (cells, values, start) in enumerate(steps):
        if between is not None:
            between(i)
        truth.reshape(-1)[cells] = values
        g = dijkstra_field(truth, goal)  # before the step: costs() settles right after it
        p.dss = i % 3 == 2
        _, path = p.update_and_path(cells, values, start)
        assert np.array_equal(p.costs(), g), f"step {i}"
        assert np.array_equal(path, reference_path(g, truth, start)), f"step {i}"
    return truth


def test_steps_are_served_by_one_launch(monkeypatch):
    from daemon.planning.cuda import resident as cuda_resident

    # the reference Dijkstra between steps is slow Python: no idle exit meanwhile
    monkeypatch.setattr(cuda_resident, "IDLE_MS", 60_000.0)
    blocked, goal, steps = case(1)
    p = planner()
    p.plan(blocked, goal)
    walk(p, blocked, goal, steps)
    assert p._loop is not None and cuda_resident.active() is p._loop.loop
    # plan() and every step went to the same launch (costs() is a copy: it does not stop it)
    assert p._loop.launches == 1


def test_a_loop_that_ended_idle_starts_again(monkeypatch):
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 1.0)
    blocked, goal, steps = case(2, steps=10)
    p = planner()
    p.plan(blocked, goal)
    walk(p, blocked, goal, steps, between=lambda i: time.sleep(0.01))
    assert p._loop.launches == 1 + len(steps)


def test_calls_racing_the_idle_exit_are_not_lost(monkeypatch):
    """The loop ends a few µs after each call, so posts land just before, during and after
    its exit; ``wait`` starts it again when it ended without taking the call."""
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 0.005)
    blocked, goal, steps = case(3, steps=40)
    rng = np.random.default_rng(3)
    gaps = rng.choice([0.0, 2e-6, 5e-6, 2e-5, 1e-4], size=len(steps))
    p = planner()
    p.plan(blocked, goal)

    def spin(i: int) -> None:
        end = time.perf_counter() + gaps[i]
        while time.perf_counter() < end:
            pass

    walk(p, blocked, goal, steps, between=spin)
    assert p._loop.launches > 1


def test_planners_take_turns_in_one_loop(monkeypatch):
    """Two planners stepping in turn share the device's loop: no call stops it."""
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 60_000.0)

    cases = [case(4), case(5, shape=(40, 120))]
    planners = [planner(), planner()]
    truths = []
    for p, (blocked, goal, _) in zip(planners, cases, strict=True):
        p.plan(blocked, goal)
        truths.append(blocked.copy())
    loop = cuda_resident.active()
    assert loop is not None and all(p._loop.loop is loop for p in planners)
    launches = loop.launches
    for i in range(len(cases[0][2])):
        for k, p in enumerate(planners):
            blocked, goal, steps = cases[k]
            cells, values, start = steps[i]
            truths[k].reshape(-1)[cells] = values
            _, path = p.update_and_path(cells, values, start)
            assert cuda_resident.active() is loop
            g = dijkstra_field(truths[k], goal)
            assert np.array_equal(p.costs(), g)
            assert np.array_equal(path, reference_path(g, truths[k], start))
    assert loop.launches == launches  # every step of both went to the same launch


def test_queries_keep_the_loop_and_path_launches_stop_it(monkeypatch):
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 60_000.0)

    # Walls across every other row: a path longer than the path buffer, so its read-back
    # launches the path kernel, which must stop the loop first.
    h, w = 64, 64
    blocked = np.zeros((h, w), bool)
    for r in range(1, h, 2):
        blocked[r, :] = True
        blocked[r, w - 1 if r % 4 == 1 else 0] = False
    goal, start = (0, 0), (h - 2, w // 2)
    p = planner()
    p.plan(blocked, goal)
    loop = p._loop.loop
    g = dijkstra_field(blocked, goal)
    assert p.cost_at(start) == g[start] and np.array_equal(p.blocked(), blocked)
    assert cuda_resident.active() is loop and loop.launches == 1
    path = p.path(start)  # longer than the buffer: continued by path kernel launches
    assert len(path) > p._path_cap
    assert np.array_equal(path, reference_path(g, blocked, start))
    assert cuda_resident.active() is None
    short = (2, 5)
    assert np.array_equal(p.path(short), reference_path(g, blocked, short))
    assert cuda_resident.active() is loop and loop.launches == 2


def test_deltas_out_of_order_or_out_of_the_map(monkeypatch):
    """The loop checks the raw delta on the device: cells out of order are sorted on the host
    and posted again (a cell's last value wins); a cell outside the map rejects the whole
    delta with IndexError, nothing applied, and the loop goes on serving."""
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 60_000.0)
    blocked, goal, _ = case(6)
    h, w = blocked.shape
    p = planner()
    p.plan(blocked, goal)
    free = [int(c) for c in np.flatnonzero(~blocked.ravel()) if c != goal[0] * w + goal[1]][:3]
    a, b, c = free
    # a twice: blocked, then free again (last wins); b blocked; c listed before a
    cells = np.array([a, b, c, a], dtype=np.int32)  # int32: the copy into the mailbox casts
    values = np.array([True, True, False, False])
    p.update(cells, values)
    truth = blocked.copy()
    truth.reshape(-1)[[b, c]] = [True, False]
    assert np.array_equal(p.blocked(), truth)
    assert np.array_equal(p.costs(), dijkstra_field(truth, goal))
    before = p.costs()
    for bad in ([c, h * w], [-1], [h * w + 5, a]):
        with pytest.raises(IndexError):
            p.update(np.array(bad), np.array([True] * len(bad)))
        assert np.array_equal(p.costs(), before) and np.array_equal(p.blocked(), truth)
    _, path = p.update_and_path(np.array([a]), np.array([True]), (0, 0))
    truth.reshape(-1)[a] = True
    g = dijkstra_field(truth, goal)
    assert np.array_equal(p.costs(), g)
    assert np.array_equal(path, reference_path(g, truth, (0, 0)))
    assert p._loop.launches == 1


def test_deltas_longer_than_one_pass_of_the_loop(monkeypatch):
    """take_delta reads the mailbox in passes of TAKE_CELLS (1024) cells: a long delta is
    applied whole; a repeated cell whose two entries straddle a pass boundary is caught as out
    of order (its last value wins after the host sorts it); a cell outside the map in a later
    pass rejects the whole delta."""
    from daemon.planning.cuda import resident as cuda_resident

    monkeypatch.setattr(cuda_resident, "IDLE_MS", 60_000.0)
    rng = np.random.default_rng(11)
    h, w = 100, 129
    blocked = rng.random((h, w)) < 0.2
    goal = (50, 64)
    blocked[goal] = False
    p = planner()
    p.plan(blocked, goal)
    truth = blocked.copy()
    others = np.array([c for c in range(h * w) if c != goal[0] * w + goal[1]], dtype=np.int64)
    cells = others[: 3 * 1024 + 100]  # four passes
    values = rng.random(cells.size) < 0.3
    _, path = p.update_and_path(cells, values, (0, 0))
    truth.reshape(-1)[cells] = values
    g = dijkstra_field(truth, goal)
    assert np.array_equal(p.costs(), g)
    assert np.array_equal(path, reference_path(g, truth, (0, 0)))
    for x in others[2000:2005]:
        # entries 1023 and 1024 both name x: blocked, then free (the last wins)
        dup = np.concatenate([np.sort(rng.choice(others[others < x], 1023, replace=False)), [x, x]])
        vals = np.zeros(dup.size, dtype=bool)
        vals[1023] = True
        p.update(dup, vals)
        truth.reshape(-1)[dup] = vals
        truth.reshape(-1)[x] = False
        assert np.array_equal(p.blocked(), truth)
        assert np.array_equal(p.costs(), dijkstra_field(truth, goal))
    before, known = p.costs(), p.blocked()
    launches = p._loop.launches  # a refused delta leaves the loop running
    bad = others[:1500].copy()
    bad[1400] = h * w  # in the second pass
    with pytest.raises(IndexError):
        p.update(np.sort(bad), np.ones(bad.size, dtype=bool))
    assert np.array_equal(p.costs(), before) and np.array_equal(p.blocked(), known)
    assert p._loop.launches == launches
