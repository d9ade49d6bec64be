// One 32 x 32 tile of the fast planner (fast.cu): load it with its halo into shared memory,
// relax it until it settles, raise the cells whose cost must rise, reset raised cells.
// Every function is called by a whole block of THREADS == TILE * TILE threads, thread
// (y, x) = (threadIdx.x / 32, threadIdx.x % 32) owning one cell.
#pragma once
#include "grid_sync.cuh"
#include "tile.cuh"

#define CHANGED_ANY 256u  // with the edge bits N S W E NW NE SW SE: some cell of the tile changed



// Tile offsets for the edge bits N S W E NW NE SW SE.
__constant__ int EDGE_DY[8] = {-1, 1, 0, 0, -1, -1, 1, 1};
__constant__ int EDGE_DX[8] = {0, 0, -1, 1, -1, 1, -1, 1};

struct Grid {
    int h, w, tiles_x, tiles_y, ntiles, goal;
};

// The tile across edge/corner k of tile t (k: N S W E NW NE SW SE), or -1 off the map.
__device__ __forceinline__ int tile_across(const Grid& G, int t, int k) {
    int ny = t / G.tiles_x + EDGE_DY[k], nx = t % G.tiles_x + EDGE_DX[k];
    if (ny < 0 || nx < 0 || ny >= G.tiles_y || nx >= G.tiles_x) return -1;
    return ny * G.tiles_x + nx;
}

// Thread k < 8 flags the tile across edge/corner k if that bit is set.
__device__ void flag_neighbour(const Grid& G, int t, unsigned bits, int k, unsigned* next,
                               unsigned* cnt) {
    if (k < 0 || k >= 8 || !(bits & (1u << k))) return;
    int n = tile_across(G, t, k);
    if (n >= 0) flag_tile(next, cnt, n);
}

// Thread k <= 8 marks stale the path exits (path_exits.cuh) that read changed cells: of the
// tile across each changed edge/corner k < 8, and (k == 8) of t itself if any cell changed.
__device__ void mark_exits_stale(const Grid& G, int t, unsigned bits, int k, unsigned* stale) {
    if (k == 8 && (bits & CHANGED_ANY)) stale[t] = 1u;
    if (k < 0 || k >= 8 || !(bits & (1u << k))) return;
    int n = tile_across(G, t, k);
    if (n >= 0) stale[n] = 1u;
}

// Which edge/corner bits a tile cell (y, x) sits on.
__device__ __forceinline__ unsigned edge_bits(int y, int x) {
    unsigned b = 0;
    if (y == 0) b |= 1u;
    if (y == TILE - 1) b |= 2u;
    if (x == 0) b |= 4u;
    if (x == TILE - 1) b |= 8u;
    if (y == 0 && x == 0) b |= 16u;
    if (y == 0 && x == TILE - 1) b |= 32u;
    if (y == TILE - 1 && x == 0) b |= 64u;
    if (y == TILE - 1 && x == TILE - 1) b |= 128u;
    return b;
}

// This thread's cell of tile t: the tile's origin (oy, ox), the cell in the tile (y, x), its
// index in the map and whether it lies inside the map (edge tiles hang over).
struct TileCell {
    int oy, ox, y, x, idx;
    bool inside;
};

__device__ __forceinline__ TileCell tile_cell(const Grid& G, int t) {
    TileCell c;
    c.oy = (t / G.tiles_x) * TILE;
    c.ox = (t % G.tiles_x) * TILE;
    c.y = threadIdx.x >> 5;
    c.x = threadIdx.x & 31;
    c.inside = c.oy + c.y < G.h && c.ox + c.x < G.w;
    c.idx = (c.oy + c.y) * G.w + c.ox + c.x;
    return c;
}

// g at halo-tile index i (sy = i / HT, sx = i % HT) of the tile at (oy, ox); INF outside.
__device__ __forceinline__ int halo_g(const Grid& G, const int* g, int oy, int ox, int i) {
    int y = oy + i / HT - 1, x = ox + i % HT - 1;
    return (y >= 0 && x >= 0 && y < G.h && x < G.w) ? __ldcg(g + y * G.w + x) : INF;
}

// The raised byte at halo-tile index i of the tile at (oy, ox); 0 outside.
__device__ __forceinline__ unsigned char halo_raised(const Grid& G, const unsigned char* raised,
                                                     int oy, int ox, int i) {
    int y = oy + i / HT - 1, x = ox + i % HT - 1;
    return (y >= 0 && x >= 0 && y < G.h && x < G.w) ? __ldcg(raised + y * G.w + x) : 0;
}

// Load g of the tile and its halo into gs (cells outside the map read INF). HT * HT = 1156
// cells for 1024 threads: both loads of a thread are issued before either is stored, so a
// visit waits for one L2 round trip here, not two.
__device__ void load_tile_g(const Grid& G, const int* g, int oy, int ox, int (*gs)[HT]) {
    static_assert(HT * HT <= 2 * THREADS, "two cells per thread");
    const int i0 = threadIdx.x, i1 = threadIdx.x + THREADS;
    int v0 = halo_g(G, g, oy, ox, i0);
    int v1 = i1 < HT * HT ? halo_g(G, g, oy, ox, i1) : INF;
    gs[i0 / HT][i0 % HT] = v0;
    if (i1 < HT * HT) gs[i1 / HT][i1 % HT] = v1;
}

#include "tile_scans.cuh"

// Relax the tile held in gs (its g and halo; bs: 1 for blocked cells and cells outside the
// map, the caller's barrier after filling both) until it settles, then store the cells that
// changed into g. Returns the edge bits of cells that changed, and CHANGED_ANY if any did;
// emin[k] (shared) is the least new g on edge/corner k, INF where none changed: every value
// the tile across k can take from this change is above it (the focused repair's bound, fast.cu).
__device__ unsigned settle_tile(const Grid& G, const TileCell& c, int* g, int (*gs)[HT],
                                unsigned char (*bs)[TILE + 1], unsigned* sweeps, int* emin) {
    __shared__ unsigned s_bits;
    PROF_NOW(a);
    const int y = c.y, x = c.x;
    const bool blk = bs[y][x] != 0;
    const bool is_goal = c.inside && c.idx == G.goal;
    if (threadIdx.x == 0) s_bits = 0;
    if (threadIdx.x < 8) emin[threadIdx.x] = INF;
    int before = gs[y + 1][x + 1];
    if (is_goal && !blk) gs[y + 1][x + 1] = 0;
    __syncthreads();
    // A Jacobi pass over the 8 neighbours, then the scans, until a Jacobi pass changes
    // nothing: that alone proves the tile settled (each scan only chains relations that the
    // Jacobi pass checks), so the last, confirming pass costs no scans. About half the visits
    // change nothing in their first pass: they never work out their segments.
    unsigned seg[4] = {0, 0, 0, 0};
    unsigned n = 0;
    while (true) {
        bool ch = false;
        if (!blk && !is_goal) {
            int cur = gs[y + 1][x + 1];
            int best = cur;
#pragma unroll
            for (int k = 0; k < 8; ++k) best = min(best, gs[y + 1 + NB_DR[k]][x + 1 + NB_DC[k]] + NB_COST[k]);
            if (best < cur) {
                gs[y + 1][x + 1] = best;
                ch = true;
            }
        }
        ++n;
        if (!__syncthreads_or(ch)) break;
        if (n == 1) {
#pragma unroll
            for (int d = 0; d < 4; ++d) seg[d] = line_segments(d, bs);
        }
        scan_line(0, seg[0], gs);
        __syncthreads();
        scan_line(1, seg[1], gs);
        __syncthreads();
        scan_line(2, seg[2], gs);
        __syncthreads();
        scan_line(3, seg[3], gs);
        __syncthreads();
    }
    PROF_NOW(b);
    PROF_ADD(PF_R_SETTLE, b - a);
    int after = gs[y + 1][x + 1];
    bool changed = c.inside && after != before;
    if (changed) {
        // Made visible to other blocks by the fence of whichever thread flags a neighbour
        // after the barrier below (fences are cumulative over the block's barrier).
        __stcg(g + c.idx, after);
        unsigned e = edge_bits(y, x);
        atomicOr(&s_bits, e | CHANGED_ANY);
        for (; e; e &= e - 1) atomicMin(emin + __ffs(e) - 1, after);
    }
    unsigned total = __syncthreads_count(changed);
    if (threadIdx.x == 0) {
        atomicAdd(sweeps, n);
        atomicAdd(sweeps + (C_CHANGED - C_SWEEPS), total);
    }
    PROF_NOW(e);
    PROF_ADD(PF_R_STORE, e - b);
    return s_bits;
}

// Load tile t and its halo into gs and bs, and settle it (settle_tile).
__device__ unsigned relax_tile(const Grid& G, int t, int* g, const unsigned char* blocked,
                               int (*gs)[HT], unsigned char (*bs)[TILE + 1], unsigned* sweeps,
                               int* emin) {
    PROF_NOW(a);
    const TileCell c = tile_cell(G, t);
    bool blk = !c.inside || __ldcg(blocked + c.idx) != 0;
    load_tile_g(G, g, c.oy, c.ox, gs);
    bs[c.y][c.x] = blk ? 1 : 0;
    __syncthreads();
    PROF_NOW(b);
    PROF_ADD(PF_R_LOAD, b - a);
    return settle_tile(G, c, g, gs, bs, sweeps, emin);
}

// EDS step 1, one tile: a cell is raised when every neighbour that supports its g (g[n] + c
// <= g[v] in the unchanged old field) is raised or newly blocked. In a settled field the
// supports are the tight neighbours (==) and the raised cells exactly those whose cost must
// rise (the CPU's rule), fewer than the whole pred subtree. Where a focused repair left tiles
// unsettled (fast.cu), a cell may hold more than a lowered neighbour's g + c: that neighbour
// still proves its g an upper bound (the cost of a real path), so it counts as a support.
// Returns the edge bits of newly raised cells; *any_raised tells whether the tile holds one,
// *fresh how many it raised in this visit.
//
// The fixpoint runs on bit masks, one warp alone: lane y holds row y's raised cells as bits
// (with its halo columns: bit j is halo column j) and, per direction, which cells that
// neighbour supports; one Jacobi pass is two shuffles and eight bit operations. A raise
// moves one cell a pass (a shadow 32 cells deep takes 32 passes): block-wide, each pass was
// nine shared loads in each of 32 warps and a block barrier. The least fixpoint of a
// monotone rule is the same whatever the passes' form, so the raised set is the old one.
__device__ unsigned raise_tile(const Grid& G, int t, const int* g, unsigned char* raised,
                               int (*gs)[HT], unsigned char (*rs)[HT], unsigned* sweeps,
                               bool* any_raised, unsigned* fresh) {
    __shared__ unsigned s_bits, s_passes;
    __shared__ int s_any;
    // s_tight[(dr + 1) * 3 + dc + 1][y]: bit x set when neighbour (dr, dc) supports (y, x);
    // s_rows[y]: row y's cells that may rise, then its raised cells.
    __shared__ unsigned s_tight[9][TILE], s_rows[TILE], s_was[TILE];
    PROF_NOW(a);
    const TileCell c = tile_cell(G, t);
    const int oy = c.oy, ox = c.ox, y = c.y, x = c.x, idx = c.idx;
    const bool inside = c.inside;
    if (threadIdx.x == 0) { s_bits = 0; s_any = 0; }
    {
        // The tile's g and raised bytes with their halo, two cells a thread (HT * HT = 1156
        // for 1024 threads): all four loads issued before any store, so the visit waits for
        // one L2 round trip. As load_tile_g then a loop over the bytes, ptxas stored each
        // value before it issued the next load (sm_90 SASS): four round trips one behind
        // another for the threads that hold two cells, on every raise visit's path.
        const int i0 = threadIdx.x, i1 = threadIdx.x + THREADS;
        const bool two = i1 < HT * HT;
        const int g0 = halo_g(G, g, oy, ox, i0), g1 = two ? halo_g(G, g, oy, ox, i1) : INF;
        const unsigned char r0 = halo_raised(G, raised, oy, ox, i0);
        const unsigned char r1 = two ? halo_raised(G, raised, oy, ox, i1) : 0;
        gs[i0 / HT][i0 % HT] = g0;
        rs[i0 / HT][i0 % HT] = r0;
        if (two) {
            gs[i1 / HT][i1 % HT] = g1;
            rs[i1 / HT][i1 % HT] = r1;
        }
    }
    __syncthreads();
    PROF_NOW(b);
    PROF_ADD(PF_A_LOAD, b - a);
    int gv = gs[y + 1][x + 1];
    unsigned tight = 0;  // bit k: neighbour k supports g (the goal has none and never rises)
    if (inside && gv > 0 && gv < INF) {
#pragma unroll
        for (int k = 0; k < 8; ++k)
            if (gs[y + 1 + NB_DR[k]][x + 1 + NB_DC[k]] + NB_COST[k] <= gv) tight |= 1u << k;
    }
    const bool was = rs[y + 1][x + 1] != 0;
    // Warp y is row y, lane x its cell x.
#pragma unroll
    for (int k = 0; k < 8; ++k) {
        unsigned m = __ballot_sync(FULL, (tight >> k) & 1u);
        if (x == 0) s_tight[(NB_DR[k] + 1) * 3 + NB_DC[k] + 1][y] = m;
    }
    unsigned may = __ballot_sync(FULL, tight && !was), had = __ballot_sync(FULL, was);
    if (x == 0) {
        s_rows[y] = may;
        s_was[y] = had;
    }
    __syncthreads();
    if (y == 0) {
        const int row = x;  // lane x of warp 0 takes tile row x
        unsigned tk[9];
#pragma unroll
        for (int j = 0; j < 9; ++j) tk[j] = j == 4 ? 0u : s_tight[j][row];
        const unsigned may_rise = s_rows[row];
        unsigned r = s_was[row];
        typedef unsigned long long u64;
        // Halo columns 0 and 33 of this row, and the halo rows above and below: fixed here.
        const u64 sides = (u64)(rs[row + 1][0] != 0) | ((u64)(rs[row + 1][HT - 1] != 0) << (HT - 1));
        const u64 top = __ballot_sync(FULL, rs[0][x] != 0) | ((u64)(rs[0][TILE] != 0) << TILE) |
                        ((u64)(rs[0][TILE + 1] != 0) << (TILE + 1));
        const u64 bottom = __ballot_sync(FULL, rs[HT - 1][x] != 0) |
                           ((u64)(rs[HT - 1][TILE] != 0) << TILE) |
                           ((u64)(rs[HT - 1][TILE + 1] != 0) << (TILE + 1));
        unsigned passes = 0;
        while (true) {
            const u64 mid = sides | ((u64)r << 1);
            u64 up = __shfl_up_sync(FULL, mid, 1), down = __shfl_down_sync(FULL, mid, 1);
            if (row == 0) up = top;
            if (row == TILE - 1) down = bottom;
            unsigned rise = may_rise & ~r;
            // Neighbour (dr, dc) of cell x is halo column x + dc + 1 of its row.
#pragma unroll
            for (int dr = -1; dr <= 1; ++dr) {
#pragma unroll
                for (int dc = -1; dc <= 1; ++dc) {
                    const u64 src = dr < 0 ? up : (dr > 0 ? down : mid);
                    rise &= ~tk[(dr + 1) * 3 + dc + 1] | (unsigned)(src >> (dc + 1));
                }
            }
            ++passes;
            if (!__any_sync(FULL, rise)) break;
            r |= rise;
        }
        s_rows[row] = r;
        if (row == 0) s_passes = passes;
    }
    __syncthreads();
    PROF_NOW(f);
    PROF_ADD(PF_A_FIX, f - b);
    bool now = (s_rows[y] >> x) & 1u;
    bool newly = inside && now && !was;
    if (newly) {
        raised[idx] = 1;
        atomicOr(&s_bits, edge_bits(y, x));
    }
    if (inside && now) s_any = 1;
    *fresh = __syncthreads_count(newly);
    if (threadIdx.x == 0) atomicAdd(sweeps, s_passes);
    *any_raised = s_any != 0;
    return s_bits;
}

// EDS step 2, one tile: raised cells take INF and are cleared (they were counted as they
// were raised). Returns the edge bits of reset cells and CHANGED_ANY if there were any (their
// exits change).
__device__ unsigned reset_tile(const Grid& G, int t, int* g, unsigned char* raised) {
    __shared__ unsigned s_bits;
    const TileCell c = tile_cell(G, t);
    if (threadIdx.x == 0) s_bits = 0;
    __syncthreads();
    if (c.inside && __ldcg(raised + c.idx)) {
        __stcg(g + c.idx, INF);
        raised[c.idx] = 0;
        atomicOr(&s_bits, edge_bits(c.y, c.x) | CHANGED_ANY);
    }
    __syncthreads();
    return s_bits;
}
