// Path extraction on the device: follow the field from `start` to the goal with the rule of
// interface.reference_path (the first neighbour in grid.NEIGHBOUR_* order with
// g[n] + cost == g[cur]), so that only the path crosses to the host.
//
// The walk is sequential, so it runs in shared memory: the block loads a WIN x WIN window of
// g, every thread works out the next step of its window cells in parallel (a byte each), and
// thread 0 chases those bytes, one shared load per step, while it stays inside the window;
// then the window is reloaded ahead of the walk (shifted in the last step's direction).
// Blocked cells always hold INF, so they never satisfy the rule and need no map of their own.
//
// out[0] = cells written, out[1] = status (0 reached the goal, 1 stopped after `cap`
// cells: call again from the last one, 2 start unreachable, 3 field inconsistent),
// out[2 ...] = flat cell indices.

#define WIN 96
#define NTHREADS 1024
#define INF 0x3FFFFFFF

// next-step codes besides the directions 0..7
#define AT_GOAL 8
#define LEAVES 9   // a neighbour inside the map lies outside the window: reload
#define STUCK 10   // no neighbour continues the field

__constant__ int P_DR[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
__constant__ int P_DC[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
__constant__ int P_COST[8] = {14, 10, 14, 10, 10, 14, 10, 14};

__device__ __forceinline__ int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }

extern "C" __global__ void __launch_bounds__(NTHREADS, 1)
walk_path(const int* g, int h, int w, int start, int* out, int cap) {
    __shared__ int win[WIN][WIN];
    __shared__ unsigned char nxt[WIN][WIN];
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
        for (int i = threadIdx.x; i < WIN * WIN; i += NTHREADS) {
            int sy = i / WIN, sx = i % WIN;
            int y = oy + sy, x = ox + sx;
            bool inside = (y == 0 || sy > 0) && (y >= h - 1 || sy < WIN - 1) &&
                          (x == 0 || sx > 0) && (x >= w - 1 || sx < WIN - 1);
            unsigned char code = LEAVES;
            if (inside) {
                int gc = win[sy][sx];
                code = gc == 0 ? AT_GOAL : STUCK;
                for (int k = 0; k < 8 && code == STUCK; ++k) {
                    int ny = y + P_DR[k], nx = x + P_DC[k];
                    if (ny < 0 || nx < 0 || ny >= h || nx >= w) continue;
                    if (win[sy + P_DR[k]][sx + P_DC[k]] + P_COST[k] == gc) code = k;
                }
            }
            nxt[sy][sx] = code;
        }
        __syncthreads();
        if (threadIdx.x == 0) {
            int cy = s_cy, cx = s_cx, n = s_n, dy = s_dy, dx = s_dx;
            while (true) {
                int code = nxt[cy - oy][cx - ox];
                if (code == LEAVES) break;
                if (n == cap) { s_status = 1; s_done = 1; break; }
                out[2 + n] = cy * w + cx;
                ++n;
                if (code == AT_GOAL) { s_done = 1; break; }
                if (code == STUCK) { s_status = 3; s_done = 1; break; }
                dy = P_DR[code];
                dx = P_DC[code];
                cy += dy;
                cx += dx;
            }
            s_cy = cy; s_cx = cx; s_n = n; s_dy = dy; s_dx = dx;
        }
        __syncthreads();
    }
    if (threadIdx.x == 0) {
        out[0] = s_n;
        out[1] = s_status;
    }
}
