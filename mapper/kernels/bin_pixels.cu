// The mapper's per-pixel pass (binning.py's _bin_pixels) as one CUDA kernel, and the pass
// that reads back, per bearing bin, the point that won. Keys pack a squared range (float32
// bits: non-negative floats order as their bits) above a pixel index, so one 64-bit
// atomicMin keeps the nearest obstacle point and, on a tie, the first pixel in raster order,
// as the CPU loop does; the farthest free point is an atomicMax with the index inverted.
// P: fx fy cx cy | rot[9] | t[3] | floor_z min_h max_h max_range min_depth cell_m push scale
//    | r0 c0 (the window's corner, whole numbers: a parameter, not an argument, so a captured
//    graph serves every window) | tan_limit (binning.TAN_LIMIT). P and the depth come up in one
//    copy; the bearing bins' yaw and span (binning.bearing_bins) are worked out here, per block.

#ifdef DEPTH_FLOAT
typedef float D;  // depth in metres
#else
typedef unsigned short D;  // depth in units of depth_scale (millimetres)
#endif

#define FX P[0]
#define FY P[1]
#define CX P[2]
#define CY P[3]
#define ROT(i, j) P[4 + 3 * (i) + (j)]
#define T(i) P[13 + (i)]
#define FLOOR_Z P[16]
#define MIN_H P[17]
#define MAX_H P[18]
#define MAX_RANGE P[19]
#define MIN_DEPTH P[20]
#define CELL P[21]
#define PUSH P[22]
#define SCALE P[23]
#define R0 ((int)P[24])
#define C0 ((int)P[25])
#define TAN_LIMIT P[26]

__device__ bool point_of(D raw, int idx, int w, const double* P, double& dx, double& dy,
                         double& pz) {
    double d = (double)raw * SCALE;
    if (!(d >= MIN_DEPTH) || d > 1e4) return false;  // 0, too near, NaN or inf: missing
    int v = idx / w, u = idx - v * w;
    double rx = (u - CX) / FX, ry = (v - CY) / FY;
    dx = (ROT(0, 0) * rx + ROT(0, 1) * ry + ROT(0, 2)) * d;
    dy = (ROT(1, 0) * rx + ROT(1, 1) * ry + ROT(1, 2)) * d;
    pz = (ROT(2, 0) * rx + ROT(2, 1) * ry + ROT(2, 2)) * d + T(2) - FLOOR_Z;
    return true;
}

// A pixel the frame check (frame.count_valid) counts: non-zero, or finite and positive. On
// the bits, for floats: a compare flushes subnormals to zero here (seen on the H100: 18 071
// pixels of 1e-40 not counted), and numpy on the host counts them.
__device__ bool present(D raw) {
#ifdef DEPTH_FLOAT
    return __float_as_uint(raw) - 1u < 0x7f7fffffu;  // 0x00000001 (tiniest) .. 0x7f7fffff (max)
#else
    return raw != 0;
#endif
}

// binning.bearing_bins: the camera's yaw (cos, sin) seen from above and the largest |tan| of
// a pixel's bearing from it, at the image's four corners; the same operations in the same order.
__device__ void bearing_bins(const double* P, int w, int h, double* out) {
    double ax = ROT(0, 2), ay = ROT(1, 2), n = sqrt(ax * ax + ay * ay);
    double c = n > 0 ? ax / n : 1.0, s = n > 0 ? ay / n : 0.0, tan_max = 1e-3;
    for (int k = 0; k < 4; ++k) {
        double rx = ((k & 1 ? w - 1.0 : 0.0) - CX) / FX, ry = ((k & 2 ? h - 1.0 : 0.0) - CY) / FY;
        double x = ROT(0, 0) * rx + ROT(0, 1) * ry + ROT(0, 2);
        double y = ROT(1, 0) * rx + ROT(1, 1) * ry + ROT(1, 2);
        double fwd = x * c + y * s, side = -x * s + y * c;
        tan_max = fmax(tan_max, fwd > 0 ? fabs(side) / fwd : TAN_LIMIT);
    }
    out[0] = c;
    out[1] = s;
    out[2] = fmin(tan_max, TAN_LIMIT) * (1.0 + 1e-6);
}

// binning.bearing_bin: the bin of the point's bearing from the camera's yaw (B: bearing_bins).
__device__ int bearing_bin(double dx, double dy, const double* B, int bins) {
    double fwd = dx * B[0] + dy * B[1], side = dy * B[0] - dx * B[1];
    double t = fwd > 0 ? side / fwd : (side > 0 ? B[2] : -B[2]);
    int b = (int)((t + B[2]) * (bins / (2.0 * B[2])));
    return min(max(b, 0), bins - 1);
}

__device__ unsigned long long key(float r2, unsigned int low) {
    return ((unsigned long long)__float_as_uint(r2) << 32) | low;
}

extern "C" __global__ void bin_pixels(const D* depth, int h, int w, const double* P, int side,
                           int map_rows, int bins, int* counts,
                           unsigned long long* hit_key, unsigned long long* far_key, int* valid,
                           int* present_count) {
    __shared__ double bearing[3];
    if (threadIdx.x == 0) bearing_bins(P, w, h, bearing);
    __syncthreads();
    int idx = blockIdx.x * blockDim.x + threadIdx.x;
    double dx, dy, pz;
    D raw = idx < h * w ? depth[idx] : (D)0;
    bool ok = idx < h * w && point_of(raw, idx, w, P, dx, dy, pz);
    unsigned int mask = __ballot_sync(0xffffffffu, ok);
    unsigned int there = __ballot_sync(0xffffffffu, present(raw));
    if ((threadIdx.x & 31) == 0 && mask) atomicAdd(valid, __popc(mask));
    if ((threadIdx.x & 31) == 0 && there) atomicAdd(present_count, __popc(there));
    if (!ok) return;
    double r2 = dx * dx + dy * dy, max_r2 = MAX_RANGE * MAX_RANGE, inv = 1.0 / CELL;
    int b = bearing_bin(dx, dy, bearing, bins);
    if (r2 > max_r2) {  // past the range: free as far as the range
        atomicMax(far_key + b, key((float)max_r2, 0xffffffffu - idx));
        return;
    }
    int top = map_rows - 1 - R0, c0 = C0;
    if (pz < MIN_H) {
        atomicMax(far_key + b, key((float)r2, 0xffffffffu - idx));
        int row = top - (int)floor((T(1) + dy) * inv), col = (int)floor((T(0) + dx) * inv) - c0;
        if (row >= 0 && row < side && col >= 0 && col < side)
            atomicAdd(counts + side * side + row * side + col, 1);
    } else if (pz <= MAX_H) {
        atomicMin(hit_key + b, key((float)r2, idx));
        double k = 1.0 + PUSH / sqrt(r2 + 1e-12);  // a face on a boundary: the cell behind
        int row = top - (int)floor((T(1) + dy * k) * inv);
        int col = (int)floor((T(0) + dx * k) * inv) - c0;
        if (row >= 0 && row < side && col >= 0 && col < side)
            atomicAdd(counts + row * side + col, 1);
    }
}

// One thread per bin: the winning pixel's squared range and point (x, y), -1/inf when none.
extern "C" __global__ void read_bins(const D* depth, int w, const double* P, int bins,
                          const unsigned long long* hit_key, const unsigned long long* far_key,
                          double* hit, double* far) {
    int b = blockIdx.x * blockDim.x + threadIdx.x;
    if (b >= bins) return;
    double dx, dy, pz, max_r2 = MAX_RANGE * MAX_RANGE;
    unsigned long long hk = hit_key[b], fk = far_key[b];
    hit[3 * b] = __longlong_as_double(0x7ff0000000000000ULL);  // inf
    far[3 * b] = -1.0;
    if (hk != 0xffffffffffffffffULL) {
        int idx = (int)(hk & 0xffffffffu);
        point_of(depth[idx], idx, w, P, dx, dy, pz);
        hit[3 * b] = dx * dx + dy * dy;
        hit[3 * b + 1] = T(0) + dx;
        hit[3 * b + 2] = T(1) + dy;
    }
    if (fk != 0ULL) {
        int idx = (int)(0xffffffffu - (unsigned int)(fk & 0xffffffffu));
        point_of(depth[idx], idx, w, P, dx, dy, pz);
        double r2 = dx * dx + dy * dy, k = 1.0;
        if (r2 > max_r2) {
            k = MAX_RANGE / sqrt(r2);
            r2 = max_r2;
        }
        far[3 * b] = r2;
        far[3 * b + 1] = T(0) + dx * k;
        far[3 * b + 2] = T(1) + dy * k;
    }
}
