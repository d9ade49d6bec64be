// The grid-wide rounds of the fast planner's EDS step (included by fast.cu): the raise rounds,
// the reset round (which also takes back deferred tiles of the focused repair), and the
// cut-over that gives the repair up; with the helpers they share with the relaxation (taking a
// block's flagged tiles, the focus's tile heuristic, the phase stamps).
#pragma once
#include "tile_relax.cuh"
#include "path_exits.cuh"

// phases (ops) of a round
#define OP_RAISE 1
#define OP_RESET 2
// In a raise round's flag count: the cells raised so far passed the limit (flag counts never
// come near it).
#define CUT_PENDING 0x80000000u

// h(focus, tile n): the octile distance from the focus (fy, fx) to n's nearest cell.
__device__ __forceinline__ int tile_h(const Grid& G, int n, int fy, int fx) {
    int oy = (n / G.tiles_x) * TILE, ox = (n % G.tiles_x) * TILE;
    int dy = max(0, max(oy - fy, fy - min(oy + TILE, G.h) + 1));
    int dx = max(0, max(ox - fx, fx - min(ox + TILE, G.w) + 1));
    return STRAIGHT * max(dy, dx) + (DIAGONAL - STRAIGHT) * min(dy, dx);
}

// Block 0's thread 0 stamps phase boundary i (ctrl[C_STAMP + i], scripts/profile_cuda_phases.py).
__device__ __forceinline__ void stamp(unsigned* ctrl, int i) {
    if (GBLOCK == 0 && threadIdx.x == 0) ctrl[C_STAMP + i] = (unsigned)global_ns();
}

// Count n cells newly raised in round r: into the round's word of the raise ring (which
// round_pending reads after the round's barrier) and the call's total (a statistic, and the
// cut-over's C_CUT). Both are reductions the visit never waits for: comparing the running
// total with the limit here needed the add's return, a round trip to L2 (~0.6 µs) on the
// visit's path, before the block could take its next tile or arrive at the barrier.
__device__ __forceinline__ void count_raised(unsigned* ctrl, unsigned n, int r) {
    atomicAdd(ctrl + C_RAISE_RING + (r + 1) % 3, n);
    atomicAdd(ctrl + C_RAISED, n);
}

// After round r's barrier, in every thread: the round's flag count, with CUT_PENDING once the
// cells raised so far passed `limit`. *so_far (shared) is the block's running sum of the
// ring's words, the same in every block: a word is read only after its round's barrier and
// is not written again before the barrier of round r + 2 (run_round zeroes it then). The
// two loads are independent: one round trip. The sum is kept in shared memory, not in a
// register passed by address, which put it on plan_call's stack.
__device__ __forceinline__ unsigned round_pending(const unsigned* ctrl, int r, unsigned limit,
                                                  unsigned* so_far) {
    const unsigned pending = ((volatile const unsigned*)ctrl)[C_CNT + (r + 1) % 3];
    const unsigned raised = ((volatile const unsigned*)ctrl)[C_RAISE_RING + (r + 1) % 3];
    const unsigned total = *so_far + raised;
    __syncthreads();  // every thread has read *so_far (its next read follows a grid barrier)
    if (threadIdx.x == 0) *so_far = total;
    return total > limit ? pending | CUT_PENDING : pending;
}

// Take this block's flagged tiles of the chunk at `base` (t = base + k * GSIZE) into
// s_list (take_flag: one atomic each; a read first would cost a second round trip on the
// wave's critical path). With `watch`, the block's last thread reads *watch into *s_watch in
// the same pass; with `s_sum`, the flags' counts are summed there. Returns how many tiles,
// the same in every thread of the block.
__device__ int take_flagged(unsigned* flags, int ntiles, int base, int* s_list, int* s_n,
                            const unsigned* watch = nullptr, unsigned* s_watch = nullptr,
                            unsigned* s_sum = nullptr) {
    __syncthreads();  // every thread has read the previous count
    if (threadIdx.x == 0) {
        *s_n = 0;
        if (s_sum) *s_sum = 0;
    }
    __syncthreads();
    int t = base + threadIdx.x * GSIZE;
    unsigned count = t < ntiles ? take_flag(flags, t) : 0u;
    if (count) {
        s_list[atomicAdd(s_n, 1)] = t;
        if (s_sum) atomicAdd(s_sum, count);
    }
    if (watch && threadIdx.x == THREADS - 1) *s_watch = *((volatile const unsigned*)watch);
    __syncthreads();
    return *s_n;
}

// One grid-wide round: every block takes its flagged tiles of `in`, applies `op`, and flags
// tiles for the next round in `next` (counted in ctrl[C_CNT + (r + 1) % 3]). Returns that
// count, 0 when no tile is flagged for the next round, the same in every block; after a
// raise, with CUT_PENDING once more than `limit` cells were raised in all (*so_far: the
// cells raised before this round, round_pending).
// The reset round also takes back the deferred tiles whose key lb + h(focus) is no more than
// `g_focus`, the focus's g after the reset (INF: every one; fy < 0: no focus).
__device__ unsigned run_round(const Grid& G, int op, unsigned* in, unsigned* next, unsigned* seeds,
                              unsigned* stale, unsigned* ctrl, int r, int* g,
                              const unsigned char* blocked, unsigned char* raised, int (*gs)[HT],
                              unsigned char (*bs)[TILE + 1], unsigned char (*rs)[HT], int* s_list,
                              int* s_n, unsigned* bar, unsigned limit, unsigned* so_far,
                              unsigned* deferred = nullptr, int* lb = nullptr, int g_focus = INF,
                              int fy = -1, int fx = 0) {
    unsigned* cnt_next = ctrl + C_CNT + (r + 1) % 3;
    if (GBLOCK == 0 && threadIdx.x == 0) {
        ctrl[C_CNT + (r + 2) % 3] = 0;
        ctrl[C_RAISE_RING + (r + 2) % 3] = 0;
        atomicAdd(ctrl + C_ROUNDS, 1u);  // a reduction: += would wait for the load
    }
    for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
        PROF_NOW(p0);
        int count = take_flagged(in, G.ntiles, base, s_list, s_n);
        PROF_NOW(p1);
        if (op == OP_RAISE) PROF_ADD(PF_A_TAKE, p1 - p0);
        for (int i = 0; i < count; ++i) {
            int tile = s_list[i];
            PROF_NOW(v0);
            if (op == OP_RAISE) {
                bool any = false;
                unsigned fresh = 0;
                unsigned bits =
                    raise_tile(G, tile, g, raised, gs, rs, ctrl + C_SWEEPS, &any, &fresh);
                flag_neighbour(G, tile, bits, threadIdx.x, next, cnt_next);
                if (any && threadIdx.x == 8) atomicExch(seeds + tile, 1u);
                if (fresh && threadIdx.x == 9) count_raised(ctrl, fresh, r);
            } else {
                unsigned bits = reset_tile(G, tile, g, raised);
                if (threadIdx.x == 0) flag_tile(next, cnt_next, tile);
                mark_exits_stale(G, tile, bits, (int)threadIdx.x - 32, stale);
            }
            if (threadIdx.x == 0) atomicAdd(ctrl + C_TILES, 1u);
            __syncthreads();  // shared tile buffers are reused by the next tile
            PROF_NOW(v1);
            if (op == OP_RAISE) PROF_ADD(PF_A_VISIT, v1 - v0);
            if (op == OP_RAISE) PROF_ADD(PF_A_VISITS, 1);
        }
    }
    if (deferred) {
        for (int t = GBLOCK * THREADS + threadIdx.x; t < G.ntiles; t += GSIZE * THREADS) {
            // Both words at once: the bound read after the flag was a second round trip on
            // block 0's path to the barrier.
            const unsigned is_deferred = __ldcg(deferred + t);
            const int bound = __ldcg(lb + t);
            if (!is_deferred) continue;
            if (fy >= 0 && bound + tile_h(G, t, fy, fx) > g_focus) continue;  // stays deferred
            deferred[t] = 0u;
            lb[t] = INF;
            flag_tile(next, cnt_next, t);
        }
    }
    grid_barrier(ctrl, bar);
    if (op == OP_RAISE) return round_pending(ctrl, r, limit, so_far);
    return *((volatile unsigned*)cnt_next);
}
