// merge.py's merge_frame on the device, run in the frame's CUDA graph after bin_pixels and
// read_bins: the clearing rays, the range-noise tails, the log-odds update with its
// hysteresis, the forgetting and the frame's proximity, against the global map kept on the
// device. Only the changed cells leave, compacted in merge_frame's order (the window's
// changes row by row, then the forgotten cells in flat order), each one word (flat index << 2 |
// value), with the proximity's figures. Last it resets the pass's counts and bin keys for the
// next frame, so the graph holds no memsets: five nodes (the upload, three kernels, one
// read-back), and each node costs the host's launch time.
// One block: the window is a few thousand cells, and one block can order its output with a
// scan and reduce its nearest cell without a second launch.
//
// Compiled with --fmad=false: every product and sum rounds as numba's (which never fuses
// them), so on the same counts and points the map, the changes and the proximity are the
// CPU's to the bit (tests/mapper/cuda/test_cuda_merge.py).
//
// P (bin_pixels.cu's, extended): T(0), T(1) the camera's x, y; CELL; R0, C0 the window's
// corner; then, per frame: cos and sin of the heading, the camera's window row and column
// (merge_frame's cam_row, cam_col), the stamp, forget_before (-inf: not this frame), the
// pixels check_depth needs, whether check_motion passed, the host's pixel count (-1: take
// the device's); once per pass: min_points, min_share, tail_share, l_hit, l_pass, l_occupied,
// l_free, l_min, l_max, corridor, the tails' beyond-cos.

#define T(i) P[13 + (i)]
#define CELL P[21]
#define R0 ((int)P[24])
#define C0 ((int)P[25])
#define COS_H P[27]
#define SIN_H P[28]
#define CAM_ROW P[29]
#define CAM_COL P[30]
#define STAMP P[31]
#define FORGET_BEFORE P[32]
#define NEED_PRESENT P[33]
#define MOTION_OK P[34]
#define HOST_PRESENT P[35]
#define MIN_POINTS P[36]
#define MIN_SHARE P[37]
#define TAIL_SHARE P[38]
#define L_HIT P[39]
#define L_PASS P[40]
#define L_OCCUPIED P[41]
#define L_FREE P[42]
#define L_MIN P[43]
#define L_MAX P[44]
#define CORRIDOR P[45]
#define BEYOND_COS P[46]

#define THREADS 512  // the block: cuda_merge.MERGE_THREADS
#define FREE 0
#define OCCUPIED 1
#define UNKNOWN 2
#define HEAD_INTS 14  // k, g, valid, present, committed, pad | ahead, nearest, side, fwd

// What one window cell of the frame does to the map (merge_frame's loop body): seen (a hit
// or cleared), its new log-odds and value.
struct Cell {
    bool seen;
    float v;
    unsigned char value, old;
};

__device__ Cell cell_of(int i, int flat, const int* obst, const int* flo,
                        const unsigned char* fr, const unsigned char* occd,
                        const unsigned char* tl, const unsigned char* occ, const float* lo,
                        const double* P) {
    Cell o;
    bool is_hit = occd[i] && !tl[i];
    bool floor_seen = flo[i] >= MIN_POINTS;
    // Floor seen with nothing standing in it is free whatever the rays say; a tail whose
    // floor is seen is a pass (merge.py says why).
    bool cleared = (obst[i] == 0 && (fr[i] != 0 || floor_seen)) || (tl[i] && floor_seen);
    o.seen = is_hit || cleared;
    o.old = occ[flat];
    o.value = o.old;
    o.v = 0.0f;
    if (!o.seen) return o;
    bool passes = cleared && (o.old != OCCUPIED || floor_seen);
    float v = lo[flat];
    if (is_hit) v = v + (float)L_HIT;
    if (passes) v = v + (float)L_PASS;
    v = fminf(fmaxf(v, (float)L_MIN), (float)L_MAX);
    if (v >= (float)L_OCCUPIED)
        o.value = OCCUPIED;
    else if (v <= (float)L_FREE)
        o.value = FREE;
    o.v = v;
    return o;
}

// binning.clear_rays for one bearing bin: 1 where its ray passed before its first hit.
__device__ void clear_ray(int b, const double* hit, const double* far, const double* P,
                          int side, int map_rows, unsigned char* fr) {
    double tx, ty, end, cam_x = T(0), cam_y = T(1), cell = CELL;
    double step = cell * 0.5, inv = 1.0 / cell, clearance = 0.5 * cell;
    if (hit[3 * b] < __longlong_as_double(0x7ff0000000000000ULL)) {
        tx = hit[3 * b + 1];
        ty = hit[3 * b + 2];
        end = sqrt(hit[3 * b]) - clearance;
    } else if (far[3 * b] >= 0.0) {
        tx = far[3 * b + 1];
        ty = far[3 * b + 2];
        end = sqrt(far[3 * b]);
    } else {
        return;
    }
    double ex = tx - cam_x, ey = ty - cam_y, full = sqrt(ex * ex + ey * ey);
    if (full <= 0.0 || end <= 0.0) return;
    double ux = ex / full, uy = ey / full;
    int n = (int)(end / step) + 1;
    for (int i = 0; i < n; ++i) {
        double s = fmin(i * step, end), x = cam_x + ux * s, y = cam_y + uy * s;
        int row = map_rows - 1 - (int)floor(y * inv) - R0;
        int col = (int)floor(x * inv) - C0;
        if (row >= 0 && row < side && col >= 0 && col < side) fr[row * side + col] = 1;
    }
}

// evidence._tails for one cell: fewer obstacle points than TAIL_SHARE of the most in a
// neighbour beyond it along the ray.
__device__ unsigned char tail_of(int r, int c, int side, const int* obst, const double* P) {
    int own = obst[r * side + c];
    if (own <= 0) return 0;
    double dr0 = r - CAM_ROW, dc0 = c - CAM_COL;
    double norm = sqrt(dr0 * dr0 + dc0 * dc0) + 1e-6, ur = dr0 / norm, uc = dc0 / norm;
    int best = 0;
    for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
            int rr = r + dr, cc = c + dc;
            if ((dr == 0 && dc == 0) || rr < 0 || rr >= side || cc < 0 || cc >= side) continue;
            if ((ur * dr + uc * dc) / sqrt((double)(dr * dr + dc * dc)) > BEYOND_COS)
                best = max(best, obst[rr * side + cc]);
        }
    return own < TAIL_SHARE * best;
}

// An exclusive prefix sum of each thread's count over the block (Hillis-Steele), and the total.
__device__ int block_scan(int mine, int* buf, int& total) {
    int t = threadIdx.x;
    buf[t] = mine;
    __syncthreads();
    for (int off = 1; off < THREADS; off <<= 1) {
        int add = t >= off ? buf[t - off] : 0;
        __syncthreads();
        buf[t] += add;
        __syncthreads();
    }
    int incl = buf[t];
    total = buf[THREADS - 1];
    __syncthreads();
    return incl - mine;
}

// out: bin_pixels' counts (obstacle, floor), valid, present, then read_bins' hit and far.
// scratch: 3 side^2 bytes (rays, occupied, tails). head: HEAD_INTS ints (the doubles from
// head + 6), then the changes' words, the window's then the forgotten ones.
extern "C" __global__ void __launch_bounds__(THREADS)
merge_cells(int* out, const double* P, int side, int bins, int map_rows, int map_cols,
            unsigned char* occ, float* lo, double* seen_at, const unsigned char* fixed,
            unsigned char* scratch, int* head, unsigned long long* hit_key,
            unsigned long long* far_key) {
    __shared__ int scan[THREADS];
    __shared__ double best_d[THREADS], best_a[THREADS];
    __shared__ int best_i[THREADS];
    int t = threadIdx.x, n = side * side;
    const int *obst = out, *flo = out + n;
    const double* hit = (const double*)(out + 2 * n + 2);
    const double* far = hit + 3 * bins;
    unsigned char *fr = scratch, *occd = scratch + n, *tl = scratch + 2 * n;
    unsigned int* cells = (unsigned int*)(head + HEAD_INTS);
    int valid = out[2 * n], present = HOST_PRESENT >= 0.0 ? (int)HOST_PRESENT : out[2 * n + 1];
    // check_depth and check_motion: a refused frame leaves the map as it was.
    bool commit = MOTION_OK != 0.0 && !(present < NEED_PRESENT);

    for (int i = t; i < n; i += THREADS) {
        int o = obst[i];
        occd[i] = o >= MIN_POINTS && o >= MIN_SHARE * (o + flo[i]);
        fr[i] = 0;
    }
    __syncthreads();
    for (int b = t; b < bins; b += THREADS) clear_ray(b, hit, far, P, side, map_rows, fr);
    for (int i = t; i < n; i += THREADS) tl[i] = tail_of(i / side, i % side, side, obst, P);

    // proximity.nearest_cells: the nearest cell edge (first in raster order on a tie), the
    // nearest ahead in the corridor; the bearing is the host's atan2 of the winner's side, fwd.
    double cell = CELL, ch = COS_H, sh = SIN_H, inf = __longlong_as_double(0x7ff0000000000000ULL);
    double nearest = inf, ahead = inf;
    int who = -1;
    for (int i = t; i < n; i += THREADS) {
        if (!occd[i]) continue;
        int r = i / side, c = i % side;
        double cx = (c + C0 + 0.5) * cell - T(0), cy = (map_rows - (r + R0) - 0.5) * cell - T(1);
        double dist = fmax(sqrt(cx * cx + cy * cy) - cell / 2, 0.0);
        double fwd = cx * ch + cy * sh, sd = -cx * sh + cy * ch;
        if (dist < nearest) nearest = dist, who = i;
        if (fwd > -cell / 2 && fabs(sd) <= CORRIDOR + cell / 2)
            ahead = fmin(ahead, fmax(fwd - cell / 2, 0.0));
    }
    best_d[t] = nearest, best_a[t] = ahead, best_i[t] = who;
    __syncthreads();
    for (int half = THREADS / 2; half > 0; half >>= 1) {
        if (t < half) {
            double d = best_d[t + half];
            int i = best_i[t + half];
            if (d < best_d[t] || (d == best_d[t] && i >= 0 && (best_i[t] < 0 || i < best_i[t])))
                best_d[t] = d, best_i[t] = i;
            best_a[t] = fmin(best_a[t], best_a[t + half]);
        }
        __syncthreads();
    }

    // The window's changes, each thread a run of the window's cells in the map, in order.
    int ra = max(0, R0), rb = min(map_rows, R0 + side), ca = max(0, C0), cb = min(map_cols, C0 + side);
    int wc = max(0, cb - ca), cn = max(0, rb - ra) * wc, per = (cn + THREADS - 1) / THREADS;
    int j0 = min(cn, t * per), j1 = min(cn, j0 + per), mine = 0;
    for (int j = j0; j < j1; ++j) {
        int mr = ra + j / wc, mc = ca + j % wc;
        Cell x = cell_of((mr - R0) * side + mc - C0, mr * map_cols + mc, obst, flo, fr, occd,
                         tl, occ, lo, P);
        mine += x.seen && x.value != x.old;
    }
    int k, at = block_scan(mine, scan, k);
    for (int j = j0; j < j1; ++j) {
        int mr = ra + j / wc, mc = ca + j % wc, flat = mr * map_cols + mc;
        Cell x = cell_of((mr - R0) * side + mc - C0, flat, obst, flo, fr, occd, tl, occ, lo, P);
        if (x.seen && x.value != x.old) cells[at++] = (unsigned int)flat << 2 | x.value;
    }

    // The forgotten: obstacles not fixed, not seen since forget_before and not seen now.
    int m = map_rows * map_cols, g = 0;
    bool forget = FORGET_BEFORE > -inf;
    int fper = forget ? (m + THREADS - 1) / THREADS : 0;
    int f0 = min(m, t * fper), f1 = min(m, f0 + fper);
    mine = 0;
    for (int pass = 0; pass < 2; ++pass) {
        for (int f = f0; f < f1; ++f) {
            if (occ[f] != OCCUPIED || fixed[f] || !(seen_at[f] < FORGET_BEFORE)) continue;
            int mr = f / map_cols, mc = f % map_cols;
            if (mr >= ra && mr < rb && mc >= ca && mc < cb &&
                cell_of((mr - R0) * side + mc - C0, f, obst, flo, fr, occd, tl, occ, lo, P).seen)
                continue;
            if (pass == 0)
                ++mine;
            else
                cells[at++] = (unsigned int)f << 2 | UNKNOWN;
        }
        if (pass == 0) at = k + block_scan(mine, scan, g);
    }
    __syncthreads();  // every read of the old map is done: only now does it change

    if (commit) {
        for (int j = j0; j < j1; ++j) {
            int mr = ra + j / wc, mc = ca + j % wc, flat = mr * map_cols + mc;
            Cell x = cell_of((mr - R0) * side + mc - C0, flat, obst, flo, fr, occd, tl, occ, lo,
                             P);
            if (!x.seen) continue;
            lo[flat] = x.v;
            seen_at[flat] = STAMP;
            occ[flat] = x.value;  // this thread's own cell: read above, no one else's
        }
        __syncthreads();
        for (int i = k + t; i < k + g; i += THREADS) {
            occ[cells[i] >> 2] = UNKNOWN;
            lo[cells[i] >> 2] = 0.0f;  // forgotten
        }
    }
    __syncthreads();  // every read of this frame's counts is done: ready them for the next
    for (int i = t; i < 2 * n + 2; i += THREADS) out[i] = 0;
    for (int b = t; b < bins; b += THREADS) hit_key[b] = 0xffffffffffffffffULL, far_key[b] = 0ULL;
    if (t == 0) {
        head[0] = k, head[1] = g, head[2] = valid, head[3] = present, head[4] = commit;
        double* hd = (double*)(head + 6);
        int i = best_i[0];
        double cx = 0, cy = 0;
        if (i >= 0) {
            int r = i / side, c = i % side;
            cx = (c + C0 + 0.5) * cell - T(0), cy = (map_rows - (r + R0) - 0.5) * cell - T(1);
        }
        hd[0] = best_a[0] < inf ? best_a[0] : __longlong_as_double(0x7ff8000000000000ULL);
        hd[1] = i >= 0 ? best_d[0] : __longlong_as_double(0x7ff8000000000000ULL);
        hd[2] = i >= 0 ? -cx * sh + cy * ch : __longlong_as_double(0x7ff8000000000000ULL);
        hd[3] = i >= 0 ? cx * ch + cy * sh : __longlong_as_double(0x7ff8000000000000ULL);
    }
}
