// Hong & DeSouza's harmonic field on the GPU, kept as w = -ln(1 - u) (relax.py says why).
//
// One cooperative launch per relaxation. It first applies the map's changes the host queued
// (`changes`: cell << 2 | code; code 0 blocked or cut off, 1 newly reachable with no value
// yet, both before code 2, the goal's fixed zero). Then every thread strides over the cells
// of one colour of the four-colour (row parity x column parity) ordering of the nine-point
// stencil, the grid synchronises between colours, and every `check_every` sweeps the largest
// change of the sweep (the residual, in log units) is reduced into a global word; all threads
// read it after a grid sync and leave together once it is below `tol` — or, past `budget`
// sweeps, once no free cell is a pit (a replanning step's stop: every descent reaches the
// goal). `jacobi` instead sweeps eq. (1) as written, from a copy of the last sweep. At the end
// each cell gets the paper's Idx: the neighbour (0..8, row-major in the 3 x 3 block) of lowest
// w when strictly below its own, 4 (itself) when none is; the host walks it. REAL is float or
// double (-DREAL=...).
#include <cooperative_groups.h>
namespace cg = cooperative_groups;

#ifndef REAL
#define REAL float
#define REAL_EPS 1.1920929e-7f
#endif
#define BLOCKED_W ((REAL)1.0e30)
#define ORTHO ((REAL)0.2)
#define DIAG ((REAL)0.05)

__device__ __forceinline__ REAL target(const REAL* w, int i, int width) {
    REAL n = w[i - width], s = w[i + width], e = w[i + 1], o = w[i - 1];
    REAL ne = w[i - width + 1], nw = w[i - width - 1], se = w[i + width + 1], sw = w[i + width - 1];
    REAL m = fmin(fmin(fmin(n, s), fmin(e, o)), fmin(fmin(ne, nw), fmin(se, sw)));
    if (m >= BLOCKED_W) return BLOCKED_W;
    REAL t = ORTHO * (exp(m - n) + exp(m - s) + exp(m - e) + exp(m - o)) +
             DIAG * (exp(m - ne) + exp(m - nw) + exp(m - se) + exp(m - sw));
    return m - log(t);
}

// The change a cell takes, and the new value; BLOCKED_W "no value yet" takes its target.
__device__ __forceinline__ REAL moved(REAL old, REAL t, REAL omega, float* worst) {
    if (t >= BLOCKED_W) return BLOCKED_W;
    if (old >= BLOCKED_W) return t;
    // Changes within a few roundings of w are noise, not a residual: float32 holds w ~ 1000
    // to 1e-4, the tolerance itself.
    *worst = fmaxf(*worst, (float)(fabs(t - old) - 4 * REAL_EPS * old));
    REAL v = old + omega * (t - old);
    return v < (REAL)0 ? (REAL)0 : v;
}

// The paper's Idx of every cell: the neighbour (0..8) of lowest w, strictly below its own;
// 4 (itself) where none is (the goal, a pocket's bottom, an obstacle's cells). A free cell
// left at 4 (a pit) or still without a value is listed for the host's fill (fill.py).
__device__ void write_idx(const REAL* w, const unsigned char* fixed, signed char* idx,
                          int height, int width, long long first, long long stride,
                          int* pit_list, unsigned* pit_count) {
    for (long long k = first; k < (long long)height * width; k += stride) {
        int i = (int)k, r = i / width, c = i % width, best = 4;
        if (r > 0 && r < height - 1 && c > 0 && c < width - 1) {
            REAL wb = w[i];
            for (int d = 0; d < 9; ++d) {
                REAL v = w[i + (d / 3 - 1) * width + d % 3 - 1];
                if (v < wb) { wb = v; best = d; }
            }
            if (wb >= BLOCKED_W) best = 4;
            if ((best == 4 || w[i] >= BLOCKED_W) && !fixed[i]) pit_list[atomicAdd(pit_count, 1u)] = i;
        }
        idx[i] = (signed char)best;
    }
}

__device__ void reduce_max(float v, unsigned* slot) {
    // Non-negative floats order as their bit patterns do: an unsigned atomicMax is a max.
    __shared__ float s_max;
    if (threadIdx.x == 0) s_max = 0.0f;
    __syncthreads();
    atomicMax((unsigned*)&s_max, __float_as_uint(v));
    __syncthreads();
    if (threadIdx.x == 0 && s_max > 0.0f) atomicMax(slot, __float_as_uint(s_max));
}

// Whether this thread's cells include a free one with no strictly lower neighbour (a pit:
// the descent would stop there); relax.py's has_pit over the thread's share.
__device__ bool has_pit(const REAL* w, const unsigned char* fixed, int height, int width,
                        long long first, long long stride) {
    const int ih = height - 2, iw = width - 2;
    for (long long k = first; k < (long long)ih * iw; k += stride) {
        int i = (int)((k / iw + 1) * width + k % iw + 1);
        if (fixed[i]) continue;
        REAL wi = w[i];
        bool lower = false;
        for (int d = 0; d < 9 && !lower; ++d) lower = w[i + (d / 3 - 1) * width + d % 3 - 1] < wi;
        if (!lower) return true;
    }
    return false;
}

// The queued changes of a step, in the launch that relaxes after them (one launch and one
// copy a step, not two scatters per kind of change): code 2 after a grid barrier, so the
// goal's zero wins over its own "newly reachable" entry.
__device__ void apply_changes(cg::grid_group& grid, REAL* w, unsigned char* fixed,
                              const int* changes, int n_changes, int late, long long first,
                              long long stride) {
    for (int pass = 0; pass < (late ? 2 : 1); ++pass) {
        for (long long k = first; k < n_changes; k += stride) {
            const int code = changes[k] & 3, cell = changes[k] >> 2;
            if ((code == 2) != (pass == 1)) continue;
            w[cell] = code == 2 ? (REAL)0 : BLOCKED_W;
            fixed[cell] = code != 1;
        }
        grid.sync();
    }
}

extern "C" __global__ void harmonic_relax(REAL* w, unsigned char* fixed, REAL* prev,
                                          int height, int width, int jacobi, REAL omega,
                                          int max_sweeps, int check_every, float tol,
                                          unsigned* worst, int* result, signed char* idx,
                                          int budget, unsigned* pits, int* pit_list,
                                          const int* changes, int n_changes, int late) {
    cg::grid_group grid = cg::this_grid();
    const long long stride = (long long)gridDim.x * blockDim.x;
    const long long first = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (n_changes > 0) apply_changes(grid, w, fixed, changes, n_changes, late, first, stride);
    const int ih = height - 2, iw = width - 2;  // the padded ring never moves
    int done = 0, checks = 0, settled = 0;
    float residual = __int_as_float(0x7f800000);  // +inf (NVRTC has no math.h)
    while (done < max_sweeps) {
        const bool check = (done + 1) % check_every == 0 || done + 1 == max_sweeps;
        float mine = 0.0f;
        if (jacobi) {
            for (long long k = first; k < (long long)height * width; k += stride) prev[k] = w[k];
            grid.sync();
            for (long long k = first; k < (long long)ih * iw; k += stride) {
                int i = (int)((k / iw + 1) * width + k % iw + 1);
                if (fixed[i]) continue;
                w[i] = moved(w[i], target(prev, i, width), (REAL)1, &mine);
            }
            grid.sync();
        } else {
            for (int colour = 0; colour < 4; ++colour) {
                const int rp = colour >> 1, cp = colour & 1;
                const int nr = (ih - rp + 1) / 2, nc = (iw - cp + 1) / 2;
                for (long long k = first; k < (long long)nr * nc; k += stride) {
                    int i = (int)((1 + rp + 2 * (k / nc)) * width + 1 + cp + 2 * (k % nc));
                    if (fixed[i]) continue;
                    w[i] = moved(w[i], target(w, i, width), omega, &mine);
                }
                grid.sync();
            }
        }
        ++done;
        if (check) {
            unsigned* slot = worst + (checks & 1);
            reduce_max(mine, slot);
            // Past the step's budget, a field without a pit is good enough to stop on.
            const bool look = done >= budget;  // the same in every thread
            unsigned* pit = pits + checks % 3;
            if (look) {
                // The slot after this one was read two checks ago (grid syncs since); it is
                // written next check, after this check's sync.
                if (first == 0) pits[(checks + 1) % 3] = 0u;
                if (__syncthreads_or(has_pit(w, fixed, height, width, first, stride)) &&
                    threadIdx.x == 0)
                    atomicOr(pit, 1u);
            }
            grid.sync();
            residual = __uint_as_float(*(volatile unsigned*)slot);
            const bool pitted = look && *(volatile unsigned*)pit != 0u;
            // The other slot is the next check's; nobody reads it until after two syncs.
            if (first == 0) worst[(checks & 1) ^ 1] = 0u;
            ++checks;
            if (residual < tol) break;
            if (look && !pitted) {
                settled = 1;
                break;
            }
        }
    }
    // pits[3] counts the listed pits.
    write_idx(w, fixed, idx, height, width, first, stride, pit_list, pits + 3);
    grid.sync();
    if (first == 0) {
        result[0] = done;
        result[1] = (int)__float_as_uint(residual);
        result[2] = settled || residual < tol;
        result[3] = (int)*(volatile unsigned*)(pits + 3);
        // Every thread has read the slots (a grid barrier since): clear them for the next
        // launch here, not with a launch of its own before it. `worst` and `pits` are one
        // array of six words (cuda.py's `flags`).
        for (int k = 0; k < 2; ++k) worst[k] = 0u;
        for (int k = 0; k < 4; ++k) pits[k] = 0u;
    }
}

// A replanning step's fill (fill.py) on the device: the pits' basins (the free cells whose
// Idx chain ends at a pit, found here by pointer jumping) take the smallest field W >= w that
// has, at every basin cell, a
// neighbour at least eps lower — W(c) = max(w(c), min over neighbours W + eps), a cell with no
// value yet taking the second term — the fixed point that Planchon & Darboux (2002) reach by
// iteration and Barnes et al.'s priority-flood by a heap. From W = BLOCKED_W on the basins the
// updates only lower W and every value stays >= the fixed point, in whatever order they come;
// once nothing lowers, W is it (unique: a chain of cells each eps above the next cannot close
// on itself). A cell with a value is never a pit, even mid-way (its lowest neighbour only went
// down since): the only pits a pass cap can leave are cells not reached yet, and write_idx
// lists them for the host.
//
// The passes go by tiles of FILL_TILE² cells, one block each: a tile whose basin cells or
// neighbour tiles changed in the last pass loads itself and its ring of neighbours into shared
// memory and iterates there, a block barrier an iteration, until it is stable against that
// ring; then one grid barrier and the tiles read each other's new borders. A value crosses a
// tile in one pass, not FILL_TILE, so the grid barriers (~3 µs each) fall from about the
// basin's longest chain of cells to its chain of tiles. `lift` (map-sized, -1 off the basins)
// holds each basin cell's w before the fill; `active` (the tiles with basin cells) and
// `stamp` (the last pass a tile changed, -2 never) are left as found. Three flag slots for the
// stop: after pass p's barrier thread 0 clears slot (p + 2) % 3, read before that barrier and
// written again only after the next one (slot (p + 1) % 3 may already be taking a fast
// block's flag).
#define FILL_TILE 32
#define FILL_ROWS (FILL_TILE / 8)  // a block of 256 threads: 32 columns x 8 rows
#define FILL_SPAN (FILL_TILE + 2)

// max(w, m + eps) for a basin cell whose lowest neighbour is m: strictly above m in REAL
// (float32 rounds m + eps back to m past 2^24 eps); lifted < BLOCKED_W is its w before.
__device__ __forceinline__ REAL filled(REAL m, REAL eps, REAL lifted) {
    REAL step = eps, v = m + step;
    while (v <= m) { step *= (REAL)2; v = m + step; }
    return lifted < BLOCKED_W && lifted > v ? lifted : v;
}

// One tile of a fill pass: returns whether it lowered any cell (the same in every thread).
__device__ bool fill_tile(REAL* w, const REAL* lift, int height, int width, int tr, int tc,
                          REAL eps, REAL* s) {
    const int r0 = tr * FILL_TILE - 1, c0 = tc * FILL_TILE - 1;
    for (int k = threadIdx.x; k < FILL_SPAN * FILL_SPAN; k += blockDim.x) {
        const int r = r0 + k / FILL_SPAN, c = c0 + k % FILL_SPAN;
        // Past the map's padded ring: nothing to fall on. __ldcg: other blocks' writes of the
        // last pass, from L2, never a stale line of this multiprocessor's L1.
        s[k] = r >= 0 && r < height && c >= 0 && c < width ? __ldcg(w + r * width + c)
                                                           : BLOCKED_W;
    }
    const int tx = threadIdx.x % FILL_TILE, ty = threadIdx.x / FILL_TILE;
    REAL lifted[FILL_ROWS], loaded[FILL_ROWS];
    __syncthreads();
    for (int j = 0; j < FILL_ROWS; ++j) {
        const int r = r0 + 1 + ty + 8 * j, c = c0 + 1 + tx;
        lifted[j] = r < height && c < width ? lift[r * width + c] : (REAL)-1;
        loaded[j] = s[(ty + 8 * j + 1) * FILL_SPAN + tx + 1];  // what the tile held
    }
    bool any = false;
    while (true) {
        // In place: a neighbour read mid-update is its old value or its new, lower one, both
        // >= the fixed point; an iteration that lowers nothing read only final values.
        bool mine = false;
        for (int j = 0; j < FILL_ROWS; ++j) {
            if (lifted[j] < (REAL)0) continue;
            const int k = (ty + 8 * j + 1) * FILL_SPAN + tx + 1;
            REAL m = BLOCKED_W;
            for (int d = 0; d < 9; ++d)
                if (d != 4) m = fmin(m, s[k + (d / 3 - 1) * FILL_SPAN + d % 3 - 1]);
            if (m >= BLOCKED_W) continue;
            const REAL v = filled(m, eps, lifted[j]);
            if (v < s[k]) { s[k] = v; mine = true; }
        }
        if (!__syncthreads_or(mine)) break;
        any = true;
    }
    if (any)
        for (int j = 0; j < FILL_ROWS; ++j) {
            const REAL v = s[(ty + 8 * j + 1) * FILL_SPAN + tx + 1];
            if (lifted[j] >= (REAL)0 && v < loaded[j])
                w[(r0 + 1 + ty + 8 * j) * width + c0 + 1 + tx] = v;
        }
    __syncthreads();  // s is the block's next tile's
    return any;
}

//
// `gate` (null: none): the pit count of the relaxation this fill was launched behind (its
// result[3], cuda.py's `fill_start`). Zero means that relaxation left no pit, so there is no
// basin: every thread returns at once, before any barrier, and the launch writes nothing —
// not Idx, the pit list or its result words, which the relaxation's stand for (the host reads
// the fill's words only when that count is not zero). The launch reads it on the device, so
// the host need not wait for the sweeps to decide whether to launch the fill.
extern "C" __global__ void __launch_bounds__(256)
harmonic_fill(REAL* w, const unsigned char* fixed, int height, int width, int* down,
              REAL* lift, REAL eps, int max_passes, unsigned* flags, int* result,
              signed char* idx, int* pit_list, unsigned char* active, int* stamp,
              const int* gate) {
    // Written by the launch before this one on the stream, which has ended: a plain load.
    if (gate != nullptr && *gate == 0) return;
    cg::grid_group grid = cg::this_grid();
    __shared__ REAL s[FILL_SPAN * FILL_SPAN];
    __shared__ unsigned s_count;
    const long long stride = (long long)gridDim.x * blockDim.x;
    const long long first = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    const long long n = (long long)height * width;
    const int tiles_x = (width + FILL_TILE - 1) / FILL_TILE;
    const int tiles = tiles_x * ((height + FILL_TILE - 1) / FILL_TILE);
    // The basins (fill.basins on the host): down[i] = (the cell i's Idx chain has reached so
    // far) << 1 | (a pit is on it). A pit (write_idx's: free, Idx 4 or no value yet) ends
    // its chain flagged; a fixed cell or Idx 4 ends it unflagged. Pointer jumping halves every
    // chain's rest a round (log2 of the longest chain rounds, not one per cell). One word a
    // cell, so a read mid-update is a consistent pair, and any pair is on the cell's chain.
    for (long long k = first; k < n; k += stride) {
        const int i = (int)k, d = idx[i];
        const bool pit = !fixed[i] && (d == 4 || w[i] >= BLOCKED_W);
        const int to = fixed[i] || d == 4 ? i : i + (d / 3 - 1) * width + d % 3 - 1;
        down[i] = pit ? (i << 1 | 1) : (to << 1);
    }
    grid.sync();
    for (int round = 0;; ++round) {
        bool mine = false;
        for (long long k = first; k < n; k += stride) {
            const int v = __ldcg(down + k), j = v >> 1;
            if ((v & 1) || j == (int)k) continue;
            const int u = __ldcg(down + j);
            if (u != v) { down[k] = u; mine = true; }
        }
        unsigned* slot = flags + round % 3;
        if (__syncthreads_or(mine) && threadIdx.x == 0) atomicOr(slot, 1u);
        grid.sync();
        const bool any = *(volatile unsigned*)slot != 0u;
        if (first == 0) flags[(round + 2) % 3] = 0u;
        if (!any) break;
    }
    if (threadIdx.x == 0) s_count = 0u;
    __syncthreads();
    for (long long k = first; k < n; k += stride) {
        if (!(__ldcg(down + k) & 1)) continue;
        const int c = (int)k, t = c / width / FILL_TILE * tiles_x + c % width / FILL_TILE;
        lift[c] = w[c];
        w[c] = BLOCKED_W;
        active[t] = 1;
        stamp[t] = -1;  // changed "before pass 0": every basin tile runs first
        atomicAdd(&s_count, 1u);
    }
    __syncthreads();
    if (threadIdx.x == 0 && s_count) atomicAdd(flags + 4, s_count);
    // The passes' slots start clear: the rounds' clears and these are all done by the
    // barrier after them.
    if (first == 0) flags[0] = flags[1] = flags[2] = 0u;
    grid.sync();
    int passes = 0;
    while (passes < max_passes) {
        bool mine = false;
        for (int t = blockIdx.x; t < tiles; t += gridDim.x) {
            if (!__ldcg(active + t)) continue;
            const int tr = t / tiles_x, tc = t % tiles_x;
            // Due when it or a neighbour tile changed in the last pass (or this one, seen
            // early: a change missed now is seen next pass, and it raised this pass's flag).
            bool due = false;
            if (threadIdx.x < 9) {
                const int r = tr + threadIdx.x / 3 - 1, c = tc + threadIdx.x % 3 - 1;
                due = r >= 0 && c >= 0 && c < tiles_x && r * tiles_x + c < tiles &&
                      __ldcg(stamp + r * tiles_x + c) >= passes - 1;
            }
            if (!__syncthreads_or(due)) continue;
            if (fill_tile(w, lift, height, width, tr, tc, eps, s)) {
                mine = true;
                if (threadIdx.x == 0) stamp[t] = passes;
            }
        }
        unsigned* slot = flags + passes % 3;
        if (mine && threadIdx.x == 0) atomicOr(slot, 1u);  // mine is the block's own verdict
        grid.sync();
        const bool any = *(volatile unsigned*)slot != 0u;
        if (first == 0) flags[(passes + 2) % 3] = 0u;
        ++passes;
        if (!any) break;
    }
    for (long long k = first; k < n; k += stride) {
        if (!(__ldcg(down + k) & 1)) continue;
        const int c = (int)k, t = c / width / FILL_TILE * tiles_x + c % width / FILL_TILE;
        lift[c] = (REAL)-1;
        active[t] = 0;
        stamp[t] = -2;
    }
    write_idx(w, fixed, idx, height, width, first, stride, pit_list, flags + 3);
    grid.sync();
    if (first == 0) {
        result[0] = passes;
        result[1] = (int)*(volatile unsigned*)(flags + 4);
        result[3] = (int)*(volatile unsigned*)(flags + 3);
        for (int k = 0; k < 5; ++k) flags[k] = 0u;
    }
}

