"""The paper's rubber band on the GPU (Figure 4: a thread per point) against the numba one,
and the harmonic planner's ``band`` (its smoothing model) reading the device field."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.guidance.smoothing import path_length, turning_angles
from daemon.planning import cuda_available, make_planner
from daemon.planning.harmonic.planner import BAND_ITERATIONS
from daemon.planning.harmonic.rubber_band import rubber_band

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]

LENGTH_TOL = 0.01
"""GPU and CPU bands of one path in one field agree in length within 1 %: the same moves
but for the rounding of ``exp`` and ``hypot``, where a tie between two moves may fall the
other way."""


@pytest.mark.parametrize("seed", range(4))
def test_gpu_band_matches_the_cpu_band(maps, seed):
    from daemon.planning.harmonic.band_cuda import rubber_band_cuda

    rng = np.random.default_rng(seed)
    goal, start = (3, 3), (76, 74)
    blocked = maps.walled_map(rng, 80, 0.05, goal, start)
    planner = make_planner("harmonic", "cpu")
    planner.plan(blocked, goal)
    path = planner.path(start)
    if len(path) < 3:
        pytest.skip("no path on this map")
    cpu = rubber_band(path, planner.field(), blocked)
    gpu, iterations = rubber_band_cuda(path, planner.field(), blocked)
    assert iterations > 0 and gpu.shape == cpu.shape
    assert np.allclose(gpu[[0, -1]], path[[0, -1]] + 0.5)
    assert maps.segments_free(blocked, gpu)
    assert abs(path_length(gpu) - path_length(cpu)) <= LENGTH_TOL * path_length(cpu)
    assert (turning_angles(gpu) > 30).sum() <= (turning_angles(path) > 30).sum()


def test_cuda_planner_bands_from_its_device_field(maps):
    rng = np.random.default_rng(7)
    goal, start = (4, 5), (115, 112)
    blocked = maps.walled_map(rng, 120, 0.04, goal, start)
    gpu = make_planner("harmonic", "cuda")
    gpu.plan(blocked, goal)
    path = gpu.path(start)
    band = gpu.band(path, blocked)
    # The same band as from the host copy of the field, in float64.
    host = rubber_band(path, gpu.field(), blocked, iterations=BAND_ITERATIONS)
    assert maps.segments_free(blocked, band)
    assert abs(path_length(band) - path_length(host)) <= LENGTH_TOL * path_length(host)
    assert path_length(band) < path_length(path + 0.5)
