// The paper's form (Díaz-Toro et al. 2022, Figure 4), kept for comparison: read-only (_r)
// and write-only (_w) maps for g, pred and incon, one kernel_planner launch per iteration
// over the whole grid, and flag_stop read back by the host after every launch. The host
// swaps the _r and _w pointers between launches.
//
// flag[slot] is set when a launch changed something; the launch also clears flag[slot ^ 1],
// the one the next launch will use, so the host needs no memset between launches.
// flag[2..3] hold a 64-bit count of the cells kernel_planner has relaxed (statistics).

#include "abi.cuh"  // INF and the neighbours in grid.NEIGHBOUR_* order

// DSS start: g = INF, pred = -1, no raised cells; the goal is 0 and its neighbours inconsistent.
extern "C" __global__ void paper_init(int* g_r, signed char* pred_r, unsigned char* incon_r,
                                      unsigned char* incon_w, unsigned char* raised_r,
                                      unsigned char* raised_w, const unsigned char* blocked,
                                      int h, int w, int goal, int* flag) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i == 0) { flag[0] = 0; flag[1] = 0; }  // flag[2..3], the running count, stays
    if (i >= h * w) return;
    bool goal_open = !blocked[goal];
    int y = i / w, x = i % w, gy = goal / w, gx = goal % w;
    bool near_goal = i != goal && abs(y - gy) <= 1 && abs(x - gx) <= 1;
    g_r[i] = (i == goal && goal_open) ? 0 : INF;
    pred_r[i] = -1;
    incon_r[i] = (near_goal && goal_open && !blocked[i]) ? 1 : 0;
    incon_w[i] = 0;
    raised_r[i] = 0;
    raised_w[i] = 0;
}

// The delta: delta[k] = cell * 2 + new_blocked. With eds != 0, newly blocked cells are
// raised (their descendants follow in kernel_raise) and newly freed cells inconsistent.
extern "C" __global__ void paper_apply(const int* delta, int n, unsigned char* blocked,
                                       unsigned char* raised_r, unsigned char* raised_w,
                                       unsigned char* incon_r, int eds) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    int cell = delta[k] >> 1;
    unsigned char now = delta[k] & 1;
    if (blocked[cell] == now) return;
    blocked[cell] = now;
    if (!eds) return;
    if (now) { raised_r[cell] = 1; raised_w[cell] = 1; }
    else incon_r[cell] = 1;
}

// One relaxation iteration over the whole grid.
extern "C" __global__ void kernel_planner(const int* g_r, int* g_w, const signed char* pred_r,
                                          signed char* pred_w, unsigned char* incon_r,
                                          unsigned char* incon_w, const unsigned char* blocked,
                                          int h, int w, int goal, int* flag, int slot) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i == 0) flag[slot ^ 1] = 0;
    bool valid = i < h * w;
    bool relaxed = false;
    if (valid) {
        int cur = g_r[i];
        signed char p = pred_r[i];
        if (incon_r[i]) {
            incon_r[i] = 0;  // the next launch uses this map as its incon_w: leave it clean
            if (!blocked[i]) {
                relaxed = true;
                int y = i / w, x = i % w;
                int best = i == goal ? 0 : cur, bp = i == goal ? -1 : p;
                for (int k = 0; k < 8 && i != goal; ++k) {
                    int ny = y + NB_DR[k], nx = x + NB_DC[k];
                    if (ny < 0 || nx < 0 || ny >= h || nx >= w) continue;
                    int v = g_r[ny * w + nx] + NB_COST[k];
                    if (v < best) { best = v; bp = k; }
                }
                if (best < cur) {
                    cur = best;
                    p = (signed char)bp;
                    for (int k = 0; k < 8; ++k) {
                        int ny = y + NB_DR[k], nx = x + NB_DC[k];
                        if (ny < 0 || nx < 0 || ny >= h || nx >= w) continue;
                        incon_w[ny * w + nx] = 1;
                    }
                    flag[slot] = 1;
                }
            }
        }
        g_w[i] = cur;
        pred_w[i] = p;
    }
    int count = __syncthreads_count(relaxed);
    if (threadIdx.x == 0 && count)
        atomicAdd((unsigned long long*)(flag + 2), (unsigned long long)count);
}

// EDS: one iteration of raising, a cell is raised when its pred is raised.
extern "C" __global__ void kernel_raise(const signed char* pred_r, const unsigned char* raised_r,
                                        unsigned char* raised_w, int h, int w, int* flag, int slot) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i == 0) flag[slot ^ 1] = 0;
    if (i >= h * w) return;
    unsigned char r = raised_r[i];
    int p = pred_r[i];
    if (!r && p >= 0) {
        int ny = i / w + NB_DR[p], nx = i % w + NB_DC[p];
        if (raised_r[ny * w + nx]) { r = 1; flag[slot] = 1; }
    }
    raised_w[i] = r;
}

// EDS: raised cells take INF, lose their pred and become inconsistent (unless blocked).
extern "C" __global__ void paper_reset(int* g_r, signed char* pred_r, unsigned char* raised_r,
                                       unsigned char* raised_w, unsigned char* incon_r,
                                       const unsigned char* blocked, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n || !raised_r[i]) return;
    g_r[i] = INF;
    pred_r[i] = -1;
    raised_r[i] = 0;
    raised_w[i] = 0;
    if (!blocked[i]) incon_r[i] = 1;
}
