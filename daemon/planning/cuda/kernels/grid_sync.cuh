// The grid-wide (group-wide: GSIZE blocks) barrier of the kernels whose blocks are all resident (fast.cu, path_tiles.cu).
//
// Valid only when every block of the launch is resident at once (the host sizes the grid
// from the occupancy). ctrl[C_BAR] counts arrivals and only ever grows: the host passes the
// count the previous launch ended with as the first target, so no reset races the next
// barrier. The last block in publishes the count in ctrl[C_RELEASE], a cache line of its own
// that the waiting blocks read while the arrivals hit the counter.
#pragma once
#include "abi.cuh"

#define SPIN_LIMIT (1u << 26)  // ~seconds of __nanosleep(32) before a wait is called hung

// The blocks a call runs on: its group of the launch's blocks. The resident loop serves the
// calls of a batch side by side, each on a group of its own (resident.cuh, serve_batch); a
// call and its barriers see only its group: block GBLOCK of GSIZE. Every kernel sets both
// before its first use (path_tiles: the whole grid).
__shared__ unsigned s_gblock, s_gsize;
#define GBLOCK s_gblock
#define GSIZE s_gsize
#include "profile.cuh"  // empty unless GB_PROFILE

__device__ __forceinline__ void whole_grid_group() {
    if (threadIdx.x == 0) {
        s_gblock = blockIdx.x;
        s_gsize = gridDim.x;
    }
    __syncthreads();
}

__device__ void grid_barrier(unsigned* ctrl, unsigned* target) {
    __syncthreads();
    if (threadIdx.x == 0) {
        PROF_NOW(b1);
        *target += GSIZE;
        PROF_BARRIER_ARRIVE(ctrl, *target);
        __threadfence();
        unsigned arrived = atomicAdd(ctrl + C_BAR, 1u) + 1u;
        volatile unsigned* release = ctrl + C_RELEASE;
        PROF_DECL(b2);  // set in the branch taken: after the atomic's return
        if (arrived == *target) {
            PROF_SET(b2);
            *release = arrived;
        } else {
            PROF_SET(b2);
            // Blocks that are not all resident (another process's kernels under MPS, say)
            // would wait here forever; after seconds, trap: a CUDA error the host's CPU
            // fallback turns into a warning instead of a hung daemon.
            unsigned spins = 0;
            while ((int)(*release - *target) < 0) {
                __nanosleep(32);
                if (++spins == SPIN_LIMIT) __trap();
            }
        }
        PROF_BARRIER_SEEN(seen);
        PROF_NOW(b3);
        __threadfence();
        PROF_NOW(b4);
        PROF_BARRIER_DONE(b1, b2, b3, b4, seen);
    }
    __syncthreads();
}

// The launch's last barrier, arrival only: every block's writes, the host's mapped memory
// included, are fenced before it arrives; returns true in the block that arrives last (every
// thread of it), which alone goes on to publish the result. The others leave at once.
__device__ bool grid_arrive_last(unsigned* ctrl, unsigned* target) {
    __shared__ int s_last;
    __syncthreads();
    if (threadIdx.x == 0) {
        *target += GSIZE;
        __threadfence_system();
        unsigned arrived = atomicAdd(ctrl + C_BAR, 1u) + 1u;
        s_last = arrived == *target;
        // The last block reads what the others counted into ctrl (device memory): an acquire
        // at device scope; their host writes reach the host before the done word through
        // their own system fences above.
        if (s_last) __threadfence();
    }
    __syncthreads();
    return s_last != 0;
}

// A flag is a count: flag_tile adds one to flags[t], after adding one to *cnt (so *cnt is the
// sum of the counts set), and take_flag reads and clears it. Both adds are reductions the
// setter never waits for. With `release`, a fence between them makes everything the setter
// wrote before, the count included, visible to the block that takes the flag: that block's
// loads then see the data, and its uncounting never overtakes the count.
__device__ __forceinline__ void flag_tile(unsigned* flags, unsigned* cnt, int t,
                                          bool release = false) {
    atomicAdd(cnt, 1u);
    if (release) __threadfence();
    atomicAdd(flags + t, 1u);
}

// The global timer, ns (resident.cuh's idle limit).
__device__ __forceinline__ unsigned long long global_ns() {
    unsigned long long t;
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t));
    return t;
}

// A load that orders this thread's later loads after it (an acquire: no full fence).
__device__ __forceinline__ unsigned load_acquire(const unsigned* p) {
    unsigned v;
    asm volatile("ld.acquire.gpu.global.b32 %0, [%1];" : "=r"(v) : "l"(p) : "memory");
    return v;
}

// Four words of host memory (mapped, 16-byte aligned) in one PCIe read, as an acquire at
// system scope: the later reads see what the host wrote before the value read here.
__device__ __forceinline__ int4 load_acquire_sys(const int* p) {
    int4 v;
    asm volatile("ld.acquire.sys.global.v4.s32 {%0, %1, %2, %3}, [%4];"
                 : "=r"(v.x), "=r"(v.y), "=r"(v.z), "=r"(v.w)
                 : "l"(p)
                 : "memory");
    return v;
}

// Take flag t: its count, and 0 left in its place. An acquire (on sm_90 the exchange, then an
// L1 invalidation), so this thread's later loads, and the block's after a barrier, see what
// the flag's setters wrote before it; __threadfence() after a plain exchange would add a full
// fence, about 340 ns on an H100, on the wave's path at every tile.
__device__ __forceinline__ unsigned take_flag(unsigned* flags, int t) {
    unsigned count;
    asm volatile("atom.acquire.gpu.global.exch.b32 %0, [%1], 0;"
                 : "=r"(count)
                 : "l"(flags + t)
                 : "memory");
    return count;
}
