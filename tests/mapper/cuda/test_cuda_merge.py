"""The device's merge (``kernels/merge_cells.cu``, ``cuda_merge``) against ``merge.merge_frame``:
fed the same binned frames, the same map, log-odds, seen-at, changed cells and proximity, to
the bit, through forgetting and refusals, also when the changes overflow the graph's
read-back."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mapper.backends import Binner, cuda_usable
from mapper.binning import bin_frame_cpu
from mapper.frame import count_valid
from mapper.occupancy_mapper import UNKNOWN, MapperSettings, OccupancyMapper
from sim.camera import RgbdCamera
from sim.courtyard import make_courtyard
from sim.scene3d import scene_from_scenario

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_usable(), reason="no usable CUDA device"),
]


class DeviceMergeOfCpuBins:
    """The numba pass's ``Binned`` laid out as the cuda pass leaves it on the device, then
    merged there: the merge alone differs from the cpu mapper's."""

    def __init__(self) -> None:
        import cupy as cp

        from mapper import cuda_merge

        self.cp, self.cm = cp, cuda_merge
        self.dmap: cuda_merge.DeviceMap | None = None
        self.stream = cp.cuda.Stream(non_blocking=True)

    def merge(self, maps: tuple, params: list[float], *args) -> tuple:
        cp, cm = self.cp, self.cm
        if self.dmap is None:
            self.dmap = cm.DeviceMap(maps[0].shape)
        self.dmap.attach(*maps)
        b = bin_frame_cpu(*args)
        depth, t, win = args[0], args[4], args[6]
        bins = b.hit.shape[0]
        pixels = np.array([b.valid, count_valid(depth)], np.int32)
        points = (b.hit.ravel().view(np.int32), b.far.ravel().view(np.int32))
        out = np.concatenate((b.counts.ravel().astype(np.int32), pixels, *points))
        p = np.zeros(64)
        p[13], p[14], p[21], p[24], p[25] = t[0], t[1], win.cell_m, win.r0, win.c0
        p[27 : 27 + len(params)] = params
        tail = cm.MergeTail(win.side, self.dmap)
        # Uncaptured, the calls the graph holds run at once on the stream.
        keys = cp.empty(bins, cp.uint64), cp.empty(bins, cp.uint64)  # reset, unused here
        tail.capture(self.stream, cp.asarray(out), cp.asarray(p), bins, *keys)
        self.stream.synchronize()
        return tail.result()

    def pull(self, logodds: np.ndarray, seen_at: np.ndarray) -> None:
        assert self.dmap is not None
        self.dmap.pull(logodds, seen_at)


def walk() -> list:
    """Six courtyard frames walking north, then two 15 s later looking south: the first
    views' obstacles, out of view and unseen for 10 s, are forgotten."""
    scene = scene_from_scenario(make_courtyard(100, 0.2, 0))
    cam, rng = RgbdCamera(), np.random.default_rng(1)
    shots = [(0.65 + 0.1 * i, math.pi / 2 + 0.05 * i, 10.0 + i) for i in range(6)]
    shots += [(1.2 + 0.05 * i, -math.pi / 2, 30.0 + i) for i in range(2)]
    return [cam.render(scene, cam.pose(5.05, y, yaw), stamp, rng) for y, yaw, stamp in shots]


@pytest.mark.parametrize("spare", [None, 1 - 65 * 65], ids=["graph", "overflow"])
def test_the_device_merge_is_the_cpus_to_the_bit(monkeypatch, spare):
    from mapper import cuda_merge

    if spare is not None:  # the graph brings back one cell: the rest by the second copy
        monkeypatch.setattr(cuda_merge, "SPARE", spare)
    settings = MapperSettings(backend="cpu")
    cpu, gpu = OccupancyMapper(settings), OccupancyMapper(settings)
    gpu.binner = Binner("device-merge", bin_frame_cpu, counts_valid=True, merges=True)
    gpu.binner._fn = DeviceMergeOfCpuBins()
    forgotten = changed = 0
    for f in walk():
        a, b = cpu.process(f), gpu.process(f)
        assert np.array_equal(a.cells, b.cells)
        assert np.array_equal(a.values, b.values)
        assert a.proximity == b.proximity
        assert a.valid == b.valid
        assert np.array_equal(cpu.occupancy, gpu.occupancy)
        assert np.array_equal(cpu.logodds, gpu.logodds)
        assert np.array_equal(cpu.seen_at, gpu.seen_at)
        changed += a.cells.size
        forgotten += int((a.values == UNKNOWN).sum())
    assert changed > 500 and forgotten > 0
    # A jump is refused on the device as on the host, and the map stays as it was.
    cam = RgbdCamera()
    jump = dataclasses.replace(f, stamp=f.stamp + 0.1, pose=cam.pose(8.05, 1.25, -math.pi / 2))
    before = gpu.logodds.copy(), gpu.occupancy.copy()
    for m in (cpu, gpu):
        with pytest.raises(Exception, match="moved"):
            m.process(jump)
    assert np.array_equal(gpu.logodds, before[0]) and np.array_equal(gpu.occupancy, before[1])
    cpu.close()
    gpu.close()
