// The fast planner's EDS step before its relaxation (included by fast.cu): the raise (without
// rounds, like the relaxation) and the reset round (which also takes back deferred tiles of
// the focused repair); with the helpers they share with the relaxation (taking a block's
// flagged tiles, the focus's tile heuristic, the phase stamps). The cut-over that gives the
// repair up is cut_over.cuh.
#pragma once
#include "tile_relax.cuh"
#include "path_exits.cuh"

#define IDLE_LIMIT (1u << 22)  // polls without work (~µs each): seconds, far beyond any plan

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

// The raise without rounds (EDS step 1), like relax_async (fast.cu): block b of the group owns
// tiles b, b + GSIZE, ... and raises each as soon as it is flagged in `flags` (round 0's, counted
// in *work); a visit that raises cells on an edge or corner flags the tile across, with a
// release, so the visit it calls for sees them. The raised set is the least fixpoint of a
// monotone rule (raise_tile), which any schedule reaches that visits a tile after each change
// of its halo: the rounds' set, without a grid barrier and a count read per round (3 to 5 µs a
// round on an H100, profile_cuda_phases.py).
// Raised cells are counted into ctrl[C_RAISED] as they are raised. A block leaves when *work is
// 0 (nothing flagged, no visit under way: the raise is complete) or once it reads that count
// above `limit`: the call cuts over (keep_below_change) and the raise is thrown away, so no
// block need finish it. The caller decides after the grid barrier that follows, from the final
// count (the same word in every block): the count only grows, so a block that left early
// decided as every block decides then, and a call cuts over exactly when the complete raise
// would pass the limit, as with rounds.
__device__ void raise_async(const Grid& G, unsigned* flags, unsigned* work, unsigned* seeds,
                            unsigned* ctrl, const int* g, unsigned char* raised, int (*gs)[HT],
                            unsigned char (*rs)[HT], int* s_list, int* s_n, unsigned limit) {
    __shared__ unsigned s_work, s_taken, s_total;
    if (GBLOCK >= G.ntiles) return;  // owns no tile: the barrier after waits for the others
    unsigned idle = 0;
    while (true) {
        // Read in the same pass as the work count, after the last pass's barrier below.
        if (threadIdx.x == THREADS - 2) s_total = ((volatile const unsigned*)ctrl)[C_RAISED];
        int visited = 0;
        for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
            int count = take_flagged(flags, G.ntiles, base, s_list, s_n,
                                     base == (int)GBLOCK ? work : nullptr, &s_work, &s_taken);
            for (int i = 0; i < count; ++i) {
                const int tile = s_list[i], k = threadIdx.x;
                bool any = false;
                unsigned fresh = 0;
                unsigned bits =
                    raise_tile(G, tile, g, raised, gs, rs, ctrl + C_SWEEPS, &any, &fresh);
                if (k < 8 && (bits & (1u << k))) {
                    const int n = tile_across(G, tile, k);
                    if (n >= 0) flag_tile(flags, work, n, true);  // after the raised bytes
                }
                if (any && k == 8) atomicExch(seeds + tile, 1u);
                if (fresh && k == 9) atomicAdd(ctrl + C_RAISED, fresh);
                if (k == 0) atomicAdd(ctrl + C_TILES, 1u);
                __syncthreads();  // shared tile buffers are reused by the next tile
            }
            // The flags this block set are counted before the ones it took are uncounted.
            if (count && threadIdx.x == 0) atomicSub(work, s_taken);
            visited += count;
        }
        const bool over = s_total > limit;
        const unsigned pending = s_work;
        __syncthreads();  // every thread has read both before the next pass writes them
        if (over) break;
        if (visited) {
            idle = 0;
            continue;
        }
        if (pending == 0u) break;
        if (++idle == IDLE_LIMIT) __trap();  // a lost flag would otherwise hang the daemon
    }
}

// The reset round (EDS step 2): every block takes its seed tiles (the tiles that hold a raised
// or freed cell), resets their raised cells to INF (reset_tile) and flags them in `next` for
// the relaxation (counted in *cnt_next). It also takes back the deferred tiles whose key
// lb + h(focus) is no more than `g_focus`, the focus's g after the reset (INF: every one;
// fy < 0: no focus). Ends with the group's barrier.
__device__ void reset_round(const Grid& G, unsigned* seeds, unsigned* next, unsigned* cnt_next,
                            unsigned* stale, unsigned* ctrl, int* g, unsigned char* raised,
                            int* s_list, int* s_n, unsigned* bar, unsigned* deferred, int* lb,
                            int g_focus, int fy, int fx) {
    if (GBLOCK == 0 && threadIdx.x == 0) atomicAdd(ctrl + C_ROUNDS, 1u);  // a reduction
    for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
        int count = take_flagged(seeds, G.ntiles, base, s_list, s_n);
        for (int i = 0; i < count; ++i) {
            int tile = s_list[i];
            unsigned bits = reset_tile(G, tile, g, raised);
            if (threadIdx.x == 0) flag_tile(next, cnt_next, tile);
            mark_exits_stale(G, tile, bits, (int)threadIdx.x - 32, stale);
            if (threadIdx.x == 0) atomicAdd(ctrl + C_TILES, 1u);
            __syncthreads();  // reset_tile's shared word is reused by the next tile
        }
    }
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
    grid_barrier(ctrl, bar);
}
