// The reach search on the device (reach.py's whole-map search), compiled after harmonic.cu in one
// module (cuda.py joins the two sources): it uses that file's fill tiling (FILL_TILE, FILL_SPAN).

// One tile of a reach pass: a free cell next to a reached one is reached, iterated in shared
// memory until the tile is stable against its ring; returns whether it reached any cell (the
// same in every thread). The fill's tiling (fill_tile), for a flag that only turns on.
__device__ bool reach_tile(unsigned char* reach, const unsigned char* blocked, int height,
                           int width, int tr, int tc, unsigned char* s) {
    const int r0 = tr * FILL_TILE - 1, c0 = tc * FILL_TILE - 1;
    for (int k = threadIdx.x; k < FILL_SPAN * FILL_SPAN; k += blockDim.x) {
        const int r = r0 + k / FILL_SPAN, c = c0 + k % FILL_SPAN;
        s[k] = r >= 0 && r < height && c >= 0 && c < width ? __ldcg(reach + r * width + c) : 0;
    }
    __syncthreads();
    const int tx = threadIdx.x % FILL_TILE, ty = threadIdx.x / FILL_TILE;
    bool open[FILL_ROWS];
    for (int j = 0; j < FILL_ROWS; ++j) {
        const int r = r0 + 1 + ty + 8 * j, c = c0 + 1 + tx;
        open[j] = r < height && c < width && !blocked[r * width + c] &&
                  !s[(ty + 8 * j + 1) * FILL_SPAN + tx + 1];
    }
    bool any = false;
    while (true) {
        bool mine = false;
        for (int j = 0; j < FILL_ROWS; ++j) {
            const int k = (ty + 8 * j + 1) * FILL_SPAN + tx + 1;
            if (!open[j] || s[k]) continue;
            bool next = false;
            for (int d = 0; d < 9 && !next; ++d) next = s[k + (d / 3 - 1) * FILL_SPAN + d % 3 - 1];
            if (next) { s[k] = 1; mine = true; }
        }
        if (!__syncthreads_or(mine)) break;
        any = true;
    }
    if (any)
        for (int j = 0; j < FILL_ROWS; ++j)
            if (open[j] && s[(ty + 8 * j + 1) * FILL_SPAN + tx + 1])
                reach[(r0 + 1 + ty + 8 * j) * width + c0 + 1 + tx] = 1;
    __syncthreads();
    return any;
}

// The whole-map reach search (reach.py's, when a change may have cut cells off) on the device:
// every free cell the goal reaches, 8-connected, grown from the goal by tiles as the fill's
// passes go (a pass crosses a tile, not a cell: the grid barriers number about the longest
// chain of tiles from the goal, not the map's breadth-first depth). Then the cells whose
// reach differs from `before` (the host's mask before the change) listed in `changed`, their
// count in result[3]. `stamp` (the fill's) is left all -2, as found.
extern "C" __global__ void __launch_bounds__(256)
harmonic_reach(const unsigned char* blocked, const unsigned char* before, unsigned char* reach,
               int height, int width, int goal, unsigned* flags, int* result, int* changed,
               int* stamp) {
    cg::grid_group grid = cg::this_grid();
    __shared__ unsigned char s[FILL_SPAN * FILL_SPAN];
    const long long stride = (long long)gridDim.x * blockDim.x;
    const long long first = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    const long long n = (long long)height * width;
    const int tiles_x = (width + FILL_TILE - 1) / FILL_TILE;
    const int tiles = tiles_x * ((height + FILL_TILE - 1) / FILL_TILE);
    const bool open = !blocked[goal];
    for (long long k = first; k < n; k += stride) reach[k] = k == goal && open;
    const int home = goal / width / FILL_TILE * tiles_x + goal % width / FILL_TILE;
    for (long long t = first; t < tiles; t += stride) stamp[t] = t == home && open ? -1 : -2;
    grid.sync();
    int passes = 0;
    while (true) {  // each pass that goes on reaches a cell more: at most the map's cells
        bool mine = false;
        for (int t = blockIdx.x; t < tiles; t += gridDim.x) {
            const int tr = t / tiles_x, tc = t % tiles_x;
            bool due = false;
            if (threadIdx.x < 9) {
                const int r = tr + threadIdx.x / 3 - 1, c = tc + threadIdx.x % 3 - 1;
                due = r >= 0 && c >= 0 && c < tiles_x && r * tiles_x + c < tiles &&
                      __ldcg(stamp + r * tiles_x + c) >= passes - 1;
            }
            if (!__syncthreads_or(due)) continue;
            if (reach_tile(reach, blocked, height, width, tr, tc, s)) {
                mine = true;
                if (threadIdx.x == 0) stamp[t] = passes;
            }
        }
        unsigned* slot = flags + passes % 3;
        if (mine && threadIdx.x == 0) atomicOr(slot, 1u);
        grid.sync();
        const bool any = *(volatile unsigned*)slot != 0u;
        if (first == 0) flags[(passes + 2) % 3] = 0u;
        ++passes;
        if (!any) break;
    }
    for (long long t = first; t < tiles; t += stride) stamp[t] = -2;
    for (long long k = first; k < n; k += stride)
        if (__ldcg(reach + k) != before[k]) changed[atomicAdd(flags + 3, 1u)] = (int)k;
    grid.sync();
    if (first == 0) {
        result[0] = passes;
        result[3] = (int)*(volatile unsigned*)(flags + 3);
        for (int k = 0; k < 4; ++k) flags[k] = 0u;
    }
}
