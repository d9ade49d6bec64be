"""The cuda backend's EDS plans small maps with the CPU repair and large ones on the device.

Either way the path is the reference Dijkstra's, tie for tie, so the rule changes only what a
step costs. The small-map half runs everywhere (no device is touched); the large-map half
and the warm-up of both parts need a GPU.
"""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning import cuda_available, make_planner
from daemon.planning.cuda.small_grids import SMALL_CELLS, SmallGridsOnCpu
from daemon.planning.dijkstra import dijkstra_field, reference_path

pytestmark = pytest.mark.timeout(120)


def walk_checked(planner, shape: tuple[int, int], seed: int = 3) -> None:
    """Plan, then random changes each with a path read, every path the reference's."""
    rng = np.random.default_rng(seed)
    blocked = rng.random(shape) < 0.2
    goal, start = (1, 1), (shape[0] - 2, shape[1] - 2)
    blocked[goal] = blocked[start] = False
    planner.plan(blocked, goal)
    for _ in range(6):
        cells = rng.choice(blocked.size, size=blocked.size // 20, replace=False)
        values = rng.random(cells.size) < 0.5
        values[cells == goal[0] * shape[1] + goal[1]] = False
        blocked.reshape(-1)[cells] = values
        _, path = planner.update_and_path(cells, values, start)
        if not blocked[start]:
            expected = reference_path(dijkstra_field(blocked, goal), blocked, start)
            np.testing.assert_array_equal(path, expected)
    np.testing.assert_array_equal(planner.costs(), dijkstra_field(blocked, goal))


def test_a_small_map_is_planned_by_the_cpu_repair_and_says_so():
    planner = SmallGridsOnCpu()
    assert planner.name == "eds-cuda-fast" and planner.shape == (0, 0)  # nothing planned yet
    with pytest.raises(RuntimeError):
        planner.path((0, 0))
    walk_checked(planner, (40, 50))
    assert planner.name == "eds-cpu-fast" and planner.shape == (40, 50)
    assert planner.pending() == 0  # costs() settled it: the CPU planner's own query answers
    assert getattr(planner, "search_stats", None) is None  # what it lacks, getattr says so


def test_the_rule_is_the_cuda_backends_eds_only():
    assert SMALL_CELLS == 100 * 100
    if cuda_available():
        assert isinstance(make_planner("eds", "cuda"), SmallGridsOnCpu)
        assert not isinstance(make_planner("dss", "cuda"), SmallGridsOnCpu)
        assert not isinstance(make_planner("eds", "cuda", "paper"), SmallGridsOnCpu)


@pytest.mark.gpu
@pytest.mark.skipif(not cuda_available(), reason="no usable CUDA device")
def test_a_map_above_the_limit_is_planned_on_the_device_and_both_parts_warm_up():
    from daemon.planning.cuda.planner import CudaPlanner
    from daemon.planning.warm import exercise

    planner = SmallGridsOnCpu(small_cells=30 * 30)
    exercise(planner)  # the warm-up's 48² map is above this limit: runs both parts anyway
    walk_checked(planner, (40, 50))
    assert isinstance(planner._serving, CudaPlanner) and planner.name == "eds-cuda-fast"
    walk_checked(planner, (20, 30), seed=4)  # a new, small map: the CPU again
    assert planner.name == "eds-cpu-fast"


def test_each_plan_sends_the_steps_to_the_planner_serving_that_map(monkeypatch):
    """A step goes straight to the serving planner's ``update_and_path`` (bound at ``plan``),
    so a new map of the other size must move the steps with it: small, large, small again."""
    from daemon.planning.cpu.fast import FastCpuPlanner

    steps: dict[str, int] = {"cpu": 0, "large": 0}

    class Counted(FastCpuPlanner):
        def __init__(self, name: str) -> None:
            super().__init__()
            self.counted = name

        def update_and_path(self, cells, blocked, start):
            steps[self.counted] += 1
            return super().update_and_path(cells, blocked, start)

    planner = SmallGridsOnCpu(small_cells=30 * 30)
    with pytest.raises(RuntimeError):  # before a plan, the class's own forwarding answers
        planner.update_and_path(np.array([0]), np.array([True]), (0, 0))
    small, large = Counted("cpu"), Counted("large")
    monkeypatch.setattr(planner, "cpu", lambda: small)
    monkeypatch.setattr(planner, "cuda", lambda: large)  # the device's part, played on the CPU
    walk_checked(planner, (20, 30))
    assert steps == {"cpu": 6, "large": 0}
    walk_checked(planner, (40, 50), seed=4)
    assert steps == {"cpu": 6, "large": 6}
    walk_checked(planner, (20, 30), seed=5)
    assert steps == {"cpu": 12, "large": 6}


def test_the_route_reads_no_search_of_either_part(cuda):
    """The route asks every step for ``max_open`` and ``search_stats`` (a searching planner's);
    neither part has them, so the wrapper answers None itself, before and after a plan."""
    from daemon.planning.cpu.fast import FastCpuPlanner

    for part in (FastCpuPlanner(), cuda.planner.CudaPlanner("fast")):
        assert not hasattr(part, "max_open") and not hasattr(part, "search_stats")
    planner = SmallGridsOnCpu()
    assert planner.max_open is None and planner.search_stats is None
    walk_checked(planner, (40, 50))
    assert getattr(planner, "max_open", 0) is None and getattr(planner, "search_stats", 0) is None
