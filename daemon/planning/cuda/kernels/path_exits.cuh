// Path extraction by tile jumps (dijkstra.reference_path's rule: from each cell, the first
// neighbour in grid.NEIGHBOUR_* order with g[n] + cost == g[cur]), in three phases that the
// kernels (path_tiles.cu, and fast.cu after a repair) separate by grid barriers:
// 1. tile_exits, per 32 x 32 tile: for each of its BORDER cells (where a path can enter),
//    follow the rule inside the tile in shared memory to the first cell outside it (the
//    exit, an entry of the next tile) or to the goal; keep exit and count. The start's tile
//    does the same for the start cell. An exit depends only on g in the tile and its halo,
//    so fast.cu recomputes only the tiles whose g or halo changed.
// 2. hop_segments, one thread: from the start, hop exit to exit (one load per tile crossed
//    instead of one step per cell) and list the segments (entry, cells, offset).
// 3. walk_segments: every segment again inside its tile, in parallel, writing its cells.
//
// out[0] = cells written, out[1] = status (PATH_DONE reached the goal, PATH_MORE stopped
// before exceeding `cap` cells: call again from the last one, PATH_NONE start unreachable,
// PATH_BROKEN field inconsistent),
// out[2 + 2k], out[3 + 2k] = row and column of the k-th cell. ctrl[P_SEG..P_NSEGS] pass
// values between the phases.
#pragma once
#include "grid_sync.cuh"  // GBLOCK, GSIZE: the blocks of the call
#include "tile.cuh"

#define EXIT_GOAL -2
#define EXIT_STUCK -3
#define CODE_GOAL 8
#define CODE_STUCK 9

// Perimeter index b (0 .. BORDER - 1) <-> tile-local cell: top row, bottom row, left and right columns.
__device__ __forceinline__ void border_cell(int b, int* ly, int* lx) {
    if (b < 32) { *ly = 0; *lx = b; }
    else if (b < 64) { *ly = TILE - 1; *lx = b - 32; }
    else if (b < 94) { *ly = b - 63; *lx = 0; }
    else { *ly = b - 93; *lx = TILE - 1; }
}

__device__ __forceinline__ int border_index(int ly, int lx) {
    if (ly == 0) return lx;
    if (ly == TILE - 1) return 32 + lx;
    if (lx == 0) return 63 + ly;
    return 93 + ly;  // lx == TILE - 1
}

__device__ __forceinline__ int tile_of(int cell, int w, int tiles_x) {
    return (cell / w / TILE) * tiles_x + (cell % w) / TILE;
}

// Load g of the tile at (oy, ox) and its halo (INF outside the map) and work out each tile
// cell's next step (code: neighbour index, CODE_GOAL or CODE_STUCK). By the `lanes` threads
// numbered `lane` (the whole block, or a half with fast.cu's pairs of tiles); every thread of
// the block takes the barriers.
__device__ void load_codes(const int* g, int h, int w, int oy, int ox, int (*gs)[HT],
                           unsigned char (*code)[TILE], int lane, int lanes) {
    for (int i = lane; i < HT * HT; i += lanes) {
        int sy = i / HT, sx = i % HT;
        int y = oy + sy - 1, x = ox + sx - 1;
        gs[sy][sx] = (y >= 0 && x >= 0 && y < h && x < w) ? __ldcg(g + y * w + x) : INF;
    }
    __syncthreads();
    for (int i = lane; i < TILE * TILE; i += lanes) {
        int ly = i / TILE, lx = i % TILE;
        int gc = gs[ly + 1][lx + 1];
        unsigned char c = CODE_STUCK;
        if (gc == 0) c = CODE_GOAL;
        else if (gc < INF) {
            for (int k = 0; k < 8 && c == CODE_STUCK; ++k)
                if (gs[ly + 1 + NB_DR[k]][lx + 1 + NB_DC[k]] + NB_COST[k] == gc) c = (unsigned char)k;
        }
        code[ly][lx] = c;
    }
    __syncthreads();
}

// Follow the codes from (ly, lx) until leaving the tile; (exit or EXIT_*, cells in the tile).
__device__ int2 follow(unsigned char (*code)[TILE], int ly, int lx, int oy, int ox, int w) {
    int count = 0;
    while (true) {
        int c = code[ly][lx];
        ++count;
        if (c == CODE_GOAL) return make_int2(EXIT_GOAL, count);
        if (c == CODE_STUCK) return make_int2(EXIT_STUCK, count);
        ly += NB_DR[c];
        lx += NB_DC[c];
        if (ly < 0 || lx < 0 || ly >= TILE || lx >= TILE) return make_int2((oy + ly) * w + ox + lx, count);
    }
}

// Phase 1 for tile t: exits[t * BORDER + b] for its border cells; the start's own segment
// to ctrl[P_SEG..] when the start lies in t. By `lanes` > BORDER threads (load_codes).
__device__ void tile_exits(const int* g, int h, int w, int t, int start, int2* exits,
                           unsigned* ctrl, int (*gs)[HT], unsigned char (*code)[TILE],
                           int lane = threadIdx.x, int lanes = blockDim.x) {
    int tiles_x = (w + TILE - 1) / TILE;
    int oy = (t / tiles_x) * TILE, ox = (t % tiles_x) * TILE;
    load_codes(g, h, w, oy, ox, gs, code, lane, lanes);
    int b = lane;
    if (b < BORDER) {
        int ly, lx;
        border_cell(b, &ly, &lx);
        exits[t * BORDER + b] = (oy + ly < h && ox + lx < w) ? follow(code, ly, lx, oy, ox, w)
                                                            : make_int2(EXIT_STUCK, 1);
    } else if (b == BORDER && start >= 0 && tile_of(start, w, tiles_x) == t) {
        int2 seg = follow(code, start / w - oy, start % w - ox, oy, ox, w);
        ctrl[P_SEG] = (unsigned)seg.x;
        ctrl[P_SEG + 1] = (unsigned)seg.y;
    }
    __syncthreads();  // the tile buffers are reused by the next tile
}

// Phase 2, one thread: hop from the start's segment to the goal through the exits.
__device__ void hop_segments(const int* g, int w, int start, const int2* exits, int4* segs,
                             int* out, int cap, unsigned* ctrl) {
    int tiles_x = (w + TILE - 1) / TILE;
    int n = 0, total = 0, status = PATH_DONE;
    if (__ldcg(g + start) >= INF) {
        status = PATH_NONE;
    } else {
        int entry = start;
        int2 seg = make_int2((int)__ldcg(ctrl + P_SEG), (int)__ldcg(ctrl + P_SEG + 1));
        while (true) {
            if (total + seg.y > cap) { status = PATH_MORE; break; }
            segs[n++] = make_int4(entry, seg.y, total, 0);
            total += seg.y;
            if (seg.x == EXIT_GOAL) break;
            if (seg.x == EXIT_STUCK) { status = PATH_BROKEN; break; }
            entry = seg.x;
            int y = entry / w, x = entry % w;
            seg = __ldcg(exits + tile_of(entry, w, tiles_x) * BORDER + border_index(y % TILE, x % TILE));
        }
    }
    ctrl[P_NSEGS] = (unsigned)n;
    out[0] = total;
    out[1] = status;
}

// Phase 3: every block walks its share of the segments again inside their tiles. Thread 0
// walks into shared memory (gs: g is not needed once the codes are worked out) and the block
// writes the cells out together, 8 bytes a thread: `out` may be mapped host memory, where one
// thread's stores, two per cell, would each be a PCIe write of their own. gs must be 8-byte
// aligned (its declarations say __align__(16)).
#define WALK_CHUNK 512  // cells per write-out (HT * HT ints hold 578 (row, column) pairs)
__device__ void walk_segments(const int* g, int h, int w, const int4* segs, int* out,
                              unsigned* ctrl, int (*gs)[HT], unsigned char (*code)[TILE]) {
    static_assert(2 * WALK_CHUNK <= HT * HT, "a chunk fits in gs");
    __shared__ int s_nsegs, s_count;
    if (threadIdx.x == 0) s_nsegs = (int)__ldcg(ctrl + P_NSEGS);
    __syncthreads();
    int2* cells = (int2*)&gs[0][0];
    int2* path = (int2*)(out + 2);  // (row, column) pairs: the host's path as is
    for (int k = GBLOCK; k < s_nsegs; k += GSIZE) {
        int4 s = __ldcg(segs + k);
        int y = s.x / w, x = s.x % w;
        int oy = (y / TILE) * TILE, ox = (x / TILE) * TILE;
        load_codes(g, h, w, oy, ox, gs, code, threadIdx.x, blockDim.x);
        int ly = y - oy, lx = x - ox;  // thread 0's place on the walk
        for (int done = 0; done < s.y; done += WALK_CHUNK) {
            if (threadIdx.x == 0) {
                int n = 0, end = min(WALK_CHUNK, s.y - done);
                while (n < end) {
                    cells[n++] = make_int2(oy + ly, ox + lx);
                    int c = code[ly][lx];
                    if (c >= CODE_GOAL) break;
                    ly += NB_DR[c];
                    lx += NB_DC[c];
                }
                s_count = n;
            }
            __syncthreads();
            for (int i = threadIdx.x; i < s_count; i += blockDim.x) path[s.z + done + i] = cells[i];
            __syncthreads();  // written out before the next chunk, or the next segment's load
        }
    }
}
