"""The mapper's CuPy pass against the numba one: the same cells, rays and map.

Runs only where cupy imports and a CUDA device answers (``pytest -m gpu`` on the GPU
machine); skipped cleanly elsewhere.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapper.backends import cuda_usable, make_binner
from mapper.binning import bin_frame_cpu
from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from sim.camera import RgbdCamera
from sim.courtyard import make_courtyard
from sim.scene3d import scene_from_scenario

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_usable(), reason="no usable CUDA device"),
]


def frames(n: int):
    scenario = make_courtyard(100, 0.2, 0)
    scene = scene_from_scenario(scenario)
    cam = RgbdCamera()
    rng = np.random.default_rng(0)
    for i in range(n):
        pose = cam.pose(5.05, 0.65 + 0.1 * i, math.pi / 2 + 0.05 * i)
        yield cam.render(scene, pose, 10.0 + i, rng)


def test_same_cells_and_rays_as_the_cpu():
    cuda = make_binner("cuda")
    m = OccupancyMapper(MapperSettings(backend="cpu"))
    for f in frames(3):
        rot, t = f.pose.world_from_optical(), np.array(f.pose.position)
        win = m.window(t[0], t[1])
        args = (f.depth, 0.001, f.intrinsics, rot, t, 0.0, win, 0.1, 2.0, 3.0, 4, 1)
        a, b = bin_frame_cpu(*args), cuda(*args)
        assert a.valid == b.valid
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
