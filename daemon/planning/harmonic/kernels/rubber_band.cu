// Hong & DeSouza's rubber band on the GPU (§IV, Figure 4: one thread per band point).
//
// The same iteration as rubber_band.py's band_iterations, point for point: every inner point
// judges the 9 moves of step delta (its own place included) by the tension of its two
// neighbours plus the harmonic force relative to its own potential, exp(w(x^) - w(x_i)) - 1,
// and takes the least, unless the new point or a segment to a neighbour is blocked. All
// points move from the last iteration's positions (two buffers), so the result does not
// depend on the order threads run in. One block runs every iteration (the band of a guidance
// call is a few hundred points; threads stride over longer ones), with block barriers only:
// one launch per band. W is the field's float type (-DW=float|double); arithmetic is double.
#ifndef W
#define W float
#endif
#define BLOCKED_W 1.0e30

struct Field {
    const W* w;
    const unsigned char* blocked;
    int h, width, pad;  // w is (h + 2 pad) x (width + 2 pad): the planner's padded field
    __device__ double at(int r, int c) const {
        return (double)w[(long long)(r + pad) * (width + 2 * pad) + c + pad];
    }
    __device__ bool free_cell(int r, int c) const {
        return r >= 0 && r < h && c >= 0 && c < width && !blocked[(long long)r * width + c];
    }
    // w between cell centres, bilinear; a blocked or outside corner counts `cap`.
    __device__ double w_at(double r, double c, double cap) const {
        double y = r - 0.5, x = c - 0.5;
        int r0 = (int)floor(y), c0 = (int)floor(x);
        double fy = y - r0, fx = x - c0, total = 0.0;
        for (int dr = 0; dr < 2; ++dr)
            for (int dc = 0; dc < 2; ++dc) {
                int rr = r0 + dr, cc = c0 + dc;
                double v = cap;
                if (rr >= 0 && rr < h && cc >= 0 && cc < width && at(rr, cc) < cap) v = at(rr, cc);
                total += (dr ? fy : 1.0 - fy) * (dc ? fx : 1.0 - fx) * v;
            }
        return total;
    }
    // The segment stays on free cells (sampled every 0.1 cell, both ends in).
    __device__ bool free_line(double r0, double c0, double r1, double c1) const {
        int n = (int)ceil(10.0 * fmax(fabs(r1 - r0), fabs(c1 - c0)));
        n = n < 1 ? 1 : n;
        for (int k = 0; k <= n; ++k) {
            double t = (double)k / n;
            if (!free_cell((int)floor(r0 + t * (r1 - r0)), (int)floor(c0 + t * (c1 - c0))))
                return false;
        }
        return true;
    }
};

extern "C" __global__ void rubber_band(double* pts, double* spare, int k, const W* w,
                                       const unsigned char* blocked, int h, int width,
                                       int pad, double delta, int iterations, double tol,
                                       int* done_out) {
    const Field f{w, blocked, h, width, pad};
    __shared__ float s_worst;
    for (int j = threadIdx.x; j < 2 * k; j += blockDim.x) spare[j] = pts[j];  // the ends
    double* cur = pts;
    double* nxt = spare;
    int done = 0;
    for (int it = 0; it < iterations; ++it) {
        if (threadIdx.x == 0) s_worst = 0.0f;
        __syncthreads();
        float worst = 0.0f;
        for (int i = 1 + threadIdx.x; i < k - 1; i += blockDim.x) {
            const double pr = cur[2 * i], pc = cur[2 * i + 1];
            // A blocked corner weighs as a potential well above the point's own.
            double cap = 0.0;
            for (int d = 0; d < 9; ++d) {
                int rr = min(h - 1, max(0, (int)pr + d / 3 - 1));
                int cc = min(width - 1, max(0, (int)pc + d % 3 - 1));
                double v = f.at(rr, cc);
                if (v < BLOCKED_W) cap = fmax(cap, v);
            }
            cap += 10.0;
            const double wi = f.w_at(pr, pc, cap);
            const double ar = cur[2 * i - 2], ac = cur[2 * i - 1];
            const double br = cur[2 * i + 2], bc = cur[2 * i + 3];
            double best_r = pr, best_c = pc, best = __longlong_as_double(0x7ff0000000000000LL);
            for (int d = 0; d < 9; ++d) {
                double xr = pr + delta * (d / 3 - 1), xc = pc + delta * (d % 3 - 1);
                if (!f.free_cell((int)floor(xr), (int)floor(xc))) continue;
                double tr = ar + br - 2.0 * xr, tc = ac + bc - 2.0 * xc;
                double force = exp(fmin(f.w_at(xr, xc, cap) - wi, 50.0)) - 1.0;
                double value = hypot(tr, tc) + force;
                if (value < best) { best = value; best_r = xr; best_c = xc; }
            }
            if (f.free_line(ar, ac, best_r, best_c) && f.free_line(best_r, best_c, br, bc)) {
                nxt[2 * i] = best_r;
                nxt[2 * i + 1] = best_c;
                worst = fmaxf(worst, (float)hypot(best_r - pr, best_c - pc));
            } else {
                nxt[2 * i] = pr;
                nxt[2 * i + 1] = pc;
            }
        }
        // Non-negative floats order as their bit patterns do.
        atomicMax((unsigned*)&s_worst, __float_as_uint(worst));
        __syncthreads();
        const float moved = s_worst;
        double* t = cur; cur = nxt; nxt = t;
        ++done;
        __syncthreads();  // every thread has read s_worst before it is cleared
        if (moved < tol) break;
    }
    if (cur != pts)
        for (int j = threadIdx.x; j < 2 * k; j += blockDim.x) pts[j] = cur[j];
    if (threadIdx.x == 0) *done_out = done;
}
