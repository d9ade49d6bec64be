// The fast CUDA planner: one persistent launch per planning call.
//
// The grid is cut into 32 x 32 tiles. A block loads a tile and its one-cell halo into
// shared memory and relaxes it until it settles; only then does the tile's change reach
// the neighbouring tiles, through a grid-wide barrier. A tile is processed in a round only
// when it is flagged: by the delta, by the goal, or by a neighbour whose border changed.
// So a plan costs ~tens of grid-wide rounds instead of ~hundreds of sweeps, and an EDS
// update touches only the tiles around the change.
//
// Correctness does not depend on the order of relaxation: every value ever written is the
// cost of a real path (an upper bound), values only decrease, and a round ends with every
// processed tile settled against the halo it read; a tile whose halo changed afterwards is
// flagged again. The fixpoint of g[v] = min(g[v], g[n] + c) over that is the exact field.
//
// Host contract (cuda_planner.py): the launch has at most as many blocks as can be resident
// at once (the barrier spins), ctrl[0] == 0 at launch, one launch at a time per device.
//
// SCANS selects the in-tile relaxation (compile-time, -DSCANS=n):
//   0  Jacobi sweeps over the 8 neighbours;
//   1  + min-plus scans along every row and column of the tile;
//   2  + scans along both diagonals, so any straight or diagonal run settles in one sweep.

#ifndef SCANS
#define SCANS 2
#endif

#ifndef MIN_BLOCKS
#define MIN_BLOCKS 1
#endif

#define TILE 32
#define HT (TILE + 2)
#define NTHREADS (TILE * TILE)
#define INF 0x3FFFFFFF
#define BIG 0x7F000000
#define FULL 0xFFFFFFFFu

// ctrl layout (unsigned ints)
#define C_BAR 0       // barrier arrivals since the planner was allocated (wraps)
#define C_CNT 2       // 3 rotating counters of tiles flagged for the next round
#define C_ROUNDS 8    // grid-wide rounds run
#define C_TILES 9     // tiles processed (all phases)
#define C_SWEEPS 10   // in-tile sweeps, summed over processed tiles
#define C_RAISED 11   // cells raised to INF by EDS
#define C_CHANGED 12  // cells whose g the relaxation lowered
#define C_RELEASE 32  // the last arrival count of a completed barrier (own cache line)

// phases (ops)
#define OP_RELAX 0
#define OP_RAISE 1
#define OP_RESET 2

__constant__ int NB_DR[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
__constant__ int NB_DC[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
__constant__ int NB_COST[8] = {14, 10, 14, 10, 10, 14, 10, 14};

// Tile offsets for the edge bits N S W E NW NE SW SE.
__constant__ int EDGE_DY[8] = {-1, 1, 0, 0, -1, -1, 1, 1};
__constant__ int EDGE_DX[8] = {0, 0, -1, 1, -1, 1, -1, 1};

struct Grid {
    int h, w, tiles_x, tiles_y, ntiles, goal;
};

// A barrier over the whole launch. Valid only when every block is resident (host sizes
// the grid from the occupancy). ctrl[C_BAR] counts arrivals and only ever grows (the host
// passes the count the previous launch ended with as `bar_base`), so no reset races the next
// barrier; the last block in publishes the count in ctrl[C_RELEASE], a cache line of its own
// that the waiting blocks read while the arrivals hit the counter.
__device__ void grid_barrier(unsigned* ctrl, unsigned* target) {
    __syncthreads();
    if (threadIdx.x == 0) {
        *target += gridDim.x;
        __threadfence();
        unsigned arrived = atomicAdd(ctrl + C_BAR, 1u) + 1u;
        volatile unsigned* release = ctrl + C_RELEASE;
        if (arrived == *target) {
            *release = arrived;
        } else {
            // Blocks that are not all resident (another process's kernels under MPS, say)
            // would wait here forever; after seconds, trap: a CUDA error the host's CPU
            // fallback turns into a warning instead of a hung daemon.
            unsigned spins = 0;
            while ((int)(*release - *target) < 0) {
                __nanosleep(32);
                if (++spins == (1u << 26)) __trap();
            }
        }
        __threadfence();
    }
    __syncthreads();
}

__device__ __forceinline__ void flag_tile(unsigned* next, unsigned* cnt, int t) {
    if (atomicExch(next + t, 1u) == 0u) atomicAdd(cnt, 1u);
}

// Flag the tile across edge/corner k (bits: N S W E NW NE SW SE) if that bit is set.
__device__ void flag_neighbour(const Grid& G, int t, unsigned bits, int k, unsigned* next,
                               unsigned* cnt) {
    if (k >= 8 || !(bits & (1u << k))) return;
    int ny = t / G.tiles_x + EDGE_DY[k], nx = t % G.tiles_x + EDGE_DX[k];
    if (ny < 0 || nx < 0 || ny >= G.tiles_y || nx >= G.tiles_x) return;
    flag_tile(next, cnt, ny * G.tiles_x + nx);
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

// Load g of the tile and its halo into gs (cells outside the map read INF).
__device__ void load_tile_g(const Grid& G, const int* g, int oy, int ox, int (*gs)[HT]) {
    for (int i = threadIdx.x; i < HT * HT; i += NTHREADS) {
        int sy = i / HT, sx = i % HT;
        int y = oy + sy - 1, x = ox + sx - 1;
        int v = INF;
        if (y >= 0 && x >= 0 && y < G.h && x < G.w) v = __ldcg(g + y * G.w + x);
        gs[sy][sx] = v;
    }
}

#if SCANS >= 1
#include "tile_scans.cuh"
#endif

// Relax one tile until it settles. Returns the edge bits of cells that changed.
__device__ unsigned relax_tile(const Grid& G, int t, int* g, const unsigned char* blocked,
                               int (*gs)[HT], unsigned char (*bs)[TILE + 1], unsigned* sweeps) {
    __shared__ unsigned s_bits;
    int oy = (t / G.tiles_x) * TILE, ox = (t % G.tiles_x) * TILE;
    int y = threadIdx.x >> 5, x = threadIdx.x & 31;
    int gy = oy + y, gx = ox + x;
    bool inside = gy < G.h && gx < G.w;
    int idx = gy * G.w + gx;
    bool blk = !inside || __ldcg(blocked + idx) != 0;
    bool is_goal = inside && idx == G.goal;
    if (threadIdx.x == 0) s_bits = 0;
    load_tile_g(G, g, oy, ox, gs);
    bs[y][x] = blk ? 1 : 0;
    __syncthreads();
    int before = gs[y + 1][x + 1];
    if (is_goal && !blk) gs[y + 1][x + 1] = 0;
    __syncthreads();
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
#if SCANS >= 1
        __syncthreads();
        ch |= scan_lines(0, gs, bs);
        __syncthreads();
        ch |= scan_lines(1, gs, bs);
#endif
#if SCANS >= 2
        __syncthreads();
        ch |= scan_lines(2, gs, bs);
        __syncthreads();
        ch |= scan_lines(3, gs, bs);
#endif
        ++n;
        if (!__syncthreads_or(ch)) break;
    }
    int after = gs[y + 1][x + 1];
    bool changed = inside && after != before;
    if (changed) {
        __stcg(g + idx, after);
        atomicOr(&s_bits, edge_bits(y, x));
    }
    unsigned total = __syncthreads_count(changed);
    if (threadIdx.x == 0) {
        atomicAdd(sweeps, n);
        atomicAdd(sweeps + (C_CHANGED - C_SWEEPS), total);
    }
    return s_bits;
}

// EDS step 1, one tile: a cell is raised when every neighbour that supports its g (a tight
// neighbour, g[n] + c == g[v] in the unchanged old field) is raised or newly blocked. That
// is exactly the set of cells whose cost must rise (the CPU's rule), smaller than the whole
// pred subtree. Returns the edge bits of newly raised cells; *any_raised tells whether the
// tile holds one.
__device__ unsigned raise_tile(const Grid& G, int t, const int* g, unsigned char* raised,
                               int (*gs)[HT], unsigned char (*rs)[HT], unsigned* sweeps,
                               bool* any_raised) {
    __shared__ unsigned s_bits;
    __shared__ int s_any;
    int oy = (t / G.tiles_x) * TILE, ox = (t % G.tiles_x) * TILE;
    int y = threadIdx.x >> 5, x = threadIdx.x & 31;
    int gy = oy + y, gx = ox + x;
    bool inside = gy < G.h && gx < G.w;
    int idx = gy * G.w + gx;
    if (threadIdx.x == 0) { s_bits = 0; s_any = 0; }
    load_tile_g(G, g, oy, ox, gs);
    for (int i = threadIdx.x; i < HT * HT; i += NTHREADS) {
        int sy = i / HT, sx = i % HT;
        int yy = oy + sy - 1, xx = ox + sx - 1;
        unsigned char v = 0;
        if (yy >= 0 && xx >= 0 && yy < G.h && xx < G.w) v = __ldcg(raised + yy * G.w + xx);
        rs[sy][sx] = v;
    }
    __syncthreads();
    int gv = gs[y + 1][x + 1];
    unsigned tight = 0;  // bit k: neighbour k supports g (the goal has none and never rises)
    if (inside && gv > 0 && gv < INF) {
#pragma unroll
        for (int k = 0; k < 8; ++k)
            if (gs[y + 1 + NB_DR[k]][x + 1 + NB_DC[k]] + NB_COST[k] == gv) tight |= 1u << k;
    }
    bool was = rs[y + 1][x + 1] != 0;
    unsigned n = 0;
    while (true) {
        bool ch = false;
        if (tight && !rs[y + 1][x + 1]) {
            bool all = true;
#pragma unroll
            for (int k = 0; k < 8; ++k)
                if ((tight >> k) & 1u) all = all && rs[y + 1 + NB_DR[k]][x + 1 + NB_DC[k]];
            if (all) {
                rs[y + 1][x + 1] = 1;
                ch = true;
            }
        }
        ++n;
        if (!__syncthreads_or(ch)) break;
    }
    bool now = rs[y + 1][x + 1] != 0;
    if (inside && now && !was) {
        raised[idx] = 1;
        atomicOr(&s_bits, edge_bits(y, x));
    }
    if (inside && now) s_any = 1;
    __syncthreads();
    if (threadIdx.x == 0) atomicAdd(sweeps, n);
    *any_raised = s_any != 0;
    return s_bits;
}

// EDS step 2, one tile: raised cells take INF and are cleared; the tile is flagged to relax.
__device__ void reset_tile(const Grid& G, int t, int* g, unsigned char* raised, unsigned* count) {
    int oy = (t / G.tiles_x) * TILE, ox = (t % G.tiles_x) * TILE;
    int y = threadIdx.x >> 5, x = threadIdx.x & 31;
    int gy = oy + y, gx = ox + x;
    unsigned r = 0;
    if (gy < G.h && gx < G.w) {
        int idx = gy * G.w + gx;
        if (__ldcg(raised + idx)) {
            __stcg(g + idx, INF);
            raised[idx] = 0;
            r = 1;
        }
    }
    unsigned total = __syncthreads_count(r);
    if (threadIdx.x == 0) atomicAdd(count, total);
}

// One grid-wide round: every block takes its flagged tiles of `in` (clearing the flags),
// applies `op`, and flags tiles for the next round in `next` (count in cnt_next).
// Returns the number of tiles flagged for the next round, the same in every block.
__device__ unsigned run_round(const Grid& G, int op, unsigned* in, unsigned* next, unsigned* seeds,
                              unsigned* ctrl, int r, int* g, const unsigned char* blocked,
                              unsigned char* raised, int (*gs)[HT], unsigned char (*bs)[TILE + 1],
                              unsigned char (*rs)[HT], unsigned* bar) {
    __shared__ int s_list[NTHREADS];
    __shared__ int s_n;
    unsigned* cnt_next = ctrl + C_CNT + (r + 1) % 3;
    if (blockIdx.x == 0 && threadIdx.x == 0) {
        ctrl[C_CNT + (r + 2) % 3] = 0;
        ctrl[C_ROUNDS] += 1;
    }
    // Collect this block's flagged tiles (t = blockIdx.x + k * gridDim.x).
    for (int base = blockIdx.x; base < G.ntiles; base += gridDim.x * NTHREADS) {
        if (threadIdx.x == 0) s_n = 0;
        __syncthreads();
        int t = base + threadIdx.x * gridDim.x;
        if (t < G.ntiles && __ldcg(in + t)) {
            in[t] = 0;
            s_list[atomicAdd(&s_n, 1)] = t;
        }
        __syncthreads();
        int count = s_n;
        for (int i = 0; i < count; ++i) {
            int tile = s_list[i];
            if (op == OP_RELAX) {
                unsigned bits = relax_tile(G, tile, g, blocked, gs, bs, ctrl + C_SWEEPS);
                flag_neighbour(G, tile, bits, threadIdx.x, next, cnt_next);
            } else if (op == OP_RAISE) {
                bool any = false;
                unsigned bits = raise_tile(G, tile, g, raised, gs, rs, ctrl + C_SWEEPS, &any);
                flag_neighbour(G, tile, bits, threadIdx.x, next, cnt_next);
                if (any && threadIdx.x == 8) atomicExch(seeds + tile, 1u);
            } else {
                reset_tile(G, tile, g, raised, ctrl + C_RAISED);
                if (threadIdx.x == 0) flag_tile(next, cnt_next, tile);
            }
            if (threadIdx.x == 0) atomicAdd(ctrl + C_TILES, 1u);
            __syncthreads();  // shared tile buffers are reused by the next tile
        }
        __syncthreads();
    }
    grid_barrier(ctrl, bar);
    return *((volatile unsigned*)cnt_next);
}

// The planning call.
//   mode 0 (DSS): apply the delta to `blocked`, g = INF everywhere, relax from the goal.
//   mode 1 (EDS): apply the delta; raise the cells whose cost must rise (raise_tile)
//   (newly blocked cells first); reset them to INF; relax from them and newly freed cells.
// delta[i] = cell * 2 + new_blocked. flags: 3 * ntiles (ping, pong, seeds), all zero.
extern "C" __global__ void __launch_bounds__(NTHREADS, MIN_BLOCKS)
plan_persistent(int* g, unsigned char* blocked, unsigned char* raised, const int* delta, int ndelta,
                unsigned* flags, unsigned* ctrl, int h, int w, int goal, int mode,
                unsigned bar_base) {
    __shared__ int gs[HT][HT];
    __shared__ unsigned char bs[TILE][TILE + 1];
    __shared__ unsigned char rs[HT][HT];
    Grid G;
    G.h = h; G.w = w; G.goal = goal;
    G.tiles_x = (w + TILE - 1) / TILE;
    G.tiles_y = (h + TILE - 1) / TILE;
    G.ntiles = G.tiles_x * G.tiles_y;
    unsigned* ping = flags;
    unsigned* pong = flags + G.ntiles;
    unsigned* seeds = flags + 2 * G.ntiles;
    int tid = blockIdx.x * NTHREADS + threadIdx.x, stride = gridDim.x * NTHREADS;
    unsigned bar = bar_base;  // thread 0's barrier target

    // Round 0: counters, the delta, the seeds of the first phase.
    if (tid == 0) {
        for (int i = 0; i < 3; ++i) ctrl[C_CNT + i] = 0;
        for (int i = C_ROUNDS; i <= C_CHANGED; ++i) ctrl[i] = 0;
    }
    grid_barrier(ctrl, &bar);
    unsigned* cnt1 = ctrl + C_CNT + 1;
    if (mode == 0) {
        for (int i = tid; i < ndelta; i += stride) blocked[delta[i] >> 1] = delta[i] & 1;
        for (int i = tid; i < h * w; i += stride) g[i] = INF;
        if (tid == 0 && goal >= 0) flag_tile(pong, cnt1, (goal / w / TILE) * G.tiles_x + (goal % w) / TILE);
    } else {
        for (int i = tid; i < ndelta; i += stride) {
            int cell = delta[i] >> 1;
            unsigned char now = delta[i] & 1;
            if (__ldcg(blocked + cell) == now) continue;
            blocked[cell] = now;
            int cy = cell / w, cx = cell % w;
            if (now) {
                // Its children may lie in the tiles around: each of those looks at it.
                raised[cell] = 1;
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        int ny = cy + dy, nx = cx + dx;
                        if (ny < 0 || nx < 0 || ny >= h || nx >= w) continue;
                        flag_tile(pong, cnt1, (ny / TILE) * G.tiles_x + nx / TILE);
                    }
                }
            }
            atomicExch(seeds + (cy / TILE) * G.tiles_x + cx / TILE, 1u);
        }
    }
    grid_barrier(ctrl, &bar);
    unsigned pending = *((volatile unsigned*)cnt1);
    int r = 1;
    if (mode == 1) {
        while (pending) {
            pending = run_round(G, OP_RAISE, (r & 1) ? pong : ping, (r & 1) ? ping : pong, seeds, ctrl, r, g, blocked,
                                raised, gs, bs, rs, &bar);
            ++r;
        }
        pending = run_round(G, OP_RESET, seeds, (r & 1) ? ping : pong, seeds, ctrl, r, g, blocked, raised,
                            gs, bs, rs, &bar);
        ++r;
    }
    while (pending) {
        pending = run_round(G, OP_RELAX, (r & 1) ? pong : ping, (r & 1) ? ping : pong, seeds, ctrl, r, g, blocked,
                            raised, gs, bs, rs, &bar);
        ++r;
    }
}
