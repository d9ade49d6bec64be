"""The cuda backend's host side against a model of the device, on a machine without a GPU.

``CudaPlanner`` runs as it is (its ``plan``, ``update_and_path``, ``path``, the resident
loop's post and wait, ``FallbackPlanner`` around it) with cupy replaced by a stand-in whose
arrays are numpy's and the mapped buffers by plain host memory (``cuda_standin``). The device is
``DeviceModel``: what ``resident.cuh`` (``take_delta``) and ``fast.cu`` do with a call, in
Python. It reads the params and the delta from the mailbox exactly where the kernels read
them, refuses deltas the way ``take_delta`` does, repairs the field with the reference
Dijkstra and writes statistics, path and done word where the kernels write them. So these
tests check the host's half of the protocol (the mailbox layout, the result words, the rare
cases: a refused delta, a stage that grows, a launch instead of the loop) in CI; the GPU
tests (``pytest -m gpu``) check the device's half.
"""

from __future__ import annotations

import importlib
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from daemon.planning.cuda_standin import HostPinned, standin_cupy
from daemon.planning.dijkstra import dijkstra_field
from daemon.planning.interface import reference_path


@pytest.fixture
def cuda(monkeypatch):
    """The cuda modules imported afresh over the stand-in cupy, and removed again after."""
    prefix = "daemon.planning.cuda_"
    for name in [n for n in sys.modules if n.startswith(prefix) and "standin" not in n]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "cupy", standin_cupy())
    ck = importlib.import_module("daemon.planning.cuda_kernels")
    monkeypatch.setattr(ck, "Pinned", HostPinned)
    mods = SimpleNamespace(
        ck=ck,
        resident=importlib.import_module("daemon.planning.cuda_resident"),
        launch=importlib.import_module("daemon.planning.cuda_launch"),
        planner=importlib.import_module("daemon.planning.cuda_planner"),
        fallback=importlib.import_module("daemon.planning.fallback"),
    )
    yield mods
    mods.resident._ACTIVE = None
    package = sys.modules["daemon.planning"]
    for name in [n for n in sys.modules if n.startswith(prefix) and "standin" not in n]:
        del sys.modules[name]
        if hasattr(package, name.rsplit(".", 1)[1]):
            delattr(package, name.rsplit(".", 1)[1])


class DeviceModel:
    """A call as the device serves it. ``loops``: resident loops started; ``served`` and
    ``refused``: calls answered with a repair and with rejection bits."""

    ROUNDS, RAISED, TILES, SWEEPS, EXITS = 7, 3, 5, 11, 2  # distinct, to check the words read

    def __init__(self, cuda: SimpleNamespace, planner) -> None:
        self.cuda, self.p = cuda, planner
        self.loops = self.served = self.refused = 0
        self.last_params: tuple[int, ...] = ()

    def attach(self) -> None:
        """Serve ``p``'s calls: its resident loops are ``ModelLoop``s, its launches this."""
        self.p._new_loop = self.new_loop
        self.p._queue_fast = self.serve_launch

    def new_loop(self):
        model, res = self, self.cuda.resident

        class ModelLoop(res.ResidentLoop):
            def post(self, seq: int, n_delta: int) -> None:
                super().post(seq, n_delta)  # the real store into the mailbox, then the model
                model.serve_mailbox(self._mail, seq, n_delta)

        self.loops += 1
        return ModelLoop(lambda stream: None, self.p._stage.array, ())

    def serve_mailbox(self, mail: np.ndarray, seq: int, n: int) -> None:
        ck, res = self.cuda.ck, self.cuda.resident
        assert mail[res.MB_POST : res.MB_POST + 2].view(np.int64)[0] == (n << 32) | seq
        cells = mail.view(np.int64)[ck.PARAMS // 2 : ck.PARAMS // 2 + n].copy()
        at = 4 * ck.PARAMS + 8 * n
        values = mail.view(np.uint8)[at : at + n] != 0
        self.serve(tuple(int(v) for v in mail[:5]), cells, values, check=True)

    def serve_launch(self, up: int) -> None:
        ck, stage = self.cuda.ck, self.p._stage.array
        codes = stage[ck.PARAMS : up].astype(np.int64)
        self.serve(tuple(int(v) for v in stage[:5]), codes >> 1, (codes & 1) != 0, check=False)

    def serve(self, params: tuple[int, ...], cells, values, check: bool) -> None:
        ck, p = self.cuda.ck, self.p
        n, mode, start, goal, seq = params
        assert n == cells.size
        self.last_params = params
        io, (h, w) = p._io_host.array, p._shape
        if check:  # take_delta: every cell in the map, strictly increasing
            reject = 0
            if n and (cells.min() < 0 or cells.max() >= h * w):
                reject |= ck.REJECT_RANGE
            elif n > 1 and not (np.diff(cells) > 0).all():
                reject |= ck.REJECT_ORDER
            if reject:
                self.refused += 1
                io[ck.IO_REJECT], io[ck.IO_DONE] = reject, seq
                return
        p._blocked_d[cells] = values
        blocked = p._blocked_d.reshape(h, w) != 0
        g = dijkstra_field(blocked, (goal // w, goal % w))
        p._g[:] = g.ravel()
        io[: ck.CTRL_READ] = 0
        io[ck.C_ROUNDS] = self.ROUNDS + mode
        io[ck.C_RAISED], io[ck.C_CHANGED] = self.RAISED, n
        io[ck.C_TILES], io[ck.C_SWEEPS], io[ck.C_EXITS] = self.TILES, self.SWEEPS, self.EXITS
        if start >= 0:
            path = reference_path(g, blocked, (start // w, start % w))
            assert 2 * len(path) <= 2 * p._path_cap
            io[ck.IO_PATH], io[ck.IO_PATH + 1] = len(path), 0 if len(path) else 2
            io[ck.IO_PATH + 2 : ck.IO_PATH + 2 + 2 * len(path)] = path.ravel()
        io[ck.IO_REJECT] = 0
        io[ck.IO_DONE] = seq
        self.served += 1


def world(seed: int, shape=(40, 50)):
    rng = np.random.default_rng(seed)
    blocked = rng.random(shape) < 0.2
    goal = (2, 3)
    blocked[goal] = False
    return rng, blocked, goal


def made(cuda, *, resident: bool = True):
    p = cuda.planner.CudaPlanner("fast", resident=resident, use_graph=False)
    model = DeviceModel(cuda, p)
    model.attach()
    return p, model


def patch(rng, shape, size: int):
    """Sorted unique cells, as inflation gives them, and a value each."""
    cells = np.sort(rng.choice(shape[0] * shape[1], size=size, replace=False)).astype(np.int64)
    return cells, rng.random(size) < 0.5


@pytest.mark.timeout(60)
@pytest.mark.parametrize("resident", [True, False], ids=["resident", "launched"])
def test_steps_return_the_models_field_path_and_statistics(cuda, resident):
    rng, blocked, goal = world(0)
    p, model = made(cuda, resident=resident)
    planner = cuda.fallback.FallbackPlanner(p, errors=())
    planner.plan(blocked, goal)
    truth = blocked.copy()
    for i in range(30):
        cells, values = patch(rng, blocked.shape, int(rng.integers(0, 60)))
        start = (int(rng.integers(40)), int(rng.integers(50)))
        truth.reshape(-1)[cells] = values
        full = i % 3 == 2
        stats, path = planner.update_and_path(cells, values, start, full=full)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(path, reference_path(g, truth, start)), f"step {i}"
        assert np.array_equal(planner.costs(), g)
        assert model.last_params == (cells.size, int(not full), start[0] * 50 + start[1],
                                     goal[0] * 50 + goal[1], p._seq)  # fmt: skip
        assert stats.iterations == model.ROUNDS + int(not full)
        assert stats.cells_touched == model.RAISED + cells.size
        assert (p.tiles, p.sweeps, p.exit_tiles) == (model.TILES, model.SWEEPS, model.EXITS)
    assert np.array_equal(planner.mirrored_blocked(), truth)
    assert model.served == 31 and model.refused == 0
    assert model.loops == (1 if resident else 0)
    if resident:  # a call with no change, served by the loop (launched: the path kernel's)
        assert np.array_equal(p.path((39, 49)), reference_path(g, truth, (39, 49)))
        assert model.served == 32 and model.last_params[0] == 0


@pytest.mark.timeout(60)
def test_a_delta_out_of_order_is_sorted_and_posted_again_once(cuda):
    """Repeated and unsorted cells: the loop refuses them, the host sorts them (each cell
    keeping its last value) and posts again; the fallback's copy is made once."""
    _, blocked, goal = world(1)
    p, model = made(cuda)
    planner = cuda.fallback.FallbackPlanner(p, errors=())
    planner.plan(blocked, goal)
    hooks = []
    copy = planner._copy_change
    planner._copy_change = lambda: (hooks.append(1), copy())
    cells = np.array([90, 17, 90, 400, 17], dtype=np.int64)
    values = np.array([True, True, False, True, False])
    _, path = planner.update_and_path(cells, values, (30, 40))
    truth = blocked.copy()
    truth.reshape(-1)[[90, 17, 400]] = [False, False, True]
    assert model.refused == 1 and model.served == 2 and len(hooks) == 1
    assert model.last_params[0] == 3
    g = dijkstra_field(truth, goal)
    assert np.array_equal(path, reference_path(g, truth, (30, 40)))
    assert np.array_equal(planner.mirrored_blocked(), truth)
    assert np.array_equal(p.blocked(), truth)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("bad", [-1, 40 * 50])
def test_a_cell_outside_the_map_is_refused_whole(cuda, bad):
    rng, blocked, goal = world(2)
    p, model = made(cuda)
    planner = cuda.fallback.FallbackPlanner(p, errors=())
    planner.plan(blocked, goal)
    with pytest.raises(IndexError):
        planner.update_and_path(np.array([5, 6, bad]), np.array([True, True, True]), (30, 40))
    assert model.refused == 1
    assert np.array_equal(p.blocked(), blocked)
    assert np.array_equal(planner.mirrored_blocked(), blocked)
    cells, values = patch(rng, blocked.shape, 20)  # the next step is served as usual
    _, path = planner.update_and_path(cells, values, (30, 40))
    truth = blocked.copy()
    truth.reshape(-1)[cells] = values
    assert np.array_equal(path, reference_path(dijkstra_field(truth, goal), truth, (30, 40)))
    assert np.array_equal(planner.mirrored_blocked(), truth)


@pytest.mark.timeout(60)
def test_a_delta_larger_than_the_mailbox_grows_it_and_restarts_the_loop(cuda):
    """The mailbox and the loop's params buffer grow for a large delta (the loop, which polls
    the mailbox, is stopped and a new one serves); a new map then shrinks the params buffer
    while the mailbox stays large, and a large delta grows the params buffer again."""
    ck = cuda.ck
    rng, blocked, goal = world(3, shape=(60, 60))
    p, model = made(cuda)
    p.plan(blocked, goal)
    truth = blocked.copy()
    loops = model.loops
    for size in (10, 700, 2500, 3500):
        cells, values = patch(rng, blocked.shape, size)
        truth.reshape(-1)[cells] = values
        _, path = p.update_and_path(cells, values, (50, 50), full=True)
        assert p._params.size >= ck.PARAMS + size
        assert p._stage.count >= ck.PARAMS + 4 * ((9 * size + 15) // 16)
        assert np.array_equal(path, reference_path(dijkstra_field(truth, goal), truth, (50, 50)))
    assert model.loops > loops
    small = np.zeros((40, 40), dtype=bool)
    p.plan(small, (0, 0))
    assert p._params.size < ck.PARAMS + 1500 < p._stage.count
    cells, values = patch(rng, small.shape, 1500)
    values[cells == 0] = False  # the goal stays free
    small.reshape(-1)[cells] = values
    _, path = p.update_and_path(cells, values, (39, 39))
    assert p._params.size >= ck.PARAMS + 1500
    assert np.array_equal(path, reference_path(dijkstra_field(small, (0, 0)), small, (39, 39)))
