// The fast CUDA planner: one replanning step, the path included, per request of a resident loop.
//
// The grid is cut into 32 x 32 tiles (tile_relax.cuh). A block loads a tile and its one-cell
// halo into shared memory and relaxes it until it settles; only then does the tile's change
// reach the neighbouring tiles. A tile is relaxed only when it is flagged: by the delta, by
// the goal, or by a neighbour whose border changed. So an EDS update touches only the tiles
// around the change.
//
// Correctness does not depend on the order of relaxation: every value ever written is the
// cost of a real path (an upper bound), values only decrease, and every tile whose halo
// changed after it last read it is flagged again. The fixpoint of g[v] = min(g[v], g[n] + c)
// is then the exact field, whatever the schedule.
//
// The relaxation has no rounds: block b of the call's GSIZE owns tiles b, b + GSIZE, ... and
// relaxes each as soon as it is flagged, so the wave moves at the pace of one tile instead of
// a grid-wide round. The EDS raise and reset phases run in grid-wide rounds (a few per step).
//
// Cut-over: an EDS call that raises more than `limit` cells (a wall across the route: the
// whole shadow behind it) gives up the repair at the end of that round: raising and
// re-lowering that many cells costs more than a plan from the goal (the CPU's rule,
// cpu/dial.py). It keeps every cell whose old g lies below the least g the change can reach
// and relaxes from there (cut_over.cuh), not from the goal. The raised cells are counted as
// they are raised, into the round's word of a ring beside the flag counts (rounds.cuh,
// count_raised); every block reads it with the round's flag count after the round's barrier
// and adds it to its running total, so the decision is the same in every block and costs no
// extra barrier, no host round trip, and no visit a wait for an atomic's return.
//
// Focused repair (focus >= 0, the user's cell; LPA*'s and D* Lite's keys, Koenig and Likhachev
// 2002, per tile). A visit that lowers cells on edge/corner k of its tile bounds every value the
// tile n across k can take from that change below by emin (their least new g), so no cell of n
// can come out cheaper than key(n) = emin + h(focus, n), h the octile distance from the focus
// to n's nearest cell. If key(n) > g(focus), n cannot lie on any of the focus's shortest paths
// (nor can any neighbour the path's tie-break compares): instead of flagging n for a visit,
// the visit defers it (deferred[n], its bound lb[n] = the least emin since it was last
// visited). The relaxation thus settles the ellipse g* + h <= g*(focus) between the focus and
// the goal and leaves the rest. Why the path read is then the reference path, tie for tie: an
// inconsistent cell u on a shortest path from the focus has a neighbour w that is exact, and
// whichever visit last lowered w flagged or deferred u's tile with a bound <= g(w), so its key
// is <= g(w) + h(u) <= g*(focus) <= g(focus): it was visited. The next call's reset round
// takes the deferred tiles back into the relaxation whose key lb + h(new focus) is no more
// than g(focus) after the raise (INF if raised: all of them), and keeps the others deferred;
// a call with focus < 0 (settle: costs(), cost_at()) takes them all back. Cells of deferred
// tiles hold upper bounds (costs of real paths) that can exceed a neighbour's g + c: the raise
// counts such a neighbour as a support (raise_tile), so no cost is ever under its true value.
// A plan from scratch (DSS) and the cut-over (cut_over.cuh) clear every deferral; DSS is never
// focused.
//
// With start >= 0 the call then extracts the path from `start` (path_exits.cuh), reusing
// the exits of every tile whose g and halo did not change since the last extraction.
//
// Host contract (cuda/planner.py): the loop has at most as many blocks as can be resident at
// once (the barriers spin), one loop at a time per device, flags zero but for the stale region
// (set at allocation), ctrl zero at allocation. Everything that changes from call to call is
// read from device memory (params, and the barrier count the last loop ended with in
// ctrl[C_BASE]), so the resident loop (resident.cuh) runs one call after another in a single
// launch, and a new launch takes over where the last one ended.
//
// The results go straight to the host: io is page-locked host memory mapped into the device.
// The call writes the path there, and the block that finishes last copies the statistics and
// then sets io[IO_DONE] to the call's sequence number, which the host polls: no copy after
// the call and no stream synchronisation. (The params come the other way through device
// memory: every block reading the same host words at its start would queue a hundred PCIe
// reads one behind another.)

#include "tile_relax.cuh"
#include "path_exits.cuh"
#include "rounds.cuh"  // the EDS step's grid-wide rounds
#include "cut_over.cuh"

// ctrl and io words: abi.cuh (generated from cuda/abi.py).

#define IDLE_LIMIT (1u << 22)  // polls without work (~µs each): seconds, far beyond any plan

// The relaxation without rounds. *work is the sum of the flags' counts, set or taken
// by a visit under way (a block uncounts what it took after its visits have flagged their
// neighbours); the phase ends when it reaches 0, which is final, since only a visit sets a flag.
// depth[t]: the longest chain of visits that flagged t (a statistic: the rounds it replaces).
// focus >= 0 (fy, fx): a neighbour whose key exceeds g(focus) is deferred, not flagged (see
// the header); the focus's g is read at each visit's start: a value read early is higher than
// the final one, so a deferral against it holds against the final one too.
__device__ void relax_async(const Grid& G, unsigned* dirty, unsigned* work, unsigned* depth,
                            unsigned* stale, unsigned* ctrl, int* g, const unsigned char* blocked,
                            int (*gs)[HT], unsigned char (*bs)[TILE + 1], int* s_list, int* s_n,
                            int focus, int fy, int fx, unsigned* deferred, int* lb) {
    // The block's statistics are summed here and added to ctrl once, at the end: atomics per
    // visit would share a cache line with the work count that every block polls.
    __shared__ unsigned s_work, s_taken, s_stats[3];  // s_stats: C_SWEEPS .. C_CHANGED
    __shared__ int s_emin[8];
    // A block that owns no tile has nothing to wait for here (the grid barrier after waits).
    if (GBLOCK >= G.ntiles) return;
    if (threadIdx.x < 3) s_stats[threadIdx.x] = 0;  // take_flagged's barrier comes before use
    PROF_FLAG_WORDS(flag_time, lb, G.ntiles);  // GB_PROFILE: the flags' times (an 8th word)
    unsigned idle = 0, longest = 0, visits = 0;
    while (true) {
        int visited = 0;
        for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
            PROF_NOW(p0);
            // The first chunk's pass also reads the work count, for the test below.
            int count = take_flagged(dirty, G.ntiles, base, s_list, s_n,
                                     base == (int)GBLOCK ? work : nullptr, &s_work, &s_taken);
            PROF_NOW(p1);
            PROF_ADD(count ? PF_R_TAKE : PF_R_IDLE, p1 - p0);
            PROF_ADD(PF_R_IDLE_N, count ? 0 : 1);
            PROF_TAKE_TIME(flag_time, s_list, count, queued);
            for (int i = 0; i < count; ++i) {
                int tile = s_list[i];
                int k = threadIdx.x;
                // The depth statistic is loaded by the threads that use it, and used only after
                // the relaxation: a load that a barrier waits for would delay every visit.
                unsigned d = k < 8 ? __ldcg(depth + tile) + 1 : 0u;
                int g_focus = k < 8 && focus >= 0 ? __ldcg(g + focus) : INF;
                unsigned bits = relax_tile(G, tile, g, blocked, gs, bs, s_stats, s_emin);
                PROF_NOW(v0);
                if (k < 8 && (bits & (1u << k))) {
                    int n = tile_across(G, tile, k);
                    if (n >= 0 && focus >= 0 && s_emin[k] + tile_h(G, n, fy, fx) > g_focus) {
                        atomicMin(lb + n, s_emin[k]);  // read by the next call, after barriers
                        deferred[n] = 1u;
                    } else if (n >= 0) {
                        atomicMax(depth + n, d);
                        PROF_FLAG_TIME(flag_time, n);
                        flag_tile(dirty, work, n, true);  // after the tile's g and the depth
                    }
                }
                mark_exits_stale(G, tile, bits, k - 32, stale);
                if (threadIdx.x == 0) {
                    ++visits;
                    longest = max(longest, d);
                }
                __syncthreads();  // shared tile buffers are reused by the next tile
                PROF_NOW(v1);
                PROF_ADD(PF_R_FLAG, v1 - v0);
                PROF_ADD(PF_R_VISITS, 1);
            }
            PROF_QUEUED(queued);
            if (count && threadIdx.x == 0) PROF_RELAX_END(ctrl);
            // The flags this block set are counted before the ones it took are uncounted.
            if (count && threadIdx.x == 0) atomicSub(work, s_taken);
            visited += count;
        }
        if (visited) {
            idle = 0;
            continue;
        }
        // No flag of ours was set; a work count of 0, read in the same pass, means none will
        // be: nothing is flagged anywhere and no visit is under way to flag one. (The next
        // write of s_work comes after the first barrier of the next pass.)
        if (s_work == 0u) break;
        if (++idle == IDLE_LIMIT) __trap();  // a lost flag would otherwise hang the daemon
    }
    PROF_RELAX_EXIT();
    if (threadIdx.x == 0) {  // settle_tile's thread 0 counted into s_stats
        atomicMax(ctrl + C_LONGEST, longest);
        atomicAdd(ctrl + C_TILES, visits);
        atomicAdd(ctrl + C_SWEEPS, s_stats[0]);
        atomicAdd(ctrl + C_CHANGED, s_stats[C_CHANGED - C_SWEEPS]);
    }
}

// params of a call: PARAM_* words, then the delta from PARAMS. io (host-mapped): the ctrl
// words 0 .. IO_DONE - 1 copied at the end, io[IO_DONE] = seq when the call is complete, the
// path from IO_PATH (count, status, then row and column of each cell).

// The planning call, run by every block once per request of the resident loop (plan_users,
// resident.cuh).
//   MODE_DSS: apply the delta to `blocked`, g = INF everywhere, relax from the goal.
//   MODE_EDS: apply the delta; raise the cells whose cost must rise (raise_tile)
//   (newly blocked cells first); reset them to INF; relax from them and newly freed cells.
//   Past `limit` raised cells: the cells the change cannot reach keep their g, the others
//   take INF, and the relaxation goes on from there (keep_below_change, cut_over.cuh).
//   focus >= 0 (EDS): the relaxation is focused on that cell (see the header).
//   start >= 0: then the path from start into io + IO_PATH (path_exits.cuh).
// params: device memory, the PARAM_* words; delta[i] = cell * 2 + new_blocked,
// in device memory, read with ld.cv (the resident loop rewrites it between calls: never an
// L1 copy from an earlier call).
// flags: 7 * ntiles (ping, pong, seeds, stale, depth, deferred, lb). *bar: thread 0's barrier target.
// Not inlined: inside the resident loop the inlined body spilled 160 bytes a thread (ptxas -v)
// and the relaxation ran 20 % slower.
__device__ __noinline__ void plan_call(int* g, unsigned char* blocked, unsigned char* raised,
                          const int* params, const int* delta, unsigned* flags, unsigned* ctrl,
                          int h, int w, int2* exits, int4* segs, int* io, int cap,
                          unsigned limit, unsigned* bar_ptr) {
    __shared__ __align__(16) int gs[HT][HT];  // aligned: walk_segments stores int2 pairs in it
    __shared__ unsigned char bs[TILE][TILE + 1];
    __shared__ unsigned char rs[HT][HT];
    __shared__ int gs2[HT][HT];  // the second tile of tile_exits' pairs
    __shared__ int s_list[THREADS];
    __shared__ int s_n;
    __shared__ int s_params[PARAM_USED];
    __shared__ unsigned s_raised;  // EDS: the cells raised so far (round_pending)
    Grid G;
    G.h = h; G.w = w;
    G.tiles_x = (w + TILE - 1) / TILE;
    G.tiles_y = (h + TILE - 1) / TILE;
    G.ntiles = G.tiles_x * G.tiles_y;
    unsigned* ping = flags;
    unsigned* pong = flags + G.ntiles;
    unsigned* seeds = flags + 2 * G.ntiles;
    unsigned* stale = flags + 3 * G.ntiles;
    unsigned* depth = flags + 4 * G.ntiles;
    unsigned* deferred = flags + 5 * G.ntiles;
    int* lb = (int*)(flags + 6 * G.ntiles);
    int tid = GBLOCK * THREADS + threadIdx.x, stride = GSIZE * THREADS;
    if (threadIdx.x < PARAM_USED) s_params[threadIdx.x] = __ldcg(params + threadIdx.x);
    if (threadIdx.x == 0) s_raised = 0;
    PROF_START();
    __syncthreads();
    const int ndelta = s_params[PARAM_NDELTA], mode = s_params[PARAM_MODE];
    const int start = s_params[PARAM_START], goal = s_params[PARAM_GOAL];
    // DSS is never focused: its field is exact after every call.
    const int focus = mode == MODE_DSS ? -1 : s_params[PARAM_FOCUS];
    const int fy = focus >= 0 ? focus / w : -1, fx = focus >= 0 ? focus % w : 0;
    int* out = io + IO_PATH;
    G.goal = goal;
    unsigned bar = *bar_ptr;
    stamp(ctrl, 0);

    // Round 0: the delta, the seeds of the first phase. (The counters and depth were zeroed
    // by the last call's last block, or at allocation: no barrier needed first.)
    unsigned* cnt1 = ctrl + C_CNT + 1;
    if (mode == MODE_DSS) {
        for (int i = tid; i < ndelta; i += stride) {
            int code = __ldcv(delta + i);
            blocked[code >> 1] = code & 1;
        }
        for (int i = tid; i < h * w; i += stride) g[i] = INF;
        for (int i = tid; i < G.ntiles; i += stride) {
            stale[i] = 1u;
            deferred[i] = 0u;
            lb[i] = INF;
        }
        if (tid == 0 && goal >= 0) flag_tile(pong, cnt1, tile_of(goal, w, G.tiles_x));
    } else {
        // Warp by warp, so that the flags are set once per distinct tile: a delta of 30,000
        // cells (a 3 m sweep at 2000²) flagged 9 tiles a cell, two atomics each, most of them
        // on one count, and spent ~200 µs here (scripts/profile_cuda_phases.py); a warp's cells lie mostly in
        // one tile.
        unsigned mine = 0, flagged = 0;  // mine: newly blocked cells, raised and counted
        const int lane = threadIdx.x & 31;
        for (int base = tid - lane; base < ndelta; base += stride) {
            int i = base + lane;
            int near[4] = {-1, -1, -1, -1};  // the tiles of a newly blocked cell's 3 x 3
            int seed = -1;
            if (i < ndelta) {
                int code = __ldcv(delta + i);
                int cell = code >> 1;
                unsigned char now = code & 1;
                if (__ldcg(blocked + cell) != now) {
                    blocked[cell] = now;
                    int cy = cell / w, cx = cell % w;
                    seed = (cy / TILE) * G.tiles_x + cx / TILE;
                    if (now) {
                        // Its children may lie in the tiles around: each of those looks at it.
                        raised[cell] = 1;
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
            // One flag per distinct tile of the warp (the raise round reads only whether a
            // tile is flagged, and the count only whether it is 0).
#pragma unroll
            for (int k = 0; k < 4; ++k) {
                unsigned same = __match_any_sync(FULL, near[k]);
                if (near[k] >= 0 && lane == __ffs(same) - 1) {
                    atomicAdd(pong + near[k], 1u);
                    ++flagged;
                }
            }
            unsigned same = __match_any_sync(FULL, seed);
            if (seed >= 0 && lane == __ffs(same) - 1 && !__ldcg(seeds + seed)) seeds[seed] = 1u;
        }
        mine = __reduce_add_sync(FULL, mine);
        flagged = __reduce_add_sync(FULL, flagged);
        if (lane == 0 && flagged) atomicAdd(cnt1, flagged);
        if (lane == 0 && mine) count_raised(ctrl, mine, 0);
    }
    grid_barrier(ctrl, &bar);
    stamp(ctrl, 1);
    unsigned pending = round_pending(ctrl, 0, limit, &s_raised);
    int r = 1;
    if (mode == MODE_DSS) stamp(ctrl, 2);
    if (mode == MODE_EDS) {
        while (pending && !(pending & CUT_PENDING)) {
            pending = run_round(G, OP_RAISE, (r & 1) ? pong : ping, (r & 1) ? ping : pong, seeds, stale,
                                ctrl, r, g, blocked, raised, gs, bs, rs, s_list, &s_n, &bar, limit,
                                &s_raised);
            ++r;
        }
        stamp(ctrl, 2);
        if (pending & CUT_PENDING) {
            keep_below_change(G, g, raised, delta, ndelta, (r & 1) ? pong : ping,
                              (r & 1) ? ping : pong, ctrl + C_CNT + (r + 1) % 3, seeds, stale,
                              deferred, lb, ctrl, &bar);
        } else {
            // The focus's g after the reset: the raise is over (its last barrier) and the
            // reset round lowers nothing. Both words at once (one round trip, not two); g is
            // read even where the focus was raised, and then not used.
            int g_focus = INF;
            if (focus >= 0) {
                const unsigned char focus_raised = __ldcg(raised + focus);
                const int g_old = __ldcg(g + focus);
                if (!focus_raised) g_focus = g_old;
            }
            pending = run_round(G, OP_RESET, seeds, (r & 1) ? ping : pong, seeds, stale, ctrl, r,
                                g, blocked, raised, gs, bs, rs, s_list, &s_n, &bar, limit,
                                nullptr, deferred, lb, g_focus, fy, fx);
        }
        ++r;
    }
    // The flags and the count the last round filled: (r & 1) ? pong : ping, C_CNT + r % 3.
    // Every block enters, even with nothing pending: a block that is late to read `pending`
    // may find the count already changed by the others' visits.
    (void)pending;
    stamp(ctrl, 3);
    relax_async(G, (r & 1) ? pong : ping, ctrl + C_CNT + r % 3, depth, stale, ctrl, g, blocked, gs,
                bs, s_list, &s_n, focus, fy, fx, deferred, lb);
    grid_barrier(ctrl, &bar);
    stamp(ctrl, 4);
    if (start >= 0) {
        // The path: exits of the stale tiles and of the start's, the hops, the segments.
        unsigned char(*code)[TILE] = (unsigned char(*)[TILE]) & rs[0][0];
        unsigned char(*code2)[TILE] = (unsigned char(*)[TILE]) & bs[0][0];  // 1056 >= 1024 bytes
        int start_tile = tile_of(start, w, G.tiles_x);
        if (threadIdx.x == 0 && start_tile % GSIZE == GBLOCK) stale[start_tile] = 1u;
        for (int base = GBLOCK; base < G.ntiles; base += GSIZE * THREADS) {
            int count = take_flagged(stale, G.ntiles, base, s_list, &s_n);
            // Two tiles at a time, one in each half of the block: a block that owns two
            // stale tiles (37 at 400²) would otherwise make the phase twice as long.
            for (int i = 0; i + 1 < count; i += 2) {
                const int half = threadIdx.x >= THREADS / 2 ? 1 : 0;
                tile_exits(g, h, w, s_list[i + half], start, exits, ctrl, half ? gs2 : gs,
                           half ? code2 : code, threadIdx.x - half * (THREADS / 2), THREADS / 2);
            }
            if (count & 1) tile_exits(g, h, w, s_list[count - 1], start, exits, ctrl, gs, code);
            if (count && threadIdx.x == 0) atomicAdd(ctrl + C_EXITS, (unsigned)count);
        }
        grid_barrier(ctrl, &bar);
        stamp(ctrl, 5);
        if (tid == 0) hop_segments(g, w, start, exits, segs, out, cap, ctrl);
        grid_barrier(ctrl, &bar);
        stamp(ctrl, 6);
        walk_segments(g, h, w, segs, out, ctrl, gs, code);
    } else {
        stamp(ctrl, 5);
        stamp(ctrl, 6);
    }
    // The result to the host: the last block in copies the ctrl words (statistics, stamps),
    // zeroes the counters and depth for the next call and, after everything it and every
    // other block wrote, sets the done word.
    PROF_FLUSH(ctrl, bar);
    if (grid_arrive_last(ctrl, &bar)) {
        if (threadIdx.x == 0) ctrl[C_STAMP + 7] = (unsigned)global_ns();
        __syncthreads();
        // C_ROUNDS goes out with the relaxation's longest chain added: summed here by the
        // thread that copies it, rather than by block 0 on its way into the path's phases.
        if (threadIdx.x < IO_DONE) {
            unsigned v = __ldcg(ctrl + threadIdx.x);
            if (threadIdx.x == C_ROUNDS) v += __ldcg(ctrl + C_LONGEST);
            io[threadIdx.x] = (int)v;
        }
        __syncthreads();  // every word is copied before it is zeroed
        PROF_ZERO(ctrl);
        if (threadIdx.x == 0) {
            for (int i = 0; i < 3; ++i) ctrl[C_CNT + i] = ctrl[C_RAISE_RING + i] = 0;
            ctrl[C_EXITS] = 0;
            ctrl[C_CUT] = 0;
            ctrl[C_KEEP] = 0;
            for (int i = C_ROUNDS; i <= C_LONGEST; ++i) ctrl[i] = 0;
            ctrl[C_BASE] = bar;
        }
        for (int i = threadIdx.x; i < G.ntiles; i += THREADS) depth[i] = 0;
        // One fence, thread 0's after the barrier, orders every thread's writes above before
        // the done word (fences are cumulative over the block's barrier).
        __syncthreads();
        if (threadIdx.x == 0) {
            __threadfence_system();
            ((volatile int*)io)[IO_DONE] = s_params[PARAM_SEQ];
        }
    }
    if (threadIdx.x == 0) *bar_ptr = bar;  // thread 0's target is the block's
}


#include "resident.cuh"
