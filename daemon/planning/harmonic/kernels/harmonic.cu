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

// A replanning step's fill (fill.py) on the device: the basins' cells `cells[:n]` (the host
// found them from Idx) take the smallest field W >= w that has, at every basin cell, a
// neighbour at least eps lower — W(c) = max(w(c), min over neighbours W + eps), a cell with no
// value yet taking the second term — the fixed point that Planchon & Darboux (2002) reach by
// iteration and Barnes et al.'s priority-flood by a heap. From W = BLOCKED_W on the basins the
// passes only lower W and every value stays >= the fixed point; once a pass lowers nothing,
// W is it (unique: a chain of cells each eps above the next cannot close on itself). A cell
// with a value is never a pit, even mid-way (its lowest neighbour only went down since): the
// only pits a pass cap can leave are cells the passes have not reached yet, and write_idx
// lists them for the host. Three flag slots, as the relaxation's pit check: after pass p's
// barrier thread 0 clears slot (p + 2) % 3, read before that barrier and written again only
// after the next one (slot (p + 1) % 3 may already be taking a fast block's flag).
extern "C" __global__ void harmonic_fill(REAL* w, const unsigned char* fixed, int height,
                                         int width, const int* cells, REAL* orig, int n,
                                         REAL eps, int max_passes, unsigned* flags,
                                         int* result, signed char* idx, int* pit_list) {
    cg::grid_group grid = cg::this_grid();
    const long long stride = (long long)gridDim.x * blockDim.x;
    const long long first = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    for (long long k = first; k < n; k += stride) {
        orig[k] = w[cells[k]];
        w[cells[k]] = BLOCKED_W;
    }
    grid.sync();
    int passes = 0;
    while (passes < max_passes) {
        bool mine = false;
        for (long long k = first; k < n; k += stride) {
            const int c = cells[k];
            REAL m = BLOCKED_W;
            for (int d = 0; d < 9; ++d)
                if (d != 4) m = fmin(m, w[c + (d / 3 - 1) * width + d % 3 - 1]);
            if (m >= BLOCKED_W) continue;
            // Strictly above m in REAL (float32 rounds m + eps back to m past 2^24 eps).
            REAL step = eps, v = m + step;
            while (v <= m) { step *= (REAL)2; v = m + step; }
            const REAL o = orig[k];
            if (o < BLOCKED_W && o > v) v = o;
            if (v < w[c]) { w[c] = v; mine = true; }
        }
        unsigned* slot = flags + passes % 3;
        if (__syncthreads_or(mine) && threadIdx.x == 0) atomicOr(slot, 1u);
        grid.sync();
        const bool any = *(volatile unsigned*)slot != 0u;
        if (first == 0) flags[(passes + 2) % 3] = 0u;
        ++passes;
        if (!any) break;
    }
    write_idx(w, fixed, idx, height, width, first, stride, pit_list, flags + 3);
    grid.sync();
    if (first == 0) {
        result[0] = passes;
        result[3] = (int)*(volatile unsigned*)(flags + 3);
        for (int k = 0; k < 4; ++k) flags[k] = 0u;
    }
}
