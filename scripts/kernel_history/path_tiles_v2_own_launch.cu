// Path extraction by tile jumps: the same cells as path.cu (interface.reference_path's rule:
// the first neighbour in grid.NEIGHBOUR_* order with g[n] + cost == g[cur]), with the long
// sequential walk cut into pieces that run in parallel.
//
// One persistent launch (path_tiles) in three phases, a grid-wide barrier between them:
// 1. every 32 x 32 tile (blocks grid-strided): for each of its 124 border cells (where a
//    path can enter), follow the rule inside the tile in shared memory to the first cell
//    outside it (the exit, an entry of the next tile) or to the goal; keep exit and count.
//    The start cell's tile does the same for the start cell.
// 2. one thread: from the start, hop exit to exit (one load per tile crossed instead of one
//    step per cell) and list the segments (entry, cells, offset).
// 3. every segment (blocks grid-strided): walk it again inside its tile, in shared memory,
//    writing its cells at its offset.
// The barrier is fast.cu's (monotone arrival count in ctrl[0], release in ctrl[32]); the
// host passes the count the previous launch ended with and sizes the grid to be resident.
//
// out[0] = cells written, out[1] = status (0 reached the goal, 1 stopped before exceeding
// `cap` cells: call again from the last one, 2 start unreachable, 3 field inconsistent),
// out[2 ...] = flat cell indices.

#define TILE 32
#define HT (TILE + 2)
#define BORDER 124          // cells on a tile's perimeter
#define INF 0x3FFFFFFF
#define EXIT_GOAL -2
#define EXIT_STUCK -3
#define CODE_GOAL 8
#define CODE_STUCK 9
#define FULL 0xFFFFFFFFu

__constant__ int T_DR[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
__constant__ int T_DC[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
__constant__ int T_COST[8] = {14, 10, 14, 10, 10, 14, 10, 14};

// Perimeter index b (0..123) <-> tile-local cell: top row, bottom row, left and right columns.
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

// Load g of tile t and its halo (INF outside the map) and work out each tile cell's next step.
__device__ void load_codes(const int* g, int h, int w, int oy, int ox, int (*gs)[HT],
                           unsigned char (*code)[TILE]) {
    for (int i = threadIdx.x; i < HT * HT; i += blockDim.x) {
        int sy = i / HT, sx = i % HT;
        int y = oy + sy - 1, x = ox + sx - 1;
        gs[sy][sx] = (y >= 0 && x >= 0 && y < h && x < w) ? __ldcg(g + y * w + x) : INF;
    }
    __syncthreads();
    for (int i = threadIdx.x; i < TILE * TILE; i += blockDim.x) {
        int ly = i / TILE, lx = i % TILE;
        int gc = gs[ly + 1][lx + 1];
        unsigned char c = CODE_STUCK;
        if (gc == 0) c = CODE_GOAL;
        else if (gc < INF) {
            for (int k = 0; k < 8 && c == CODE_STUCK; ++k)
                if (gs[ly + 1 + T_DR[k]][lx + 1 + T_DC[k]] + T_COST[k] == gc) c = (unsigned char)k;
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
        ly += T_DR[c];
        lx += T_DC[c];
        if (ly < 0 || lx < 0 || ly >= TILE || lx >= TILE) return make_int2((oy + ly) * w + ox + lx, count);
    }
}

__device__ void grid_barrier(unsigned* ctrl, unsigned* target) {
    __syncthreads();
    if (threadIdx.x == 0) {
        *target += gridDim.x;
        __threadfence();
        unsigned arrived = atomicAdd(ctrl, 1u) + 1u;
        volatile unsigned* release = ctrl + 32;
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

// exits: 124 per tile; segs[k] = (entry cell, cells, offset of its first cell in the path).
extern "C" __global__ void __launch_bounds__(128)
path_tiles(const int* g, int h, int w, int start, int2* exits, int4* segs, int* out, int cap,
           unsigned* ctrl, unsigned bar_base) {
    __shared__ int gs[HT][HT];
    __shared__ unsigned char code[TILE][TILE];
    __shared__ int s_nsegs;
    unsigned bar = bar_base;
    int tiles_x = (w + TILE - 1) / TILE;
    int ntiles = tiles_x * ((h + TILE - 1) / TILE);
    int sy = start / w, sx = start % w;
    int start_tile = (sy / TILE) * tiles_x + sx / TILE;

    // 1. exits of every border cell; the start's own segment goes to ctrl[40..41]
    for (int t = blockIdx.x; t < ntiles; t += gridDim.x) {
        int oy = (t / tiles_x) * TILE, ox = (t % tiles_x) * TILE;
        load_codes(g, h, w, oy, ox, gs, code);
        int b = threadIdx.x;
        if (b < BORDER) {
            int ly, lx;
            border_cell(b, &ly, &lx);
            exits[t * BORDER + b] = (oy + ly < h && ox + lx < w) ? follow(code, ly, lx, oy, ox, w)
                                                                : make_int2(EXIT_STUCK, 1);
        } else if (b == BORDER && t == start_tile) {
            int2 seg = follow(code, sy - oy, sx - ox, oy, ox, w);
            ctrl[40] = (unsigned)seg.x;
            ctrl[41] = (unsigned)seg.y;
        }
        __syncthreads();  // the tile buffers are reused by the next tile
    }
    grid_barrier(ctrl, &bar);

    // 2. hop from tile to tile
    if (blockIdx.x == 0 && threadIdx.x == 0) {
        int n = 0, total = 0, status = 0;
        if (__ldcg(g + start) >= INF) {
            status = 2;
        } else {
            int entry = start;
            int2 seg = make_int2((int)__ldcg(ctrl + 40), (int)__ldcg(ctrl + 41));
            while (true) {
                if (total + seg.y > cap) { status = 1; break; }
                segs[n++] = make_int4(entry, seg.y, total, 0);
                total += seg.y;
                if (seg.x == EXIT_GOAL) break;
                if (seg.x == EXIT_STUCK) { status = 3; break; }
                entry = seg.x;
                int y = entry / w, x = entry % w;
                int t = (y / TILE) * tiles_x + x / TILE;
                seg = __ldcg(exits + t * BORDER + border_index(y % TILE, x % TILE));
            }
        }
        ctrl[42] = (unsigned)n;
        out[0] = total;
        out[1] = status;
    }
    grid_barrier(ctrl, &bar);

    // 3. walk each segment again inside its tile
    if (threadIdx.x == 0) s_nsegs = (int)__ldcg(ctrl + 42);
    __syncthreads();
    for (int k = blockIdx.x; k < s_nsegs; k += gridDim.x) {
        int4 s = __ldcg(segs + k);
        int y = s.x / w, x = s.x % w;
        int oy = (y / TILE) * TILE, ox = (x / TILE) * TILE;
        load_codes(g, h, w, oy, ox, gs, code);
        if (threadIdx.x == 0) {
            int ly = y - oy, lx = x - ox;
            for (int i = 0; i < s.y; ++i) {
                out[2 + s.z + i] = (oy + ly) * w + ox + lx;
                int c = code[ly][lx];
                if (c >= CODE_GOAL) break;
                ly += T_DR[c];
                lx += T_DC[c];
            }
        }
        __syncthreads();  // the tile buffers are reused by the next segment
    }
}
