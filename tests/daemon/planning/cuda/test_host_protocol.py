"""The cuda backend's host side against a model of the device, on a machine without a GPU.

``CudaPlanner`` runs as it is (its ``plan``, ``update_and_path``, ``path``, the resident
loop's post and wait) with cupy replaced by a stand-in whose arrays are numpy's and the mapped
buffers by plain host memory (``conftest.py`` beside this file: the ``cuda`` fixture). The device is
``DeviceModel``: what ``resident.cuh`` (``take_delta``) and ``fast.cu`` do with a call, in
Python. It reads the params and the delta from the mailbox exactly where the kernels read
them, refuses deltas the way ``take_delta`` does, repairs the field with the reference
Dijkstra and writes statistics, path and done word where the kernels write them. So these
tests check the host's half of the protocol (the mailbox layout, the result words, the rare
cases: a refused delta, a stage that grows) in CI; the GPU
tests (``pytest -m gpu``) check the device's half.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from daemon.planning.cuda import abi
from daemon.planning.dijkstra import dijkstra_field, reference_path


class DeviceModel:
    """A call as the device serves it. ``loops``: slots attached (again whenever the buffers
    move); ``served`` and ``refused``: calls answered with a repair and with rejection bits."""

    ROUNDS, RAISED, TILES, SWEEPS, EXITS = 7, 3, 5, 11, 2  # distinct, to check the words read

    def __init__(self, cuda: SimpleNamespace, planner) -> None:
        self.cuda, self.p = cuda, planner
        self.loops = self.served = self.refused = 0
        self.last_params: tuple[int, ...] = ()

    def attach(self) -> None:
        """Serve ``p``'s calls: its resident loops are ``ModelLoop``s."""
        self.p._new_loop = self.new_loop

    def new_loop(self):
        model, res = self, self.cuda.resident

        class ModelLoop(res.ResidentLoop):
            def post(self, slot: int, n_delta: int) -> None:
                super().post(slot, n_delta)  # the real stores into the box, then the model
                assert self._mail[abi.BOX_SLOT] == slot
                post = self._mail[abi.BOX_POST : abi.BOX_POST + 2].view(np.int64)[0]
                assert post == (n_delta << 32) | self._gen
                model.serve_mailbox(model.p._stage.array, n_delta)

        self.loops += 1
        return ModelLoop(lambda *args: None).attach((0,) * abi.SLOT_WORDS, ())

    def serve_mailbox(self, mail: np.ndarray, n: int) -> None:
        cells = mail.view(np.int64)[abi.PARAMS // 2 : abi.PARAMS // 2 + n].copy()
        at = 4 * abi.PARAMS + 8 * n
        values = mail.view(np.uint8)[at : at + n] != 0
        self.serve(tuple(int(v) for v in mail[: abi.PARAM_USED]), cells, values)

    def serve(self, params: tuple[int, ...], cells, values) -> None:
        ck, p = abi, self.p
        words = (abi.PARAM_NDELTA, abi.PARAM_MODE, abi.PARAM_START, abi.PARAM_GOAL, abi.PARAM_SEQ)
        n, mode, start, goal, seq = (params[k] for k in words)
        assert n == cells.size
        self.last_params = params
        io, (h, w) = p._io_host.array, p._shape
        reject = 0  # take_delta: every cell in the map, strictly increasing
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
            status = ck.PATH_DONE if len(path) else ck.PATH_NONE
            io[ck.IO_PATH], io[ck.IO_PATH + 1] = len(path), status
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


def made(cuda, *, dss: bool = False):
    p = cuda.planner.CudaPlanner("fast", dss=dss)
    model = DeviceModel(cuda, p)
    model.attach()
    return p, model


def patch(rng, shape, size: int):
    """Sorted unique cells, as inflation gives them, and a value each."""
    cells = np.sort(rng.choice(shape[0] * shape[1], size=size, replace=False)).astype(np.int64)
    return cells, rng.random(size) < 0.5


@pytest.mark.timeout(60)
@pytest.mark.parametrize("dss", [False, True], ids=["eds", "dss"])
def test_steps_return_the_models_field_path_and_statistics(cuda, dss):
    rng, blocked, goal = world(0)
    planner, model = made(cuda, dss=dss)
    planner.plan(blocked, goal)
    truth = blocked.copy()
    for i in range(30):
        cells, values = patch(rng, blocked.shape, int(rng.integers(0, 60)))
        start = (int(rng.integers(40)), int(rng.integers(50)))
        truth.reshape(-1)[cells] = values
        stats, path = planner.update_and_path(cells, values, start)
        g = dijkstra_field(truth, goal)
        assert np.array_equal(path, reference_path(g, truth, start)), f"step {i}"
        mode = abi.MODE_DSS if dss else abi.MODE_EDS
        here = start[0] * 50 + start[1]
        assert model.last_params[:5] == (cells.size, mode, here, goal[0] * 50 + goal[1],
                                         planner._seq)  # fmt: skip
        # EDS is focused on the user's cell; DSS never is.
        assert model.last_params[abi.PARAM_FOCUS] == (-1 if dss else here)
        assert stats.iterations == model.ROUNDS + mode
        assert stats.cells_touched == model.RAISED + cells.size
        assert (planner.tiles, planner.sweeps, planner.exit_tiles) == (
            model.TILES, model.SWEEPS, model.EXITS)  # fmt: skip
        # EDS: costs() first settles what the focused repair deferred, in a call of its own
        # with no change and no focus.
        assert np.array_equal(planner.costs(), g)
        if not dss:
            assert model.last_params[abi.PARAM_NDELTA] == 0
            assert model.last_params[abi.PARAM_FOCUS] == -1
    assert np.array_equal(planner.blocked(), truth)
    assert model.served == (31 if dss else 61) and model.refused == 0 and model.loops == 1
    # A call with no change, served by the loop.
    assert np.array_equal(planner.path((39, 49)), reference_path(g, truth, (39, 49)))
    assert model.served == (32 if dss else 62) and model.last_params[0] == 0


@pytest.mark.timeout(60)
def test_a_delta_out_of_order_is_sorted_and_posted_again_once(cuda):
    """Repeated and unsorted cells: the loop refuses them, the host sorts them (each cell
    keeping its last value) and posts again."""
    _, blocked, goal = world(1)
    p, model = made(cuda)
    planner = p
    planner.plan(blocked, goal)
    cells = np.array([90, 17, 90, 400, 17], dtype=np.int64)
    values = np.array([True, True, False, True, False])
    _, path = planner.update_and_path(cells, values, (30, 40))
    truth = blocked.copy()
    truth.reshape(-1)[[90, 17, 400]] = [False, False, True]
    assert model.refused == 1 and model.served == 2
    assert model.last_params[0] == 3
    g = dijkstra_field(truth, goal)
    assert np.array_equal(path, reference_path(g, truth, (30, 40)))
    assert np.array_equal(p.blocked(), truth)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("bad", [-1, 40 * 50])
def test_a_cell_outside_the_map_is_refused_whole(cuda, bad):
    rng, blocked, goal = world(2)
    p, model = made(cuda)
    planner = p
    planner.plan(blocked, goal)
    with pytest.raises(IndexError):
        planner.update_and_path(np.array([5, 6, bad]), np.array([True, True, True]), (30, 40))
    assert model.refused == 1
    assert np.array_equal(p.blocked(), blocked)
    cells, values = patch(rng, blocked.shape, 20)  # the next step is served as usual
    _, path = planner.update_and_path(cells, values, (30, 40))
    truth = blocked.copy()
    truth.reshape(-1)[cells] = values
    assert np.array_equal(path, reference_path(dijkstra_field(truth, goal), truth, (30, 40)))
    assert np.array_equal(p.blocked(), truth)


@pytest.mark.timeout(60)
def test_a_new_map_has_room_for_large_deltas_and_a_larger_one_grows_it(cuda, monkeypatch):
    """A new map's mailbox and params buffer hold a delta of ``DELTA_ROOM`` of its cells: the
    growing deltas of a walk (a wall seen whole) are served by the loop that served the first
    step, where each doubling used to stop it and start another. A delta beyond the room
    grows them (the loop, which polls the mailbox, is stopped and a new one serves); a new map
    sizes the params buffer for itself while the mailbox stays large. (A floor of 64 cells
    instead of thousands: the rule at a map size the model's Dijkstra serves quickly.)"""
    ck, planner = abi, cuda.planner
    monkeypatch.setattr(planner, "DELTA_ROOM_MIN", 64)
    shape = (60, 80)
    room = int(planner.DELTA_ROOM * shape[0] * shape[1])
    assert room > planner.DELTA_ROOM_MIN  # the share decides here, not the floor
    rng, blocked, goal = world(3, shape=shape)
    p, model = made(cuda, dss=True)
    p.plan(blocked, goal)
    truth = blocked.copy()

    def step(size: int) -> None:
        cells, values = patch(rng, shape, size)
        truth.reshape(-1)[cells] = values
        _, path = p.update_and_path(cells, values, (50, 70))
        assert p._params.size >= ck.PARAMS + size
        assert p._stage.count >= ck.PARAMS + 4 * ((9 * size + 15) // 16)
        ref = reference_path(dijkstra_field(truth, goal), truth, (50, 70))
        assert np.array_equal(path, ref)

    step(10)
    loops = model.loops
    for size in (40, 90, 200, room):
        step(size)
    assert model.loops == loops  # no stop, no new loop
    step(room + 1)
    assert model.loops == loops + 1
    small = np.zeros((8, 8), dtype=bool)
    p.plan(small, (0, 0))
    assert p._params.size == ck.PARAMS + 8 * 8 < p._stage.count  # room for every cell
    cells, values = patch(rng, small.shape, 30)
    values[cells == 0] = False  # the goal stays free
    small.reshape(-1)[cells] = values
    _, path = p.update_and_path(cells, values, (7, 7))
    assert np.array_equal(path, reference_path(dijkstra_field(small, (0, 0)), small, (7, 7)))
