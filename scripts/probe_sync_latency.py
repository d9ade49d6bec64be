"""What the fast planner's synchronisation costs on this GPU: fences, atomics, barriers, PCIe.

One thread (or one 1024-thread block for the barriers) times each operation with ``clock64``
around it, the operation's result consumed before the second read of the clock, and prints
the median over repeats in SM cycles and ns. These are the costs that fast.cu's hand-off
between tiles and resident.cuh's mailbox are built from (BENCHMARKS.md, "Planning on the GPU").
On sm_90 and up also what thread block clusters would cost: the cluster-wide barrier and
reads of another block's shared memory (distributed shared memory, DSMEM), the parts of a
hand-off between tiles that skips L2 (BENCHMARKS.md, Notes: "The fifth session of
2026-11-23").

    python3 scripts/probe_sync_latency.py
"""

from __future__ import annotations

import cupy as cp
import numpy as np

SOURCE = r"""
#define REPS 200
__device__ __forceinline__ unsigned exch_acquire(unsigned* p) {
    unsigned v;
    asm volatile("atom.acquire.gpu.global.exch.b32 %0, [%1], 0;" : "=r"(v) : "l"(p) : "memory");
    return v;
}
// out[r * 16 + i]: cycles of probe i in repeat r. dev: device memory, host: mapped host memory.
// Each latency is a chain of CHAIN operations, each addressed by the last one's result (so
// each waits for the one before), divided by CHAIN. Fences block the thread: timed singly.
#define CHAIN 8
extern "C" __global__ void probe(unsigned* dev, int* host, long long* out) {
    const int k = threadIdx.x;
    unsigned v = 0;
    for (int r = 0; r < REPS; ++r) {
        long long t[16] = {0}, a;
        unsigned* line = dev + (r % 64) * 32;  // a fresh line each repeat
        __syncthreads();
        if (k == 0) {
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = atomicExch(line + (v & 1u), 0u);
            t[0] = (clock64() - a) / CHAIN;
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = exch_acquire(line + 2 + (v & 1u));
            t[1] = (clock64() - a) / CHAIN;
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = atomicAdd(line + 4 + (v & 1u), 0u);
            t[2] = (clock64() - a) / CHAIN;
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = __ldcg(line + 6 + (v & 1u));
            t[3] = (clock64() - a) / CHAIN;
            a = clock64(); __threadfence(); t[4] = clock64() - a;
            __stcg((int*)line + 8, r);
            a = clock64(); __threadfence(); t[5] = clock64() - a;
            a = clock64(); __threadfence_system(); t[6] = clock64() - a;
            host[r % 64] = r;
            a = clock64(); __threadfence_system(); t[7] = clock64() - a;
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = (unsigned)__ldcv(host + 64 + (v & 1u));
            t[8] = (clock64() - a) / CHAIN;
        }
        __syncthreads();
        a = clock64();
        __syncthreads();
        t[9] = clock64() - a;
        a = clock64();
        int any = __syncthreads_or(k == 5);
        t[10] = clock64() - a;
        // PCIe reads issued together: does the SM overlap them? (resident.cuh's take_delta)
        if (k == 0) {
            a = clock64();
            int x0 = __ldcv(host + 64), x1 = __ldcv(host + 80), x2 = __ldcv(host + 96),
                x3 = __ldcv(host + 112);
            v += (unsigned)(x0 + x1 + x2 + x3);
            t[11] = clock64() - a;
        }
        __syncthreads();
        a = clock64();
        any = __syncthreads_or(k < 96 && __ldcv(host + 64 + (k & 63)) == 12345);
        t[12] = clock64() - a;
        a = clock64();
        any += __syncthreads_or(k < 72 && (__ldcv((const long long*)(host + 128) + k) +
                                           __ldcv((const long long*)(host + 128) + k + 1) +
                                           __ldcv((const signed char*)(host + 320) + k)) == 12345);
        t[13] = clock64() - a;
        if (k == 0)
            for (int i = 0; i < 14; ++i) out[r * 16 + i] = t[i];
        if (k == 0 && any == 12345) out[0] = v;  // keeps the chains
    }
}
"""

CLUSTER_SOURCE = r"""
#define REPS 200
__device__ __forceinline__ unsigned cluster_rank() {
    unsigned r;
    asm volatile("mov.u32 %0, %%cluster_ctarank;" : "=r"(r));
    return r;
}
// Every thread of the cluster's blocks; releases this thread's writes to those that waited.
__device__ __forceinline__ void cluster_sync() {
    asm volatile("barrier.cluster.arrive.release.aligned;\n\t"
                 "barrier.cluster.wait.acquire.aligned;" ::: "memory");
}
// The address of `p` (this block's shared memory) in block `rank`'s shared memory.
__device__ __forceinline__ unsigned remote_addr(const void* p, unsigned rank) {
    unsigned local = (unsigned)__cvta_generic_to_shared(p), remote;
    asm volatile("mapa.shared::cluster.u32 %0, %1, %2;" : "=r"(remote) : "r"(local), "r"(rank));
    return remote;
}
__device__ __forceinline__ int load_remote(unsigned addr) {
    int v;
    asm volatile("ld.shared::cluster.s32 %0, [%1];" : "=r"(v) : "r"(addr) : "memory");
    return v;
}
__device__ __forceinline__ void or_remote(unsigned addr, unsigned v) {
    asm volatile("red.shared::cluster.or.b32 [%0], %1;" ::"r"(addr), "r"(v) : "memory");
}
#define CHAIN 8
// A cluster of four 1024-thread blocks; rank 0's thread 0 times, out[r * 8 + i] as above.
extern "C" __global__ void __cluster_dims__(4, 1, 1) probe_cluster(long long* out) {
    __shared__ int s[64];
    __shared__ unsigned s_or;
    const int k = threadIdx.x;
    const unsigned rank = cluster_rank();
    if (k < 64) s[k] = 0;
    if (k == 0) s_or = 0;
    cluster_sync();
    const unsigned peer = remote_addr(s, rank ^ 1u);
    unsigned v = 0;
    for (int r = 0; r < REPS; ++r) {
        long long t[8] = {0}, a;
        cluster_sync();
        a = clock64();
        cluster_sync();
        t[0] = clock64() - a;
        if (k == 0) {
            a = clock64();
            for (int i = 0; i < CHAIN; ++i) v = (unsigned)load_remote(peer + 4u * (v & 1u));
            t[1] = (clock64() - a) / CHAIN;
        }
        __syncthreads();
        a = clock64();
        int x = k < 132 ? load_remote(peer + 4u * (unsigned)(k & 63)) : 0;
        if (k < 64) s[k] = x;  // 0: the same value back
        __syncthreads();
        t[2] = clock64() - a;
        a = clock64();
        if (k == 0) or_remote(remote_addr(&s_or, rank ^ 1u), 1u);
        cluster_sync();
        t[3] = clock64() - a;
        if (k == 0 && rank == 0)
            for (int i = 0; i < 4; ++i) out[r * 8 + i] = t[i];
    }
    if (k == 0 && rank == 0 && v == 12345u) out[0] = v;  // keeps the chain
}
"""

CLUSTER_NAMES = (
    "cluster barrier, 4 x 1024 threads",
    "ld.shared::cluster, one thread",
    "132 threads ld.shared::cluster + bar",
    "red.shared::cluster + cluster barrier",
)


NAMES = (
    "atomicExch on L2",
    "atom.acquire.exch (take_flag)",
    "atomicAdd on L2",
    "ld.cg from L2",
    "__threadfence, nothing pending",
    "st.cg + __threadfence",
    "__threadfence_system",
    "store to mapped host + fence.sys",
    "ld.cv from mapped host (PCIe)",
    "__syncthreads, 1024 threads",
    "__syncthreads_or, 1024 threads",
    "4 ld.cv from mapped host, one thread",
    "96 threads, one ld.cv each + barrier",
    "72 threads, 3 ld.cv each + barrier",
)


def report(cycles: np.ndarray, names: tuple[str, ...], mhz: float) -> None:
    """Each probe's median over the repeats (rows), in cycles and ns."""
    for i, label in enumerate(names):
        med = float(np.median(cycles[:, i]))
        print(f"  {label:34s} {med:7.0f} cycles {med / mhz * 1e3:7.0f} ns")


def main() -> None:
    kernel = cp.RawModule(code=SOURCE).get_function("probe")
    reps = 200
    dev = cp.zeros(64 * 32 + 64, dtype=cp.uint32)
    mem = cp.cuda.PinnedMemory(512 * 4, cp.cuda.runtime.hostAllocMapped)
    host_ptr = cp.cuda.runtime.pointerGetAttributes(mem.ptr).devicePointer
    out = cp.zeros(reps * 16, dtype=cp.int64)
    for _ in range(2):  # the first launch warms caches and the module
        kernel((1,), (1024,), (dev, np.uintp(host_ptr), out))
        cp.cuda.runtime.deviceSynchronize()
    cycles = out.get().reshape(reps, 16)[20:]
    mhz = cp.cuda.Device().attributes["ClockRate"] / 1e3
    name = cp.cuda.runtime.getDeviceProperties(0)["name"].decode()
    print(f"{name}, SM clock {mhz:.0f} MHz (nominal); median of {len(cycles)} repeats")
    report(cycles, NAMES, mhz)
    if cp.cuda.Device().compute_capability < "90":
        return
    cluster = cp.RawModule(code=CLUSTER_SOURCE).get_function("probe_cluster")
    out = cp.zeros(reps * 8, dtype=cp.int64)
    for _ in range(2):
        cluster((4,), (1024,), (out,))
        cp.cuda.runtime.deviceSynchronize()
    report(out.get().reshape(reps, 8)[20:], CLUSTER_NAMES, mhz)


if __name__ == "__main__":
    main()
