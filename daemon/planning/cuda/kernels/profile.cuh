// The link profile (compiled in only with GB_PROFILE, which scripts/profile_cuda_links.py
// passes to NVRTC through device.DEFINES; a product build holds none of this: every macro
// below is empty). It answers what the phase stamps cannot: how much of a relaxation link is
// the queue (a neighbour's flag to the owner's take) and how much the visit (halo load, settle
// passes, stores, flags), what a raise visit costs, and what a grid barrier costs beyond the
// slowest block's arrival.
//
// Each block sums its own figures in shared memory (thread 0, SM cycles from clock64, read
// right after a block barrier so that they time the whole block), and adds them to the ctrl
// words abi.PF_* once, at the end of the call (prof_flush). Block 0 alone times its grid
// barriers. Cross-block intervals (the queue, a barrier's lag, the relaxation's end) use the
// global timer, whose low 32 bits suffice for differences within a call.
#pragma once
#include "abi.cuh"

#ifdef GB_PROFILE

// Per block: the sums, indexed by ctrl word (PF_*); 56 .. 63 are block 0's own scratch.
__shared__ unsigned s_prof[64];
#define PS_BAR_GT 56     // the global timer when block 0 left its last barrier (0: none yet)
#define PS_RELAX_GT 57   // when block 0 left the relaxation's loop
#define PS_CLOCK0 58     // block 0's clock64 (low word) and global timer at the call's start
#define PS_NS0 59

__device__ __forceinline__ unsigned prof_ns() {
    unsigned long long t;
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t));
    return (unsigned)t | 1u;  // 0 means "no time" in the flag-time words
}

#define PROF_NOW(v) const long long v = clock64()
#define PROF_DECL(v) long long v
#define PROF_SET(v) v = clock64()
#define PROF_ADD(word, amount)                                   \
    do {                                                         \
        if (threadIdx.x == 0) s_prof[word] += (unsigned)(amount); \
    } while (0)

// plan_call's start: every thread < 64 zeroes its word (a barrier follows in plan_call).
__device__ __forceinline__ void prof_start() {
    if (threadIdx.x < 64) s_prof[threadIdx.x] = 0;
    if (threadIdx.x == 0 && s_gblock == 0) {
        s_prof[PS_CLOCK0] = (unsigned)clock64();
        s_prof[PS_NS0] = prof_ns();
    }
}

// A barrier's two scratch words (PF_CYCLES, PF_NS until the flush): by parity of the barrier.
__device__ __forceinline__ unsigned* prof_bar_word(unsigned* ctrl, unsigned target) {
    return ctrl + PF_CYCLES + ((target / s_gsize) & 1u);
}

// Thread 0 of every block, arriving (before its fence): the latest arrival time, a reduction.
// Block 0 also takes (and zeroes) the last barrier's latest arrival, issued here so that its
// round trip overlaps the fence; the value is used after the arrival's atomic returns.
__device__ __forceinline__ unsigned prof_arrive(unsigned* ctrl, unsigned target) {
    atomicMax(prof_bar_word(ctrl, target), prof_ns());
    if (s_gblock != 0 || s_prof[PS_BAR_GT] == 0) return 0u;
    return atomicExch(prof_bar_word(ctrl, target - s_gsize), 0u);
}

// Block 0's thread 0 after a barrier: its phases (cycles) and the last barrier's lag, the time
// from the latest arrival to block 0 seeing the release (ns).
__device__ __forceinline__ void prof_barrier(long long b1, long long b2, long long b3,
                                             long long b4, unsigned last_arrival, unsigned seen) {
    if (s_gblock != 0) return;
    if (last_arrival && s_prof[PS_BAR_GT]) s_prof[PF_B_LAG] += s_prof[PS_BAR_GT] - last_arrival;
    s_prof[PS_BAR_GT] = seen;
    s_prof[PF_B_N] += 1;
    s_prof[PF_B_ARRIVE] += (unsigned)(b2 - b1);
    s_prof[PF_B_WAIT] += (unsigned)(b3 - b2);
    s_prof[PF_B_LEAVE] += (unsigned)(b4 - b3);
}

#define PROF_BARRIER_ARRIVE(ctrl, target) const unsigned prof_last = prof_arrive(ctrl, target)
#define PROF_BARRIER_SEEN(v) const unsigned v = prof_ns()
#define PROF_BARRIER_DONE(b1, b2, b3, b4, seen) prof_barrier(b1, b2, b3, b4, prof_last, seen)

// The relaxation: a flag's time, set by the first flag since the owner last took the tile
// (before the flag's release, so the owner's acquire sees it); the owner's take exchanges it.
#define PROF_FLAG_TIME(ft, n) atomicCAS((ft) + (n), 0u, prof_ns())
#define PROF_RELAX_END(ctrl) atomicMax((ctrl) + PF_T_LAG, prof_ns())
#define PROF_RELAX_EXIT()                                                   \
    do {                                                                    \
        if (threadIdx.x == 0 && s_gblock == 0) s_prof[PS_RELAX_GT] = prof_ns(); \
    } while (0)
// The last block, after copying ctrl to the host: the words start the next call at 0.
#define PROF_ZERO(ctrl)                                                     \
    do {                                                                    \
        if (threadIdx.x >= PF_R_VISITS && threadIdx.x <= PF_NS && threadIdx.x != C_RELEASE && \
            (threadIdx.x < P_SEG || threadIdx.x > P_NSEGS))                 \
            (ctrl)[threadIdx.x] = 0u;                                       \
    } while (0)

// The relaxation's flag times: an eighth word per tile after lb (the profile's planner
// allocates it, planner.FLAG_SEGMENTS).
#define PROF_FLAG_WORDS(ft, lb, ntiles) unsigned* ft = (unsigned*)(lb) + (ntiles)
// After a take: thread i < count exchanges tile s_list[i]'s flag time; the value is used only
// after the block's visits (PROF_QUEUED), so the exchange's round trip delays no visit.
#define PROF_TAKE_TIME(ft, s_list, count, v)                                       \
    unsigned v = 0u, v##_at = 0u;                                                  \
    if ((int)threadIdx.x < (count)) {                                              \
        v##_at = prof_ns();                                                        \
        v = atomicExch((ft) + (s_list)[threadIdx.x], 0u);                          \
    }
// The flag-to-take times of the tiles taken, summed into the block's words.
#define PROF_QUEUED(v)                                                             \
    do {                                                                           \
        if (v) {                                                                   \
            atomicAdd(&s_prof[PF_R_QUEUE], v##_at - v);                            \
            atomicAdd(&s_prof[PF_R_QUEUE_N], 1u);                                  \
        }                                                                          \
    } while (0)
#define PROF_START() prof_start()
#define PROF_FLUSH(ctrl, target) prof_flush(ctrl, target)

// The end of the call, every block (thread 0), before the last arrival: the block's sums into
// ctrl; block 0's barriers, the relaxation's end lag and the clocks. The arrival's fence
// orders these before the last block copies ctrl to the host.
__device__ void prof_flush(unsigned* ctrl, unsigned target) {
    if (threadIdx.x != 0) return;
    const int summed[] = {PF_R_VISITS, PF_R_TAKE, PF_R_IDLE_N, PF_R_IDLE, PF_R_LOAD,
                          PF_R_SETTLE, PF_R_STORE, PF_R_FLAG, PF_R_QUEUE, PF_R_QUEUE_N,
                          PF_A_VISITS, PF_A_TAKE, PF_A_LOAD, PF_A_FIX, PF_A_VISIT};
    for (int i = 0; i < (int)(sizeof(summed) / sizeof(summed[0])); ++i)
        if (s_prof[summed[i]]) atomicAdd(ctrl + summed[i], s_prof[summed[i]]);
    if (s_gblock != 0) return;
    // Every block arrived at the last barrier after its reductions above it: the words hold
    // that barrier's latest arrival and the relaxation's last visit end.
    const unsigned last = __ldcg(prof_bar_word(ctrl, target));
    if (last && s_prof[PS_BAR_GT]) s_prof[PF_B_LAG] += s_prof[PS_BAR_GT] - last;
    const unsigned relax_end = __ldcg(ctrl + PF_T_LAG);
    ctrl[PF_T_LAG] = relax_end && s_prof[PS_RELAX_GT] ? s_prof[PS_RELAX_GT] - relax_end : 0u;
    for (int w = PF_B_N; w <= PF_B_LAG; ++w) ctrl[w] = s_prof[w];
    ctrl[PF_CYCLES] = (unsigned)clock64() - s_prof[PS_CLOCK0];
    ctrl[PF_NS] = prof_ns() - s_prof[PS_NS0];
}

#else

#define PROF_NOW(v)
#define PROF_DECL(v)
#define PROF_SET(v)
#define PROF_ADD(word, amount)
#define PROF_BARRIER_ARRIVE(ctrl, target)
#define PROF_BARRIER_SEEN(v)
#define PROF_BARRIER_DONE(b1, b2, b3, b4, seen)
#define PROF_FLAG_TIME(ft, n)
#define PROF_RELAX_END(ctrl)
#define PROF_RELAX_EXIT()
#define PROF_ZERO(ctrl)
#define PROF_FLAG_WORDS(ft, lb, ntiles)
#define PROF_TAKE_TIME(ft, s_list, count, v)
#define PROF_QUEUED(v)
#define PROF_START()
#define PROF_FLUSH(ctrl, target)

#endif
