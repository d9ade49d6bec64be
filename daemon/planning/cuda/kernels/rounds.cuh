// The grid-wide rounds of the fast planner's EDS step (included by fast.cu): round 0 (the
// delta), the raise rounds, and the relaxation's start after them (which also takes back
// deferred tiles of the focused repair; the cut-over that gives the repair up is in
// cut_over.cuh); with the helpers they share with the relaxation (taking a block's flagged
// tiles, the focus's tile heuristic, the phase stamps).
#pragma once
#include "tile_relax.cuh"
#include "path_exits.cuh"

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
// is not written again before the barrier of round r + 2 (raise_round zeroes it then). The
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

// EDS round 0, every block of the group: the delta applied, warp by warp, so that the flags
// are set once per distinct tile (a delta of 30,000 cells, a 3 m sweep at 2000², flagged 9
// tiles a cell, two atomics each, most of them on one count, and spent ~200 µs here,
// scripts/profile_cuda_phases.py; a warp's cells lie mostly in one tile). A newly blocked cell
// is raised, takes INF at once (raise_tile: raised cells hold INF from their raise on, which
// stands in for the reset round), marks stale the exits that read it, and flags the tiles of
// its 3 x 3 for the first raise round (into `flags`, counted in *cnt). seeds: the tiles of
// the changed cells.
// From the old field, before anything here changes it: the cut-over's level (cut_over.cuh),
// the least of the newly blocked cells' g, of g + STRAIGHT beside the freed cells, and of the
// deferred tiles' bounds, into ctrl[C_KEEP] as INF - level (a max keeps the least level). The
// g loads go out with the blocked byte's: one round trip. A g read here that another thread
// already set to INF belongs to a newly blocked cell, whose own term is lower: the least is
// the same.
// Not inlined: it runs once a call, and inlined it added to plan_call's spills (ptxas -v,
// sm_90: 180 bytes of stores a thread against 176; main's plan_call spilled 152).
__device__ __noinline__ void apply_delta(const Grid& G, const int* delta, int ndelta, int* g,
                            unsigned char* blocked, unsigned char* raised, unsigned* flags,
                            unsigned* cnt, unsigned* seeds, unsigned* stale,
                            const unsigned* deferred, const int* lb, unsigned* ctrl) {
    const int tid = GBLOCK * THREADS + threadIdx.x, stride = GSIZE * THREADS;
    const int h = G.h, w = G.w, lane = threadIdx.x & 31;
    unsigned mine = 0, flagged = 0;  // mine: newly blocked cells, raised and counted
    int low = INF;
    if (tid == 0) ctrl[C_WORK] = GSIZE;  // the relaxation's tokens (start_relaxation)
    for (int base = tid - lane; base < ndelta; base += stride) {
        int i = base + lane;
        int near[4] = {-1, -1, -1, -1};  // the tiles of a newly blocked cell's 3 x 3
        int seed = -1;
        if (i < ndelta) {
            const int code = __ldcv(delta + i);
            const int cell = code >> 1, cy = cell / w, cx = cell % w;
            const unsigned char now = code & 1;
            const unsigned char was = __ldcg(blocked + cell);
            if (now) {
                low = min(low, __ldcg(g + cell));
            } else {
#pragma unroll
                for (int k = 0; k < 8; ++k) {
                    int ny = cy + NB_DR[k], nx = cx + NB_DC[k];
                    if (ny >= 0 && nx >= 0 && ny < h && nx < w)
                        low = min(low, __ldcg(g + ny * w + nx) + STRAIGHT);
                }
            }
            if (was != now) {
                blocked[cell] = now;
                seed = (cy / TILE) * G.tiles_x + cx / TILE;
                if (now) {
                    // Its children may lie in the tiles around: each of those looks at it.
                    raised[cell] = 1;
                    __stcg(g + cell, INF);
                    ++mine;
                    int y0 = max(cy - 1, 0) / TILE, y1 = min(cy + 1, h - 1) / TILE;
                    int x0 = max(cx - 1, 0) / TILE, x1 = min(cx + 1, w - 1) / TILE;
                    near[0] = y0 * G.tiles_x + x0;
                    if (x1 != x0) near[1] = y0 * G.tiles_x + x1;
                    if (y1 != y0) near[2] = y1 * G.tiles_x + x0;
                    if (y1 != y0 && x1 != x0) near[3] = y1 * G.tiles_x + x1;
                }
            }
        }
        // One flag per distinct tile of the warp (the raise round reads only whether a tile
        // is flagged, and the count only whether it is 0). The tiles of the 3 x 3 are the
        // cell's own and those across the edges it lies on: the exits that read it.
#pragma unroll
        for (int k = 0; k < 4; ++k) {
            unsigned same = __match_any_sync(FULL, near[k]);
            if (near[k] >= 0 && lane == __ffs(same) - 1) {
                atomicAdd(flags + near[k], 1u);
                stale[near[k]] = 1u;
                ++flagged;
            }
        }
        unsigned same = __match_any_sync(FULL, seed);
        if (seed >= 0 && lane == __ffs(same) - 1 && !__ldcg(seeds + seed)) seeds[seed] = 1u;
    }
    for (int t = tid; t < G.ntiles; t += stride) {
        const unsigned is_deferred = __ldcg(deferred + t);
        const int bound = __ldcg(lb + t);  // with the flag: one round trip, not two
        if (is_deferred) low = min(low, bound);
    }
    low = __reduce_min_sync(FULL, low);
    if (lane == 0 && low < INF) atomicMax(ctrl + C_KEEP, (unsigned)(INF - low));
    mine = __reduce_add_sync(FULL, mine);
    flagged = __reduce_add_sync(FULL, flagged);
    if (lane == 0 && flagged) atomicAdd(cnt, flagged);
    if (lane == 0 && mine) count_raised(ctrl, mine, 0);
}

// One grid-wide raise round r: every block takes its flagged tiles of `in`, raises them
// (raise_tile), and flags tiles for the next round in `next` (counted in
// ctrl[C_CNT + (r + 1) % 3]). Returns that count, 0 when no tile is flagged for the next round,
// the same in every block, with CUT_PENDING once more than `limit` cells were raised in all
// (*so_far: the cells raised before this round, round_pending).
__device__ unsigned raise_round(const Grid& G, unsigned* in, unsigned* next, unsigned* seeds,
                                unsigned* stale, unsigned* ctrl, int r, int* g,
                                unsigned char* raised, int (*gs)[HT], unsigned char (*rs)[HT],
                                int* s_list, int* s_n, unsigned* bar, unsigned limit,
                                unsigned* so_far) {
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
        PROF_ADD(PF_A_TAKE, p1 - p0);
        for (int i = 0; i < count; ++i) {
            int tile = s_list[i];
            PROF_NOW(v0);
            bool any = false;
            unsigned fresh = 0;
            unsigned bits = raise_tile(G, tile, g, raised, gs, rs, ctrl + C_SWEEPS, &any, &fresh);
            flag_neighbour(G, tile, bits, threadIdx.x, next, cnt_next);
            if (any && threadIdx.x == 8) atomicExch(seeds + tile, 1u);
            if (fresh && threadIdx.x == 9) count_raised(ctrl, fresh, r);
            // The cells raised here now hold INF: the exits that read them.
            mark_exits_stale(G, tile, fresh ? bits | CHANGED_ANY : 0u, (int)threadIdx.x - 32,
                             stale);
            if (threadIdx.x == 0) atomicAdd(ctrl + C_TILES, 1u);
            __syncthreads();  // shared tile buffers are reused by the next tile
            PROF_NOW(v1);
            PROF_ADD(PF_A_VISIT, v1 - v0);
            PROF_ADD(PF_A_VISITS, 1);
        }
    }
    grid_barrier(ctrl, bar);
    return round_pending(ctrl, r, limit, so_far);
}

// EDS after a raise that did not cut over, every block of the group: what the reset round
// did, without its grid barrier. The raised cells already hold INF (raise_tile), so the reset
// is only bookkeeping: each block takes its tiles of `seeds` (those of the changed and the
// raised cells), clears their raised bytes (nothing reads them until the next call's round 0)
// and flags them for the relaxation, and takes back the deferred tiles whose key
// lb + h(focus) is no more than `g_focus` (an upper bound of the focus's final g: INF takes
// back every one; fy < 0: no focus). Then it gives back its token of *work (GSIZE tokens, set
// in round 0): no block sees the count at 0, and leaves the relaxation, before every block has
// flagged its tiles, and a flag is counted before its token is given back (the block's
// barrier orders its threads' adds before thread 0's subtraction).
__device__ void start_relaxation(const Grid& G, unsigned* seeds, unsigned* dirty, unsigned* work,
                                 unsigned char* raised, unsigned* deferred, int* lb, int g_focus,
                                 int fy, int fx, int* s_list, int* s_n) {
    for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
        int count = take_flagged(seeds, G.ntiles, base, s_list, s_n);
        for (int i = 0; i < count; ++i) {
            const TileCell c = tile_cell(G, s_list[i]);
            if (c.inside) raised[c.idx] = 0;
        }
        if ((int)threadIdx.x < count) flag_tile(dirty, work, s_list[threadIdx.x]);
    }
    for (int t = GBLOCK * THREADS + threadIdx.x; t < G.ntiles; t += GSIZE * THREADS) {
        // Both words at once: the bound read after the flag would be a second round trip.
        const unsigned is_deferred = __ldcg(deferred + t);
        const int bound = __ldcg(lb + t);
        if (!is_deferred) continue;
        if (fy >= 0 && bound + tile_h(G, t, fy, fx) > g_focus) continue;  // stays deferred
        deferred[t] = 0u;
        lb[t] = INF;
        flag_tile(dirty, work, t);
    }
    __syncthreads();
    if (threadIdx.x == 0) atomicSub(work, 1u);
}
