"""The mapper's CuPy pass against the numba one: the same cells, rays and map.

Runs only where cupy imports and a CUDA device answers (``pytest -m gpu`` on the GPU
machine); skipped cleanly elsewhere.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mapper.backends import cuda_usable, make_binner
from mapper.binning import bin_frame_cpu
from mapper.frame import count_valid
from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from sim.camera import RgbdCamera
from sim.courtyard import make_courtyard
from sim.scene3d import scene_from_scenario

from ..scenes import bad_frames, box_scene, edge_frames, frame, mapper, outcome

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_usable(), reason="no usable CUDA device"),
]


def frames(n: int, out: np.ndarray | None = None):
    scenario = make_courtyard(100, 0.2, 0)
    scene = scene_from_scenario(scenario)
    cam = RgbdCamera()
    rng = np.random.default_rng(0)
    for i in range(n):
        pose = cam.pose(5.05, 0.65 + 0.1 * i, math.pi / 2 + 0.05 * i)
        yield cam.render(scene, pose, 10.0 + i, rng, out=out)


def test_same_cells_and_rays_as_the_cpu():
    cuda = make_binner("cuda")
    m = OccupancyMapper(MapperSettings(backend="cpu"))
    for f in frames(3):
        rot, t = f.pose.world_from_optical(), np.array(f.pose.position)
        win = m.window(t[0], t[1])
        args = (f.depth, 0.001, f.intrinsics, rot, t, 0.0, win, 0.1, 2.0, 3.0, 4, 1)
        a, b = bin_frame_cpu(*args), cuda(*args)
        assert a.valid == b.valid
        assert b.present == count_valid(f.depth)
        # Fused multiply-adds on the device may put a point sitting on a cell boundary
        # into the neighbour: a handful of the 300 000 points at most.
        assert np.abs(a.counts - b.counts).sum() <= 20
        assert np.allclose(a.hit[:, 0], b.hit[:, 0], rtol=1e-5)
        assert np.allclose(a.far[:, 0], b.far[:, 0], rtol=1e-5)
        has = np.isfinite(a.hit[:, 0])
        # Ties within float32 of the range may pick the neighbouring pixel: millimetres apart.
        assert np.allclose(a.hit[has, 1:], b.hit[has, 1:], atol=0.02)


def test_the_same_map_on_either_backend():
    maps = {}
    for backend in ("cpu", "cuda"):
        m = OccupancyMapper(MapperSettings(backend=backend))
        assert m.backend == backend
        for f in frames(6):
            m.process(f)
        maps[backend] = m.occupancy.copy()
    assert (maps["cpu"] != maps["cuda"]).sum() <= 2


def test_the_pass_counts_what_the_check_counts():
    """``Binned.present`` is ``frame.count_valid`` of the frame as given: uint16 with holes,
    float32 with every kind of missing pixel (on the device), and float64 or a strided pass
    (the device sees a cast or subsampled copy: counted on the host)."""
    cuda = make_binner("cuda")
    f = next(frames(1))
    rot, t = f.pose.world_from_optical(), np.array(f.pose.position)
    win = OccupancyMapper(MapperSettings(backend="cpu")).window(t[0], t[1])
    holed = f.depth.copy()
    holed.flat[::5] = 0
    metres = f.depth.astype(np.float32) / 1000.0
    metres.flat[::3], metres.flat[1::7], metres.flat[2::11] = np.nan, np.inf, -1.0
    metres.flat[4::13], metres.flat[5::17] = 1e-30, 1e-40  # tiny, subnormal: both positive
    wide = metres.astype(np.float64)
    wide.flat[6::19] = 1e-50  # positive as float64, 0 once cast to float32
    for depth, scale, stride in ((f.depth, 0.001, 1), (holed, 0.001, 1), (metres, 1.0, 1),
                                 (wide, 1.0, 1), (holed, 0.001, 2)):  # fmt: skip
        args = (depth, scale, f.intrinsics, rot, t, 0.0, win, 0.1, 2.0, 3.0, 4, stride)
        assert cuda(*args).present == count_valid(depth)


def test_a_frame_is_refused_on_cuda_as_on_the_cpu():
    """The same refusals, reasons and order with the pixels counted on the device, and a
    refused frame keeps nothing there either."""
    cpu, gpu = mapper(floor_async=True, floor_every=1), mapper(floor_async=True, floor_every=1)
    gpu.binner = make_binner("cuda")
    good = frame(box_scene(), 10.0)
    seq = [good, dataclasses.replace(good, stamp=10.05)]
    seq += [f for f, _ in bad_frames(dataclasses.replace(good, stamp=10.5))]
    seq += [dataclasses.replace(f, stamp=10.1 + 0.1 * i) for i, f in enumerate(edge_frames(good))]
    seq.append(dataclasses.replace(good, stamp=11.0))
    for f in seq:
        before = gpu.logodds.copy()
        said = [outcome(m, f) for m in (cpu, gpu)]
        assert said[0] == said[1]
        if said[1] != "mapped":
            assert np.array_equal(gpu.logodds, before)
        assert (cpu.last_stamp, cpu.frames, cpu._floor_age) == (gpu.last_stamp, gpu.frames,
                                                                 gpu._floor_age)  # fmt: skip
        # The fits are made on the host from the same samples: the same floor, to the bit.
        assert cpu._floor is not None and gpu._floor is not None
        assert cpu._floor[0].floor_z == gpu._floor[0].floor_z
        assert np.array_equal(cpu._floor[1], gpu._floor[1])
    assert cpu.refused == gpu.refused
    assert sum(gpu.refused.values()) == len(seq) - 5
    assert (cpu.occupancy != gpu.occupancy).sum() <= 2
    cpu.close()
    gpu.close()


def test_a_frame_in_the_lent_buffer_maps_as_a_copied_one():
    """Frames rendered into the buffer the mapper lends (``depth_buffer``: the pass's own
    page-locked upload, so the frame is not copied on its path) give the same changes,
    proximity and map as the same frames in their own arrays, copied by the pass."""
    copied = OccupancyMapper(MapperSettings(backend="cuda"))
    lent = OccupancyMapper(MapperSettings(backend="cuda"))
    buf = lent.depth_buffer(480, 640)
    assert buf is lent.depth_buffer(480, 640) and buf.dtype == np.uint16
    changed = 0
    for a, b in zip(frames(6), frames(6, out=buf), strict=True):
        assert b.depth is buf and np.array_equal(a.depth, b.depth)
        ra, rb = copied.process(a), lent.process(b)
        assert np.array_equal(ra.cells, rb.cells) and np.array_equal(ra.values, rb.values)
        assert (ra.proximity, ra.valid) == (rb.proximity, rb.valid)
        changed += ra.cells.size
    assert changed > 100
    assert np.array_equal(copied.occupancy, lent.occupancy)
    assert np.array_equal(copied.logodds, lent.logodds)
    for m in (copied, lent):
        m.close()
