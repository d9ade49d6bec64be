// The EDS cut-over that keeps what the change cannot touch (included by fast.cu).
//
// When the raise passes its limit the repair is given up (fast.cu). Planning from the goal
// again would recompute the whole field; but every cell whose old g lies below the least g the
// change can give or take away keeps its g, so the relaxation starts from that level instead:
// LPA*'s rule (Koenig and Likhachev 2002: a cell whose g is below the least key of the
// inconsistent cells is final), with the changed cells' keys bounded from the old field.
//
// The rule. Moves go to the 8 neighbours at STRAIGHT or DIAGONAL, into and out of free cells
// only, so a changed cell x changes only the edges between x and its 8 neighbours. Let
//   level = min( min over newly blocked x of g(x),
//                min over freed x and every neighbour n of x of g(n) + STRAIGHT,
//                min over deferred tiles t of lb[t] ).
// (1) The old field: g is an upper bound everywhere, and a cell v with g(v) > g*(v) has
// g*(v) >= lb of some deferred tile (walk v's true shortest path towards the goal to the last
// cell u whose g is too high: u is inconsistent with the next cell w, exact, so w was lowered
// after u's tile last read it, which deferred that tile with lb <= g(w) <= g*(v); a tile that
// was flagged instead would have been visited). So every g below level is the old g*, and
// every old g* >= level where g >= level.
// (2) Blocking: a cell v with old g*(v) < level has a shortest old path whose cells all have
// g* <= g*(v) < level <= g*(x) for every newly blocked x, so it avoids them: it still exists.
// Freeing: a new path through a freed x leaves x (the last changed edge on it is x -> n, n a
// neighbour), so it costs at least STRAIGHT + g*(n) >= level; costs of paths avoiding the
// change did not move. Hence new g*(v) = old g(v) for every v with g(v) < level, exactly.
// (3) The cells at or above level take INF; the tiles that held one, and the tiles of the
// changed cells, are flagged. No other cell is inconsistent: a kept cell is exact, and a cell
// that already held INF with a finite kept neighbour would be unreachable across an unchanged
// edge from a cell below level, impossible by (1), or across a changed edge, whose ends both
// lie next to a changed cell and so at or above level. The relaxation (fast.cu) then finds
// the exact field from any flagged field of upper bounds, focused or not, and the deferrals
// are all dropped (their pending values were at or above lb >= level: reset).
//
// On a walk the change lies ahead of the user, away from the goal, so the cells between the
// goal and the change keep their g and the wave starts next to the change.
#pragma once
#include "rounds.cuh"

// Every block of the call's group, after the raise round that passed the limit. delta/ndelta:
// the call's delta (cell * 2 + blocked). left: the flags the last raise round left; dirty, cnt:
// the flags the relaxation takes and their count (zero); seeds: the tiles of the changed
// cells; stale, deferred, lb: the path exits' and the focused repair's per-tile words. Two
// group barriers: the level, then the reset.
__device__ void keep_below_change(const Grid& G, int* g, unsigned char* raised, const int* delta,
                                  int ndelta, unsigned* left, unsigned* dirty, unsigned* cnt,
                                  unsigned* seeds, unsigned* stale, unsigned* deferred, int* lb,
                                  unsigned* ctrl, unsigned* bar) {
    const int tid = GBLOCK * THREADS + threadIdx.x, stride = GSIZE * THREADS;
    int low = INF;
    for (int i = tid; i < ndelta; i += stride) {
        int code = __ldcv(delta + i);
        int cell = code >> 1;
        if (code & 1) {
            low = min(low, __ldcg(g + cell));
            continue;
        }
        int cy = cell / G.w, cx = cell % G.w;
#pragma unroll
        for (int k = 0; k < 8; ++k) {
            int ny = cy + NB_DR[k], nx = cx + NB_DC[k];
            if (ny >= 0 && nx >= 0 && ny < G.h && nx < G.w)
                low = min(low, __ldcg(g + ny * G.w + nx) + STRAIGHT);
        }
    }
    for (int t = tid; t < G.ntiles; t += stride) {
        const unsigned is_deferred = __ldcg(deferred + t);
        const int bound = __ldcg(lb + t);  // with the flag: one round trip, not two
        if (is_deferred) low = min(low, bound);
    }
    // One atomic a warp; stored as INF - level so that the zero the word starts with means
    // "no bound" and a max keeps the least level.
    low = __reduce_min_sync(FULL, low);
    if ((threadIdx.x & 31) == 0 && low < INF) atomicMax(ctrl + C_KEEP, (unsigned)(INF - low));
    grid_barrier(ctrl, bar);

    const int level = INF - (int)__ldcg(ctrl + C_KEEP);
    for (int t = GBLOCK; t < G.ntiles; t += GSIZE) {
        const TileCell c = tile_cell(G, t);
        bool reset = false;
        if (c.inside) {
            raised[c.idx] = 0;
            int v = __ldcg(g + c.idx);
            if (v >= level && v < INF) {
                __stcg(g + c.idx, INF);
                reset = true;
            }
        }
        int any = __syncthreads_or(reset);
        if (threadIdx.x == 0) {
            if (any || __ldcg(seeds + t)) flag_tile(dirty, cnt, t);
            left[t] = 0u;
            seeds[t] = 0u;
            stale[t] = 1u;  // the path's exits: every tile again, as after a plan from scratch
            deferred[t] = 0u;
            lb[t] = INF;
        }
    }
    if (tid == 0) {
        ctrl[C_CUT] = __ldcg(ctrl + C_RAISED);  // every raise counted before the first barrier
        ctrl[C_RAISED] = 0u;
        ctrl[C_ROUNDS] += 2;
    }
    grid_barrier(ctrl, bar);
}
