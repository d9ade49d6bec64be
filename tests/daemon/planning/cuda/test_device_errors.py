"""A failing device call on a real cuda planner: what the navigator's CPU fallback relies on.

The planner raises an exception the caller recognises (``device_errors()``), and stays
unusable; the caller, which owns the map, builds a CPU planner from it and gets the same field
and path the device gave before the fault. Errors that are not the device's (a cell outside
the map) are not device errors, and the planner goes on.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available, device_errors, make_planner
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device"),
    pytest.mark.timeout(120),
]


@pytest.mark.parametrize("name", ["eds", "dss"])
@pytest.mark.parametrize("variant", ["fast", "paper"])
def test_a_cupy_error_is_a_device_error_and_the_cpu_takes_over_from_the_map(name, variant):
    import cupy

    rng = np.random.default_rng(1)
    blocked = rng.random((30, 40)) < 0.25
    goal, start = (2, 3), (27, 35)
    blocked[goal] = blocked[start] = False
    from daemon.planning.cuda.planner import CudaPlanner

    planner = CudaPlanner(variant, dss=name == "dss")  # the device planner, on any grid
    planner.plan(blocked, goal)
    for step in range(4):
        cells = rng.choice(30 * 40, size=25, replace=False)
        values = rng.random(25) < 0.5
        if step == 2:  # an illegal address, as a faulting kernel would report it
            planner.inject_fault(cupy.cuda.runtime.CUDARuntimeError(700))
            with pytest.raises(device_errors()):
                planner.update_and_path(cells, values, start)
            # unusable: a sticky fault fails every later call
            with pytest.raises(device_errors()):
                planner.update(cells, values)
            with pytest.raises(device_errors()):
                planner.path(start)
            break
        blocked.reshape(-1)[cells] = values  # the caller's map: only changes the device took
        _, path = planner.update_and_path(cells, values, start)
    cpu = make_planner(name, "cpu", variant)
    cpu.plan(blocked, goal)
    g = dijkstra_field(blocked, goal)
    assert np.array_equal(cpu.costs(), g)
    assert np.array_equal(cpu.path(start), path)
    assert np.array_equal(path, reference_path(g, blocked, start))
    # the step that failed, replayed on the CPU
    blocked.reshape(-1)[cells] = values
    _, path = cpu.update_and_path(cells, values, start)
    g = dijkstra_field(blocked, goal)
    assert np.array_equal(cpu.costs(), g)
    assert np.array_equal(path, reference_path(g, blocked, start))


def test_other_errors_are_not_device_errors_and_the_planner_goes_on():
    from daemon.planning.cuda.planner import CudaPlanner

    planner = CudaPlanner("fast")
    blocked = np.zeros((8, 8), bool)
    planner.plan(blocked, (0, 0))
    with pytest.raises(IndexError) as caught:
        planner.update(np.array([99]), np.array([True]))
    assert not isinstance(caught.value, device_errors())
    planner.update(np.array([9]), np.array([True]))
    blocked.reshape(-1)[9] = True
    assert np.array_equal(planner.costs(), dijkstra_field(blocked, (0, 0)))
