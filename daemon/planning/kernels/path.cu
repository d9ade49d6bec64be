// Path extraction on the device: follow the field from `start` to the goal with the rule of
// interface.reference_path (the first neighbour in grid.NEIGHBOUR_* order with
// g[n] + cost == g[cur]), so that only the path crosses to the host.
//
// The walk is sequential and latency-bound, so it runs in shared memory and by one warp:
// the block loads a WIN x WIN window of g; warp 0 walks while the current cell's neighbours
// are inside it, lanes 0..7 testing the 8 neighbours at once (a ballot picks the first
// match in the fixed order, a shuffle hands over its g); then the window is reloaded ahead of
// the walk (shifted in the last step's direction). Blocked cells always hold INF, so they
// never satisfy the rule and need no map of their own.
//
// out[0] = cells written, out[1] = status (0 reached the goal, 1 stopped after `cap`
// cells: call again from the last one, 2 start unreachable, 3 field inconsistent),
// out[2 + 2k], out[3 + 2k] = row and column of the k-th cell (the host's (n, 2) path as is).

#ifndef WIN
#define WIN 64
#endif
#define NTHREADS 1024
#define INF 0x3FFFFFFF
#define FULL 0xFFFFFFFFu

// Neighbour k (grid.NEIGHBOUR_* order) packed two bits per k: dr + 1, dc + 1; diagonal mask.
#define PACKED_DR 0xA940u
#define PACKED_DC 0x9224u
#define DIAGONALS 0xA5u

__device__ __forceinline__ int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }
__device__ __forceinline__ int nb_dr(int k) { return (int)((PACKED_DR >> (2 * k)) & 3u) - 1; }
__device__ __forceinline__ int nb_dc(int k) { return (int)((PACKED_DC >> (2 * k)) & 3u) - 1; }

extern "C" __global__ void __launch_bounds__(NTHREADS, 1)
walk_path(const int* g, int h, int w, int start, int* out, int cap) {
    __shared__ int win[WIN][WIN];
    __shared__ int s_cy, s_cx, s_dy, s_dx, s_done, s_n, s_status;
    if (threadIdx.x == 0) {
        s_cy = start / w;
        s_cx = start % w;
        s_dy = -1;  // the walks of this project head north; only a guess for the first window
        s_dx = 0;
        s_n = 0;
        s_status = 0;
        s_done = 0;
        if (__ldcg(g + start) >= INF) {
            s_status = 2;
            s_done = 1;
        }
    }
    __syncthreads();
    const int lane = threadIdx.x & 31;
    const int k = lane & 7;
    const int my_dr = nb_dr(k), my_dc = nb_dc(k);
    const int my_cost = ((DIAGONALS >> k) & 1u) ? 14 : 10;
    while (!s_done) {
        // Window origin: the current cell sits near the trailing edge, the rest lies ahead,
        // and every neighbour of the current cell is inside.
        const int ahead = WIN / 2 - 4;
        int oy = clampi(s_cy - WIN / 2 + s_dy * ahead, 0, max(h - WIN, 0));
        int ox = clampi(s_cx - WIN / 2 + s_dx * ahead, 0, max(w - WIN, 0));
        oy = clampi(oy, s_cy - WIN + 2, s_cy - 1 < 0 ? 0 : s_cy - 1);
        ox = clampi(ox, s_cx - WIN + 2, s_cx - 1 < 0 ? 0 : s_cx - 1);
        oy = clampi(oy, 0, max(h - WIN, 0));
        ox = clampi(ox, 0, max(w - WIN, 0));
        for (int i = threadIdx.x; i < WIN * WIN; i += NTHREADS) {
            int sy = i / WIN, sx = i % WIN;
            int y = oy + sy, x = ox + sx;
            win[sy][sx] = (y < h && x < w) ? __ldcg(g + y * w + x) : INF;
        }
        __syncthreads();
        if (threadIdx.x < 32) {
            int cy = s_cy, cx = s_cx, n = s_n, dy = s_dy, dx = s_dx;
            int gc = win[cy - oy][cx - ox];
            int status = 0, done = 0;
            while (true) {
                bool inside = (cy == 0 || cy - 1 >= oy) && (cy == h - 1 || cy + 1 < oy + WIN) &&
                              (cx == 0 || cx - 1 >= ox) && (cx == w - 1 || cx + 1 < ox + WIN);
                if (!inside) break;
                if (n == cap) { status = 1; done = 1; break; }
                if (lane == 0) {
                    out[2 + 2 * n] = cy;
                    out[3 + 2 * n] = cx;
                }
                ++n;
                if (gc == 0) { done = 1; break; }
                int ny = cy + my_dr, nx = cx + my_dc;
                bool ok = lane < 8 && ny >= 0 && nx >= 0 && ny < h && nx < w;
                int v = ok ? win[ny - oy][nx - ox] : INF;
                unsigned match = __ballot_sync(FULL, ok && v + my_cost == gc);
                if (!match) { status = 3; done = 1; break; }
                int kk = __ffs(match) - 1;
                gc = __shfl_sync(FULL, v, kk);
                dy = nb_dr(kk);
                dx = nb_dc(kk);
                cy += dy;
                cx += dx;
            }
            if (lane == 0) {
                s_cy = cy; s_cx = cx; s_n = n; s_dy = dy; s_dx = dx;
                if (done) { s_done = 1; s_status = status; }
            }
        }
        __syncthreads();
    }
    if (threadIdx.x == 0) {
        out[0] = s_n;
        out[1] = s_status;
    }
}
