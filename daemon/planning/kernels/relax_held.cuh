// SCHED 2 (included by fast.cu): the asynchronous relaxation with each block's tiles held in
// shared memory for the whole phase, used while a block owns at most HELD_MAX tiles (maps up
// to about 700 x 700 on a 132-SM H100; larger maps take relax_async).
//
// Why: in relax_async a change reaches the next tile through three L2 round trips one after
// another: the visit stores its cells and fences, sets the flag; the neighbour's poll takes
// the flag and fences; it loads the halo. On a 400 x 400 plan that chain is 30 tiles long and
// those trips are most of its time (BENCHMARKS.md). Here a block polls the halo rings of its
// tiles themselves: a ring value lower than the one held is relaxed at once, about one round
// trip after its writer stored it, while the flag is still on its way.
//
// The flags stay, for termination and for whatever an unordered poll may miss. Taking a flag
// (then a fence) only promises that the *next* pass's ring loads see what its setter stored
// before it; so a flag taken in pass p is uncounted from *work at the end of pass p + 1, after
// that pass's loads have been relaxed and its visits have flagged their neighbours. *work then
// keeps relax_async's meaning and stays above 0 while any visit is under way: a visit started
// by a ring value is covered by the flag its writer sets after storing that value (set or
// about to be; taken in this pass or the last; or, if taken earlier, the value was already
// held). So *work == 0 is final, and every ring has been relaxed against its last values.
#pragma once

#define HELD_MAX 4
#define RING (4 * (TILE + 1))  // halo cells around a tile
static_assert(HELD_MAX * RING + HELD_MAX + 1 <= NTHREADS, "one thread per ring cell and flag");

// Halo-tile coordinates (sy, sx) of ring cell i: the top row, the bottom row, the left column,
// the right column.
__device__ __forceinline__ void ring_cell(int i, int* sy, int* sx) {
    if (i < HT) {
        *sy = 0; *sx = i;
    } else if (i < 2 * HT) {
        *sy = HT - 1; *sx = i - HT;
    } else if (i < 2 * HT + TILE) {
        *sy = i - 2 * HT + 1; *sx = 0;
    } else {
        *sy = i - 2 * HT - TILE + 1; *sx = HT - 1;
    }
}

// A load of the value last written at p, fresh from L2 on every pass (a plain or .cg load in
// a loop may be merged or kept by the compiler; volatile asm is issued each time).
__device__ __forceinline__ int load_relaxed(const int* p) {
    int v;
    asm volatile("ld.relaxed.gpu.global.b32 %0, [%1];" : "=r"(v) : "l"(p) : "memory");
    return v;
}

// Tiles that block b holds: b, b + gridDim.x, ... below ntiles.
__device__ __forceinline__ int held_count(const Grid& G) {
    return (int)blockIdx.x < G.ntiles ? (G.ntiles - 1 - (int)blockIdx.x) / (int)gridDim.x + 1 : 0;
}

__device__ void relax_held(const Grid& G, unsigned* dirty, unsigned* work,
                                        unsigned* depth, unsigned* stale, unsigned* ctrl, int* g,
                                        const unsigned char* blocked) {
    __shared__ int hg[HELD_MAX][HT][HT];
    __shared__ unsigned char hb[HELD_MAX][TILE][TILE + 1];
    __shared__ int s_visit[HELD_MAX];  // relax held tile j in this pass
    __shared__ unsigned s_took;        // the counts of the flags taken in this pass
    __shared__ unsigned s_work;
    const int k = threadIdx.x, held = held_count(G);
    if (held == 0) return;
    // The tiles as the grid barrier before this phase left them.
    for (int j = 0; j < held; ++j) {
        const TileCell c = tile_cell(G, blockIdx.x + j * gridDim.x);
        hb[j][c.y][c.x] = !c.inside || __ldcg(blocked + c.idx) != 0;
        load_tile_g(G, g, c.oy, c.ox, hg[j]);
    }
    // This thread's ring cell (ring < 0: none, or outside the map) and flag (f < held).
    const int j_ring = k / RING, f = NTHREADS - 1 - k;
    int sy = 0, sx = 0, ring = -1;
    if (j_ring < held) {
        ring_cell(k % RING, &sy, &sx);
        const int t = blockIdx.x + j_ring * gridDim.x;
        const int y = (t / G.tiles_x) * TILE + sy - 1, x = (t % G.tiles_x) * TILE + sx - 1;
        if (y >= 0 && x >= 0 && y < G.h && x < G.w) ring = y * G.w + x;
    }
    unsigned idle = 0, longest = 0;
    unsigned confirming = 0;  // counts taken in the last pass, uncounted at the end of this one
    for (bool first = true;; first = false) {
        __syncthreads();  // the last pass has read s_visit and s_took
        if (k < HELD_MAX) s_visit[k] = 0;
        if (k == 0) s_took = 0;
        __syncthreads();
        // One round trip: the rings, this block's flags, the work count.
        if (ring >= 0) {
            const int v = load_relaxed(g + ring);
            if (v < hg[j_ring][sy][sx]) {
                hg[j_ring][sy][sx] = v;
                s_visit[j_ring] = 1;
            }
        }
        const unsigned count = f < held ? take_flag(dirty, blockIdx.x + f * gridDim.x) : 0u;
        if (count) {
            atomicAdd(&s_took, count);  // the next pass's loads see what the setters stored
            // The flags set before this phase (the goal's tile, the EDS seeds) mark tiles
            // whose own cells changed: relax them once whatever their rings say.
            if (first) s_visit[f] = 1;
        }
        if (k == NTHREADS - 1 - HELD_MAX) s_work = *((volatile unsigned*)work);
        __syncthreads();
        bool visited = false;
        for (int j = 0; j < held; ++j) {
            if (!s_visit[j]) continue;
            visited = true;
            const int tile = blockIdx.x + j * gridDim.x;
            unsigned d = k < 8 ? __ldcg(depth + tile) + 1 : 0u;
            unsigned bits = settle_tile(G, tile, g, hg[j], hb[j], ctrl + C_SWEEPS);
            if (k < 8 && (bits & (1u << k))) {
                int n = tile_across(G, tile, k);
                if (n >= 0) {
                    atomicMax(depth + n, d);
                    flag_tile(dirty, work, n, true);  // after the tile's g and the depth
                }
            }
            mark_exits_stale(G, tile, bits, k - 32, stale);
            if (k == 0) {
                atomicAdd(ctrl + C_TILES, 1u);
                longest = max(longest, d);
            }
            __syncthreads();  // this visit's flags are set before the uncounting below
        }
        const unsigned took = s_took;
        // The flags this pass's visits set are counted before the confirmed ones are uncounted.
        if (k == 0 && confirming) atomicSub(work, confirming);
        const bool busy = visited || took || confirming;
        confirming = took;
        if (busy) {
            idle = 0;
            continue;
        }
        // Nothing held changed, no flag was ours, none awaits confirming: a work count of 0,
        // read in this pass, means no flag is set anywhere and no visit is under way.
        if (s_work == 0u) break;
        if (++idle == IDLE_LIMIT) __trap();  // a lost flag would otherwise hang the daemon
    }
    if (k == 0) atomicMax(ctrl + C_LONGEST, longest);
}
