"""The cuda backend's host path in the closed-loop walk, on a machine without a GPU.

What a walking step costs the host around the device (BENCHMARKS.md, "Planning on the GPU",
Notes): ``FallbackPlanner(CudaPlanner).update_and_path`` runs as it is, the Python of both
classes and of the resident loop's post and wait, on numpy arrays standing in for the mapped
buffers; cupy is replaced by a mock and the device by a function that, at the post, writes
the CPU planner's path and the done word, as fast.cu would. The walk is the real one
(``drivers.sim.walk``: sensing and inflation between steps, which is what leaves the host's
caches cold). Prints, per walk, the median µs from the call to the post ("before") and from
the device's answer to the return ("after": the wait's last look, the path and statistics,
the mirror; and here the fallback's copies, which on a GPU run while the device works).

Its figures are this machine's; the point is comparing host code, one version against
another, without spending device time. Runs in its own process (the mock must be in place
before ``daemon.planning.cuda_planner`` is imported):

    python3 scripts/emulate_host_path.py --grid 400 --mode dss --walks 9
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
if "daemon.planning.cuda_planner" in sys.modules:
    raise RuntimeError("run this script in a process of its own: cupy must be mocked first")
_fake_cupy = mock.MagicMock()
_fake_cupy.cuda.runtime.streamQuery = lambda ptr: 600  # the loop runs: never asked to restart
sys.modules["cupy"] = _fake_cupy

from daemon.planning import cuda_kernels as ck  # noqa: E402
from daemon.planning import cuda_resident  # noqa: E402
from daemon.planning.backends import make_planner  # noqa: E402
from daemon.planning.cuda_planner import CudaPlanner  # noqa: E402
from daemon.planning.fallback import FallbackPlanner  # noqa: E402
from daemon.planning.interface import UpdateStats  # noqa: E402
from drivers.sim.courtyard import make_courtyard  # noqa: E402
from drivers.sim.walk import walk  # noqa: E402


class HostBuffer:
    """Stands in for ``cuda_kernels.Pinned``: a numpy array, large enough never to move."""

    def __init__(self, count: int) -> None:
        self.array = np.zeros(count, dtype=np.int32)
        self.count = count
        self.memory = None
        self.device_ptr = 0

    def reserve(self, count: int) -> bool:
        if count > self.count:
            raise ValueError(f"emulated buffer of {self.count} words, {count} asked for")
        return False


class AnsweringLoop(cuda_resident.ResidentLoop):
    """The resident loop's host side as it is; the device answers at the post."""

    def __init__(self, io: np.ndarray, stage: np.ndarray, clock: dict[str, float]) -> None:
        super().__init__(lambda stream: None, stage, ())
        self._running, self._served_at = True, time.perf_counter()
        self.io, self.clock = io, clock
        self.path = np.empty((0, 2), dtype=np.int32)

    def post(self, seq: int, n_delta: int) -> None:
        super().post(seq, n_delta)
        self.clock["posted"] = time.perf_counter()
        at, n = ck.IO_PATH, len(self.path)
        self.io[at], self.io[at + 1] = n, 0
        self.io[at + 2 : at + 2 + 2 * n] = self.path.ravel()
        self.io[ck.IO_REJECT] = 0
        self.io[ck.IO_DONE] = seq
        self.clock["answered"] = time.perf_counter()


def emulated_cuda_planner(
    shape: tuple[int, int], goal: tuple[int, int], clock: dict[str, float]
) -> CudaPlanner:
    """A ``CudaPlanner`` in the state ``plan`` leaves it in with a resident loop running."""
    planner = CudaPlanner.__new__(CudaPlanner)
    planner.__dict__.update(
        path_mode="tiles", use_graph=True, resident=True, max_blocks=None, variant="fast",
        name="cuda-fast", _shape=shape, _goal=goal, _fault=None, while_waiting=None,
        last_stats=None, _defines=(), _seq=0, _stage_views=(np.empty(0),),
        _io_host=HostBuffer(ck.IO_PATH + 2 + 2 * 16384),
        _stage=HostBuffer(ck.PARAMS + 4 * 65536),
        _params=np.zeros(ck.PARAMS + 65536, dtype=np.int32),
        sweeps=0, raised_cells=0, tiles=0, exit_tiles=0,
    )  # fmt: skip
    loop = AnsweringLoop(planner._io_host.array, planner._stage.array, clock)
    cuda_resident._ACTIVE = planner._loop = loop
    return planner


class TimedStep:
    """The walk's planner: the CPU planner finds the path (not timed), then the emulated cuda
    planner, behind the fallback wrapper as ``make_planner("cuda")`` gives it, is timed."""

    def __init__(self) -> None:
        self.cpu = make_planner("cpu", "fast")
        self.clock: dict[str, float] = {}
        self.before: list[float] = []
        self.after: list[float] = []

    def plan(self, blocked: np.ndarray, goal: tuple[int, int]) -> UpdateStats:
        self.cuda = emulated_cuda_planner(blocked.shape, goal, self.clock)
        self.cuda.plan = lambda blocked, goal: UpdateStats(0, 0, 0.0)  # already in that state
        self.wrapped = FallbackPlanner(self.cuda, errors=())
        self.wrapped.plan(blocked, goal)  # its mirror of the map
        return self.cpu.plan(blocked, goal)

    def update_and_path(self, cells, blocked, start, *, full=False):
        stats, path = self.cpu.update_and_path(cells, blocked, start, full=full)
        self.cuda._loop.path = path
        t0 = time.perf_counter()
        _, emulated_path = self.wrapped.update_and_path(cells, blocked, start, full=full)
        t1 = time.perf_counter()
        if not np.array_equal(emulated_path, path):
            raise AssertionError("the emulated host path returned another path")
        self.before.append((self.clock["posted"] - t0) * 1e6)
        self.after.append((t1 - self.clock["answered"]) * 1e6)
        return stats, path

    def cost_at(self, cell):
        return self.cpu.cost_at(cell)

    def path(self, start):
        return self.cpu.path(start)

    shape = property(lambda self: self.cpu.shape)
    goal = property(lambda self: self.cpu.goal)


def main(argv: list[str] | None = None) -> float:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=400)
    ap.add_argument("--unknown", type=float, default=0.4)
    ap.add_argument("--mode", choices=("eds", "dss"), default="dss")
    ap.add_argument("--walks", type=int, default=5)
    ap.add_argument("--max-steps", type=int, default=None)
    args = ap.parse_args(argv)
    scenario = make_courtyard(args.grid, args.unknown, seed=0)
    totals = []
    for i in range(args.walks):
        step = TimedStep()
        result = walk(scenario, mode=args.mode, planner=step, max_steps=args.max_steps)
        before, after = np.median(step.before[5:]), np.median(step.after[5:])
        totals.append(before + after)
        print(f"walk {i + 1}: {result.steps} steps, host before the post {before:.1f} µs, "
              f"after the answer {after:.1f} µs")  # fmt: skip
    total = float(np.median(totals))
    print(f"median over walks: {total:.1f} µs of host time per step")
    return total


if __name__ == "__main__":
    main()
