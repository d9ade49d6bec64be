"""Where a replanning step's time goes on the GPU: host side and the fused launch's phases.

Replays the recorded courtyard walk (``scripts/time_cuda_planner.py``'s recording) through the
steps of ``CudaPlanner.update_and_path``, timed one by one on the host (the call: the delta
into the stage, the post to the resident loop or the graph's or the direct launch
(``--launch``), the wait for the done word and the result words; the path; the
statistics), with the kernel compiled with ``-DPROFILE`` so that
block 0 stamps the global timer at the end of each phase of the launch. Prints medians in µs,
per mode (EDS, DSS), and DSS-only plans on the whole inflated map.

``--gap work`` puts ~1 ms of numpy work on a map-sized array between steps (as sensing and
inflation do in the closed-loop walk), ``--gap sleep`` 1 ms of idling, to tell host caches
from an idle GPU.

    python3 scripts/profile_fast_phases.py --grid 400 --dss 400,2000
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cupy as cp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from time_cuda_planner import dss_case, record

from daemon.planning.cuda_planner import CudaPlanner

PHASES = ("init", "delta", "raise+reset", "relax", "exits", "hops", "segments")
VISIT = ("take", "load", "solve", "publish")  # fast.cu C_VISIT: P_TAKE .. P_PUBLISH
C_VISIT = 16
HOST = ("call", "path", "stats")  # call: stage, post or launch, wait, read the result words


def fused_step(p: CudaPlanner, cells, values, start, full: bool) -> list[float]:
    """update_and_path's body, with a clock between its parts (µs)."""
    t = [time.perf_counter()]
    p._call_fast(not full, cells, values, start[0] * p.shape[1] + start[1])
    t.append(time.perf_counter())
    p._path_locked(start, fused=True)
    t.append(time.perf_counter())
    p._read_fast_stats()
    t.append(time.perf_counter())
    return list(np.diff(t) * 1e6)


def planner(args: argparse.Namespace) -> CudaPlanner:
    return CudaPlanner(
        "fast", scans=args.scans, sched=args.sched, use_graph=args.launch != "direct",
        resident=args.launch == "resident", profile=True,
    )  # fmt: skip


def gap(kind: str, scratch: np.ndarray) -> None:
    """~1 ms between steps: CPU work over a map-sized array, or idling."""
    end = time.perf_counter() + 1e-3
    if kind == "sleep":
        time.sleep(1e-3)
    while kind == "work" and time.perf_counter() < end:
        np.add(scratch, 1.0, out=scratch)
        scratch.sort(axis=1)


def visit_split(p: CudaPlanner) -> np.ndarray:
    """µs of the last call's relaxation per block polling in vain, then per tile visit: the
    poll that took it, its load, settling it, publishing it (fast.cu C_VISIT, summed SM
    cycles / 16 at the device's nominal clock)."""
    cycles = p._io_host.array[C_VISIT : C_VISIT + 5].view(np.uint32).astype(np.float64) * 16
    us = cycles / (cp.cuda.Device().attributes["ClockRate"] * 1e3) * 1e6
    return np.concatenate([[us[0] / p._blocks], us[1:] / max(p.tiles, 1)])


def report(
    label: str, host: list[list[float]], dev: list[np.ndarray], extra: str, split: list | None
) -> None:
    h, d = np.median(np.array(host), axis=0), np.median(np.array(dev), axis=0) / 1e3
    total_dev = np.median([x.sum() for x in dev]) / 1e3
    total_host = np.median([sum(x) for x in host])
    print(f"\n{label}: host total {total_host:.1f} µs, device (block 0, stamp to stamp) "
          f"{total_dev:.1f} µs; {extra}")  # fmt: skip
    print("  host  " + "  ".join(f"{k} {v:.1f}" for k, v in zip(HOST, h, strict=True)))
    print("  device " + "  ".join(f"{k} {v:.1f}" for k, v in zip(PHASES, d, strict=True)))
    if split:  # DSS: every visit counted in p.tiles is a relaxation visit
        v = np.median(np.array(split), axis=0)
        print(f"  relaxation: idle polls per block {v[0]:.1f}, per visit "
              + "  ".join(f"{k} {x:.2f}" for k, x in zip(VISIT, v[1:], strict=True)))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=400)
    ap.add_argument("--dss", default="400,2000")
    ap.add_argument("--sched", type=int, default=1)
    ap.add_argument("--scans", type=int, default=2)
    ap.add_argument(
        "--launch", choices=("resident", "graph", "direct"), default="resident",
        help="how a call reaches the device: the resident loop, a CUDA graph, a direct launch",
    )  # fmt: skip
    ap.add_argument("--gap", choices=("none", "work", "sleep"), default="none")
    ap.add_argument("--walk-only", action="store_true")
    args = ap.parse_args()
    rec, _ = record(args.grid, 0.4, None)
    blocked, goal = rec.initial
    for mode in ("eds", "dss"):
        p = planner(args)
        p.plan(blocked, goal)
        host, dev, visits, sweeps, split = [], [], [], [], []
        scratch = np.random.default_rng(0).random((args.grid, args.grid))
        for cells, values, start in rec.steps:
            if start is None:
                continue
            gap(args.gap, scratch)
            host.append(fused_step(p, cells, values, start, full=mode == "dss"))
            dev.append(p.phase_ns())
            visits.append(p.tiles)
            split.append(visit_split(p))
            sweeps.append(p.sweeps / max(p.tiles, 1))
        extra = (f"tiles run {np.median(visits):.0f}, Jacobi passes per tile "
                 f"{np.mean(sweeps):.2f}")  # fmt: skip
        label = f"{args.grid}² walk, {mode}, gap {args.gap}, {len(host)} steps"
        report(label, host, dev, extra, split if mode == "dss" else None)
    for size in [] if args.walk_only else [int(s) for s in args.dss.split(",") if s]:
        sc, blocked_full, _ = dss_case(size)
        p = planner(args)
        p.plan(blocked_full, sc.goal)
        none = np.empty(0, np.int64), np.empty(0, bool)
        host, dev, split = [], [], []
        for _ in range(10):
            host.append(fused_step(p, *none, sc.start, full=True))
            dev.append(p.phase_ns())
            split.append(visit_split(p))
        extra = (f"tiles run {p.tiles}, Jacobi passes per tile {p.sweeps / max(p.tiles, 1):.2f}, "
                 f"exits recomputed {p.exit_tiles}")  # fmt: skip
        report(f"{size}² DSS only", host, dev, extra, split)


if __name__ == "__main__":
    main()
