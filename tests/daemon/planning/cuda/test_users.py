"""Many planners on one device (issue 28): the device's one resident loop serves them all.

Planners of different map sizes and modes step interleaved, and in batches served side by
side (``cuda/batch.py``), each step bit-exact with the reference Dijkstra, without the loop
ever stopping; planners that go away give their slot back to the next, and a table that
fills up grows.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest

from daemon.planning import cuda_available
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(180),
]


@pytest.fixture(autouse=True)
def _fresh_loop(monkeypatch):
    from daemon.planning.cuda import resident

    resident.evict()
    monkeypatch.setattr(resident, "_SHARED", None)
    # the reference Dijkstra between steps is slow Python: no idle exit meanwhile
    monkeypatch.setattr(resident, "IDLE_MS", 60_000.0)
    yield resident
    resident.evict()


class User:
    """One planner, its map and goal, and a seeded walk of patches that open and close."""

    def __init__(self, seed: int, shape: tuple[int, int], dss: bool = False, planner=None) -> None:
        from daemon.planning.cuda.planner import CudaPlanner

        self.rng = np.random.default_rng(seed)
        self.truth = self.rng.random(shape) < 0.25
        h, w = shape
        self.goal = (int(self.rng.integers(h)), int(self.rng.integers(w)))
        self.truth[self.goal] = False
        self.p = planner or CudaPlanner("fast", dss=dss)
        self.p.plan(self.truth, self.goal)

    def change(self) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """The next step's delta (a patch opened and closed at random) and start."""
        h, w = self.truth.shape
        cy, cx, r = (int(v) for v in self.rng.integers((0, 0, 1), (h, w, 5)))
        ys, xs = np.mgrid[max(cy - r, 0) : min(cy + r + 1, h), max(cx - r, 0) : min(cx + r + 1, w)]
        cells = (ys * w + xs).ravel().astype(np.int64)
        values = self.rng.random(cells.size) < 0.6
        values[cells == self.goal[0] * w + self.goal[1]] = False
        self.truth.reshape(-1)[cells] = values
        return cells, values, (int(self.rng.integers(h)), int(self.rng.integers(w)))

    def check(self, path: np.ndarray, start: tuple[int, int]) -> None:
        g = dijkstra_field(self.truth, self.goal)
        assert np.array_equal(path, reference_path(g, self.truth, start))
        assert np.array_equal(self.p.costs(), g)

    def step(self) -> None:
        cells, values, start = self.change()
        _, path = self.p.update_and_path(cells, values, start)
        self.check(path, start)


def test_planners_of_every_size_step_interleaved_in_one_launch(_fresh_loop):
    """Four planners (one tile, a few tiles, more tiles than the loop has blocks, DSS beside
    EDS) step round-robin; every step is exact and the loop is launched once for all."""
    shapes = [(1, 1), (30, 70), (20, 20), (390, 380)]
    users = [User(s, shape, dss=s == 2) for s, shape in enumerate(shapes)]
    loop = _fresh_loop.active()
    assert loop is not None and loop.attached == 4
    launches = loop.launches
    for _ in range(6):
        for u in users:
            u.step()
    assert _fresh_loop.active() is loop and loop.launches == launches


def test_slots_are_given_back_and_the_table_grows(_fresh_loop):
    """More planners than the table's first size; the ones dropped free their slots, which
    new planners take, and every planner left stays exact."""
    n = _fresh_loop.SLOTS + 6
    users = [User(100 + k, (24, 40)) for k in range(n)]
    loop = _fresh_loop.shared()
    assert loop.attached == n
    for u in users[::7]:
        u.step()
    kept = users[1::2]
    del users, u
    gc.collect()
    assert loop.attached == len(kept)
    fresh = [User(500 + k, (33, 33)) for k in range(3)]
    assert loop.attached == len(kept) + 3
    for u in [*fresh, *kept[::5]]:
        u.step()


def batch_step(users: list[User]) -> None:
    """One step of every user as one batch; every path and field exact."""
    from daemon.planning.cuda.batch import step_many

    changes = [u.change() for u in users]
    results = step_many([(u.p, *c) for u, c in zip(users, changes, strict=True)])
    for u, c, res in zip(users, changes, results, strict=True):
        assert not isinstance(res, BaseException), res
        u.check(res[1], c[2])


def test_batched_steps_of_every_size_are_exact_in_one_launch(_fresh_loop):
    """Four planners (one tile, a few tiles, more tiles than the loop has blocks, DSS beside
    EDS) step as one batch, each on its own group of blocks, between steps of their own."""
    shapes = [(1, 1), (30, 70), (20, 20), (390, 380)]
    users = [User(10 + s, shape, dss=s == 2) for s, shape in enumerate(shapes)]
    loop = _fresh_loop.active()
    launches = loop.launches
    for r in range(5):
        batch_step(users if r % 2 else users[::-1])
        users[r % 4].step()
        batch_step(users[1:3])
    assert _fresh_loop.active() is loop and loop.launches == launches


def test_batched_cut_overs_keep_each_users_field_on_its_own_group(_fresh_loop):
    """Planners that cut over at every raise (cut_over=0) step as one batch: the cut-over's
    level and reset (cut_over.cuh) run on each call's own group of blocks and cover its whole
    map, so every field stays exact."""
    from daemon.planning.cuda.planner import CudaPlanner

    shapes = [(30, 70), (390, 380), (64, 64), (200, 150)]
    users = [
        User(40 + s, shape, planner=CudaPlanner("fast", cut_over=0.0))
        for s, shape in enumerate(shapes)
    ]
    for _ in range(6):
        batch_step(users)


def test_a_batch_of_more_calls_than_blocks_or_than_the_box_holds(_fresh_loop):
    """More calls than the device has blocks (a group serves several, one after another) and
    than one post holds (two batches): every step exact."""
    from daemon.planning.cuda import abi

    users = [User(1000 + k, (20 + k % 7, 24)) for k in range(abi.BATCH_MAX + 20)]
    for _ in range(2):
        batch_step(users)
    batch_step(users[::3])


def test_a_refused_delta_in_a_batch_is_its_users_alone(_fresh_loop):
    """In one batch: a delta out of order (a cell twice: sorted and posted again, its last
    value kept), a delta outside the map (IndexError in its place, nothing applied), and
    steps beside them served exact."""
    from daemon.planning.cuda.batch import step_many

    users = [User(2000 + k, (40, 50)) for k in range(4)]
    changes = [u.change() for u in users]
    cells, values, start = changes[1]
    changes[1] = (np.concatenate([cells, cells[:1]]), np.concatenate([values, values[:1]]), start)
    before = users[2].p.costs()
    bad = (np.array([40 * 50 + 3], dtype=np.int64), np.array([True]), changes[2][2])
    users[2].truth.reshape(-1)[changes[2][0]] = users[2].p.blocked().reshape(-1)[changes[2][0]]
    posted = [*changes[:2], bad, changes[3]]
    results = step_many([(u.p, *c) for u, c in zip(users, posted, strict=True)])
    assert isinstance(results[2], IndexError)
    assert np.array_equal(users[2].p.costs(), before)
    for k in (0, 1, 3):
        users[k].check(results[k][1], changes[k][2])
    batch_step(users)


def test_the_backends_planners_are_batched_where_the_device_serves_their_map(_fresh_loop):
    """make_planner("eds", "cuda") plans small maps on the CPU (small_grids.py): in a batch,
    those step on the host and the others go to the device, every one exact."""
    from daemon.planning.registry import make_planner

    users = [User(3000 + k, shape, planner=make_planner("eds", "cuda"))
             for k, shape in enumerate([(40, 50), (210, 200), (30, 30), (205, 210)])]  # fmt: skip
    assert [u.p.name for u in users] == ["eds-cpu-fast", "eds-cuda-fast"] * 2
    for _ in range(3):
        batch_step(users)


def test_planners_stepped_from_their_own_threads_at_once_share_posts_and_stay_exact(
    _fresh_loop, monkeypatch
):
    """As the daemon steps its users: each planner on a thread of its own, all released
    together each round. The steps combine into shared posts (``combine.py``); every path is
    the reference Dijkstra's and the CPU planner's, every field Dijkstra's. A delta outside
    its map fails that thread's step alone, and no thread is left behind. The combiner starts
    contended, as once calls have queued (a daemon under load): its waits let the other
    threads in to queue (``test_combine.py`` covers how it becomes so)."""
    import threading

    from daemon.planning.cuda import posting
    from daemon.planning.registry import make_planner

    shapes = [(30, 70), (20, 20), (64, 64), (390, 380), (45, 33), (100, 120), (1, 1), (64, 200)]
    users = [User(4000 + k, shape, dss=k == 2) for k, shape in enumerate(shapes)]
    cpus = [make_planner("dss" if k == 2 else "eds", "cpu") for k in range(len(users))]
    for u, cpu in zip(users, cpus, strict=True):
        cpu.plan(u.truth, u.goal)
    before = set(threading.enumerate())
    posts, calls = posting.STEPS.posts, posting.STEPS.calls
    monkeypatch.setattr(posting.STEPS, "_queued_at", posts)
    barrier = threading.Barrier(len(users))
    refused: list[BaseException] = []
    failures: list[BaseException] = []

    def walk(k: int) -> None:
        u, cpu = users[k], cpus[k]
        try:
            for r in range(6):
                if k == 0 and r == 3:  # a cell past the map's end
                    h, w = u.truth.shape
                    barrier.wait()
                    try:
                        u.p.update_and_path(np.array([h * w + 3]), np.array([True]), (0, 0))
                    except IndexError as exc:
                        refused.append(exc)
                    continue
                cells, values, start = u.change()
                barrier.wait()
                _, path = u.p.update_and_path(cells, values, start)
                _, want = cpu.update_and_path(cells, values, start)
                assert np.array_equal(path, want)
                u.check(path, start)
        except BaseException as exc:
            failures.append(exc)
            barrier.abort()

    threads = [threading.Thread(target=walk, args=(k,)) for k in range(len(users))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not failures, failures
    assert len(refused) == 1
    assert posting.STEPS.calls - calls == 6 * len(users)
    assert posting.STEPS.posts - posts < posting.STEPS.calls - calls  # some posts were shared
    assert set(threading.enumerate()) == before
