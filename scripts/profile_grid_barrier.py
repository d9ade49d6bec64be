"""What one grid-wide barrier costs on this GPU: fast.cu's barrier against cooperative groups.

Times a launch of K barriers and of 1 barrier (CUDA events, median of 20) for several block
counts and spin back-offs, and prints the cost per barrier. The persistent planner kernel
pays one barrier per round, so this is the floor of its per-round time.

    python3 scripts/profile_grid_barrier.py
"""

from __future__ import annotations

import cupy as cp
import numpy as np

SOURCE = r"""
#include <cooperative_groups.h>
#define C_BAR 0
#define C_RELEASE 32
extern "C" __global__ void bar_mine(unsigned* ctrl, int k, unsigned base, int sleep_ns) {
    unsigned target = base;
    for (int i = 0; i < k; ++i) {
        __syncthreads();
        if (threadIdx.x == 0) {
            target += gridDim.x;
            __threadfence();
            unsigned arrived = atomicAdd(ctrl + C_BAR, 1u) + 1u;
            volatile unsigned* release = ctrl + C_RELEASE;
            if (arrived == target) {
                *release = arrived;
            } else {
                while ((int)(*release - target) < 0) { if (sleep_ns) __nanosleep(sleep_ns); }
            }
            __threadfence();
        }
        __syncthreads();
    }
}
extern "C" __global__ void bar_cg(int k) {
    cooperative_groups::grid_group grid = cooperative_groups::this_grid();
    for (int i = 0; i < k; ++i) grid.sync();
}
"""


def timed(fn, repeats: int = 20) -> float:
    out = []
    for _ in range(repeats):
        e0, e1 = cp.cuda.Event(), cp.cuda.Event()
        e0.record()
        fn()
        e1.record()
        e1.synchronize()
        out.append(cp.cuda.get_elapsed_time(e0, e1))
    return float(np.median(out)) * 1e3  # us


def main() -> None:
    mine = cp.RawModule(code=SOURCE, options=("--std=c++17",)).get_function("bar_mine")
    ctrl = cp.zeros(64, dtype=np.uint32)
    arrivals = [0]  # the barrier counter's value, known without reading it back
    sms = cp.cuda.Device().attributes["MultiProcessorCount"]
    for blocks in (8, 32, 66, sms):
        for sleep in (0, 32, 200):
            def run(k, blocks=blocks, sleep=sleep):
                base = np.uint32(arrivals[0] % 2**32)
                mine((blocks,), (1024,), (ctrl, np.int32(k), base, np.int32(sleep)))
                arrivals[0] += blocks * k

            t1, t101 = timed(lambda run=run: run(1)), timed(lambda run=run: run(101))
            print(f"own barrier: {blocks:4} blocks, nanosleep {sleep:3}: "
                  f"{(t101 - t1) / 100:6.2f} us per barrier, launch+1 {t1:6.1f} us")  # fmt: skip
    try:
        mod = cp.RawModule(code=SOURCE, options=("--std=c++17",), enable_cooperative_groups=True)
        cg = mod.get_function("bar_cg")
        for blocks in (8, 32, 66, sms):
            t1 = timed(lambda b=blocks: cg((b,), (1024,), (np.int32(1),)))
            t101 = timed(lambda b=blocks: cg((b,), (1024,), (np.int32(101),)))
            print(f"cooperative groups: {blocks:4} blocks: "
                  f"{(t101 - t1) / 100:6.2f} us per barrier, "
                  f"launch+1 {t1:6.1f} us")  # fmt: skip
    except Exception as exc:  # report and go on: this is a measurement, not a dependency
        print(f"cooperative groups unavailable: {type(exc).__name__}: {exc}")


if __name__ == "__main__":
    main()
