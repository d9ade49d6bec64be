"""The cuda backend's host path in the closed-loop walk, on a machine without a GPU.

What a walking step costs the host around the device (BENCHMARKS.md, "Planning on the GPU",
Notes): ``FallbackPlanner(CudaPlanner).update_and_path`` runs as it is, the Python of both
classes and of the resident loop's post and wait, with cupy and the mapped buffers replaced
by ``daemon.planning.cuda_standin`` and the device by a loop that, at the post, writes the
CPU planner's path and the done word, as fast.cu would. The walk is the real one
(``sim.walk``: sensing and inflation between steps, which is what leaves the host's
caches cold). Prints, per walk, the median µs from the call to the post ("before") and from
the device's answer to the return ("after": the wait's last look, the result words and the
path, the statistics, the mirror; and here the fallback's copies, which on a GPU run while
the device works).

Its figures are this machine's; the point is comparing host code, one version against
another, without spending device time. ``--against TREE`` does that: the planning package
of another checkout (``git worktree add /tmp/old HEAD~1``, say) is loaded beside this one's,
the walk's steps alternate between the two, and the difference is printed per walk. Steps
that alternate see the same machine, so the difference is steady to ~1 µs where separate
runs of this script differ by 5-10 on a shared VM. Runs in its own process (the stand-in
must be in place before ``daemon.planning.cuda_planner`` is imported):

    python3 scripts/emulate_host_path.py --grid 400 --mode dss --walks 9
    python3 scripts/emulate_host_path.py --walks 5 --against /tmp/old
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys
import time
from pathlib import Path
from types import ModuleType

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
if "daemon.planning.cuda_planner" in sys.modules:
    raise RuntimeError("run this script in a process of its own: cupy must be replaced first")

from daemon.planning import cuda_standin  # noqa: E402

sys.modules["cupy"] = cuda_standin.standin_cupy()

from daemon.planning.backends import make_planner  # noqa: E402
from sim.courtyard import make_courtyard  # noqa: E402
from sim.walk import walk  # noqa: E402


def planning_package(tree: Path | None) -> ModuleType:
    """This checkout's ``daemon.planning``, or ``tree``'s loaded beside it as ``against``."""
    if tree is None:
        return importlib.import_module("daemon.planning")
    init = tree.resolve() / "daemon" / "planning" / "__init__.py"
    spec = importlib.util.spec_from_file_location("against", init)
    if spec is None or spec.loader is None:
        raise FileNotFoundError(init)
    spec.submodule_search_locations = [str(init.parent)]
    package = importlib.util.module_from_spec(spec)
    sys.modules["against"] = package
    spec.loader.exec_module(package)
    return package


class EmulatedBackend:
    """A package's ``FallbackPlanner(CudaPlanner)``, built and planned as ``make_planner``
    would, whose resident loop answers each post at once with ``path``."""

    def __init__(self, package: ModuleType) -> None:
        name = package.__name__
        ck = importlib.import_module(f"{name}.cuda_kernels")
        ck.Pinned = cuda_standin.HostPinned
        self.ck, self.resident = ck, importlib.import_module(f"{name}.cuda_resident")
        self.CudaPlanner = importlib.import_module(f"{name}.cuda_planner").CudaPlanner
        self.FallbackPlanner = importlib.import_module(f"{name}.fallback").FallbackPlanner
        self.clock: dict[str, float] = {}
        self.path = np.empty((0, 2), dtype=np.int32)
        self.before: list[float] = []
        self.after: list[float] = []

    def plan(self, blocked: np.ndarray, goal: tuple[int, int]) -> None:
        self.cuda = self.CudaPlanner("fast")
        self.cuda._new_loop = self._new_loop  # its loops are answering ones
        self.wrapped = self.FallbackPlanner(self.cuda, errors=())
        self.wrapped.plan(blocked, goal)

    def _new_loop(self):
        backend, ck, planner = self, self.ck, self.cuda

        class AnsweringLoop(self.resident.ResidentLoop):
            """The resident loop's host side as it is; the device answers at the post."""

            def post(self, seq: int, n_delta: int) -> None:
                super().post(seq, n_delta)
                backend.clock["posted"] = time.perf_counter()
                io, at, n = planner._io_host.array, ck.IO_PATH, len(backend.path)
                io[at], io[at + 1] = n, 0
                io[at + 2 : at + 2 + 2 * n] = backend.path.ravel()
                io[ck.IO_REJECT] = 0
                io[ck.IO_DONE] = seq
                backend.clock["answered"] = time.perf_counter()

        return AnsweringLoop(lambda stream: None, planner._stage.array, ())

    def step(self, cells, blocked, start, full: bool, path: np.ndarray) -> None:
        """One timed step, whose device answers with ``path``."""
        self.resident._ACTIVE = self.cuda._loop  # the other package's loop is not evicted
        self.path = path
        t0 = time.perf_counter()
        _, emulated_path = self.wrapped.update_and_path(cells, blocked, start, full=full)
        t1 = time.perf_counter()
        if not np.array_equal(emulated_path, path):
            raise AssertionError("the emulated host path returned another path")
        self.before.append((self.clock["posted"] - t0) * 1e6)
        self.after.append((t1 - self.clock["answered"]) * 1e6)


class TimedWalk:
    """The walk's planner: the CPU planner finds the path (not timed), then an emulated
    backend takes the step, timed; with two backends they take the steps in turn."""

    def __init__(self, backends: list[EmulatedBackend]) -> None:
        self.cpu = make_planner("cpu", "fast")
        self.backends = backends
        self.steps = 0

    def plan(self, blocked, goal):
        for backend in self.backends:
            backend.plan(blocked, goal)
        return self.cpu.plan(blocked, goal)

    def update_and_path(self, cells, blocked, start, *, full=False):
        stats, path = self.cpu.update_and_path(cells, blocked, start, full=full)
        self.backends[self.steps % len(self.backends)].step(cells, blocked, start, full, path)
        self.steps += 1
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
    ap.add_argument("--against", type=Path, default=None,
                    help="another checkout whose host path takes every other step")  # fmt: skip
    args = ap.parse_args(argv)
    scenario = make_courtyard(args.grid, args.unknown, seed=0)
    packages = [planning_package(None)]
    if args.against is not None:
        packages.append(planning_package(args.against))
    totals: list[list[float]] = [[] for _ in packages]
    for i in range(args.walks):
        backends = [EmulatedBackend(p) for p in packages]
        timed = TimedWalk(backends)
        result = walk(scenario, mode=args.mode, planner=timed, max_steps=args.max_steps)
        for b, backend in enumerate(backends):
            before, after = np.median(backend.before[5:]), np.median(backend.after[5:])
            totals[b].append(before + after)
            label = "" if len(backends) == 1 else (" this tree:", " against:")[b]
            print(f"walk {i + 1}:{label} {result.steps} steps, host before the post {before:.1f} "
                  f"µs, after the answer {after:.1f} µs")  # fmt: skip
    total = float(np.median(totals[0]))
    print(f"median over walks: {total:.1f} µs of host time per step")
    if args.against is not None:
        diff = np.array(totals[0]) - np.array(totals[1])
        print(f"this tree minus {args.against}: {np.median(diff):+.1f} µs per step (median over "
              f"walks; each walk {' '.join(f'{d:+.1f}' for d in diff)})")  # fmt: skip
    return total


if __name__ == "__main__":
    main()
