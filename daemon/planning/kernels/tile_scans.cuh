// In-tile min-plus scans for fast.cu (included there; SCANS >= 1).
//
// A warp holds one line of 32 cells of the tile in shared memory (a row, a column or a
// diagonal) and gives every cell min over its segment of g[l'] + step * |l - l'|, so a
// straight or diagonal run of free cells settles in one pass instead of one cell per sweep.

#pragma once

#if SCANS >= 1
// Segmented min-plus scan along one line of 32 cells held by a warp: every cell gets
// min over cells of its segment of g[l'] + step * |l - l'|. A segment ends at a blocked
// cell or where the line leaves the tile (wrap of a diagonal).
__device__ __forceinline__ int line_scan(int gv, bool blk, bool head, bool tail, int step) {
    int lane = threadIdx.x & 31;
    // forward: min over l' <= l of g[l'] - step*l', then + step*l
    int v = blk ? BIG : gv - step * lane;
    int f = head ? 1 : 0;
    for (int d = 1; d < 32; d <<= 1) {
        int v2 = __shfl_up_sync(FULL, v, d);
        int f2 = __shfl_up_sync(FULL, f, d);
        if (lane >= d) {
            if (!f) v = min(v, v2);
            f |= f2;
        }
    }
    int best = v + step * lane;
    // backward: min over l' >= l of g[l'] + step*l', then - step*l
    v = blk ? BIG : gv + step * lane;
    f = tail ? 1 : 0;
    for (int d = 1; d < 32; d <<= 1) {
        int v2 = __shfl_down_sync(FULL, v, d);
        int f2 = __shfl_down_sync(FULL, f, d);
        if (lane + d < 32) {
            if (!f) v = min(v, v2);
            f |= f2;
        }
    }
    return min(best, v - step * lane);
}

// Scan family `dir` (0 rows, 1 columns, 2 diagonals, 3 anti-diagonals): warp w takes line w,
// lane l its l-th cell. Returns whether this thread's cell decreased.
__device__ __forceinline__ bool scan_lines(int dir, int (*gs)[HT], unsigned char (*bs)[TILE + 1]) {
    int w = threadIdx.x >> 5, l = threadIdx.x & 31;
    int y, x, step;
    bool head, tail;
    if (dir == 0) { y = w; x = l; step = 10; head = l == 0; tail = l == 31; }
    else if (dir == 1) { y = l; x = w; step = 10; head = l == 0; tail = l == 31; }
    else if (dir == 2) {
        y = l; x = (w + l) & 31; step = 14;
        head = l == 0 || x == 0; tail = l == 31 || x == 31;
    } else {
        y = l; x = (w - l) & 31; step = 14;
        head = l == 0 || x == 31; tail = l == 31 || x == 0;
    }
    bool blk = bs[y][x] != 0;
    // A blocked cell is its own segment: it neither passes nor takes a value.
    bool prev_blk = __shfl_up_sync(FULL, blk ? 1 : 0, 1) != 0;
    bool next_blk = __shfl_down_sync(FULL, blk ? 1 : 0, 1) != 0;
    head = head || blk || (l > 0 && prev_blk);
    tail = tail || blk || (l < 31 && next_blk);
    int gv = gs[y + 1][x + 1];
    int cand = line_scan(gv, blk, head, tail, step);
    if (!blk && cand < gv) {
        gs[y + 1][x + 1] = cand;
        return true;
    }
    return false;
}
#endif
