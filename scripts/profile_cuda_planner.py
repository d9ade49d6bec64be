"""Where a cuda replanning step's time goes: device time (CUDA events) against wall time.

On the courtyard's full inflated map at each size: the path walk kernel for several window
sizes (device time, cells walked), ``path`` on the wall clock, and ``update`` with an empty
delta and with a small obstacle on the path (wall clock, device time, rounds).

    python3 scripts/profile_cuda_planner.py --sizes 400,2000
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

import cupy as cp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from daemon.planning import cuda_kernels as ck
from daemon.planning.cuda_planner import CudaPlanner
from daemon.planning.grid import OCCUPIED
from sim.courtyard import dilate, make_courtyard


def device_ms(fn, repeats: int = 20) -> tuple[float, float]:
    """Median device time (events) and wall time of ``fn`` in ms."""
    dev, wall = [], []
    for _ in range(repeats):
        e0, e1 = cp.cuda.Event(), cp.cuda.Event()
        t0 = time.perf_counter()
        e0.record()
        fn()
        e1.record()
        e1.synchronize()
        wall.append((time.perf_counter() - t0) * 1e3)
        dev.append(cp.cuda.get_elapsed_time(e0, e1))
    return float(np.median(dev)), float(np.median(wall))


def profile(size: int, max_blocks: int | None) -> None:
    sc = make_courtyard(size, 0.4, seed=0)
    blocked = dilate(sc.true == OCCUPIED, sc.radius_cells)
    p = CudaPlanner("fast", max_blocks=max_blocks)
    p.plan(blocked, sc.goal)
    print(f"{size}: {p._blocks} blocks")
    h, w = p.shape
    start = sc.start[0] * w + sc.start[1]
    for win in (64,) if max_blocks is None else ():
        k = ck.kernel("path", "walk_path", (f"WIN={win}",))
        buf = cp.zeros(2 + p._path_cap, dtype=np.int32)
        args = (p._g, np.int32(h), np.int32(w), np.int32(start), buf, np.int32(p._path_cap))
        d, wl = device_ms(partial(k, (1,), (ck.THREADS,), args))
        n = int(buf[0].get())
        print(f"{size}: walk WIN={win:3}: {d * 1e3:8.1f} us device, {wl * 1e3:8.1f} us wall, "
              f"{n} cells, {d * 1e6 / max(n, 1):6.1f} ns/cell", flush=True)  # fmt: skip
    want = p.path(sc.start)
    for mode in ("walk", "tiles"):
        p.path_mode = mode
        assert np.array_equal(p.path(sc.start), want)
        d, wl = device_ms(lambda: p.path(sc.start))
        print(f"{size}: path() by {mode}: {d * 1e3:8.1f} us device span, {wl * 1e3:8.1f} us wall")
    empty = np.empty(0, np.int64)
    d, wl = device_ms(lambda: p.update(empty, np.empty(0, bool)))
    print(f"{size}: update(no change): {d * 1e3:8.1f} us device span, {wl * 1e3:8.1f} us wall, "
          f"rounds {p.last_stats.iterations}")  # fmt: skip
    path = p.path(sc.start)
    r, c = (int(v) for v in path[len(path) // 3])
    box = np.array([(r + dr) * w + c + dc for dr in (-1, 0, 1) for dc in (-1, 0, 1)])
    times = []
    for i in range(20):
        d, wl = device_ms(partial(p.update, box, np.full(box.size, i % 2 == 0)), 1)
        times.append((d, wl, p.last_stats.iterations, p.tiles, p.sweeps))
    t = np.array(times)
    print(f"{size}: update(3x3 box on the path, on/off): {np.median(t[:, 0]) * 1e3:8.1f} us "
          f"device span, {np.median(t[:, 1]) * 1e3:8.1f} us wall, rounds "
          f"{np.median(t[:, 2]):.0f}, tiles {np.median(t[:, 3]):.0f}, "
          f"sweeps/tile {np.median(t[:, 4] / np.maximum(t[:, 3], 1)):.1f}")  # fmt: skip
    d, wl = device_ms(lambda: p.plan(blocked, sc.goal), 5)
    print(f"{size}: plan(): {d * 1e3:8.1f} us device span, {wl * 1e3:8.1f} us wall, rounds "
          f"{p.last_stats.iterations}, tiles {p.tiles}, "
          f"sweeps/tile {p.sweeps / max(p.tiles, 1):.1f}", flush=True)  # fmt: skip



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="400,2000")
    ap.add_argument("--max-blocks", default="0", help="persistent grid caps to try (0: none)")
    args = ap.parse_args()
    for size in (int(s) for s in args.sizes.split(",")):
        for cap in (int(c) for c in args.max_blocks.split(",")):
            profile(size, cap or None)


if __name__ == "__main__":
    main()
