// In-tile min-plus scans for tile_relax.cuh (included there when SCANS >= 1).
//
// A warp holds one line of 32 cells of the tile in shared memory (a row, a column or a
// diagonal) and gives every cell min over its segment of g[l'] + step * |l - l'|, so a
// straight or diagonal run of free cells settles in one pass instead of one cell per sweep.
// A segment ends at a blocked cell (which is a segment of its own) or where a diagonal wraps
// round the tile. The map does not change during a visit, so each thread works out its four
// segments and cells once per visit (line_segments) and a scan is then 10 shuffles, no
// ballot and no index arithmetic: the settle is bound by instruction issue (32 warps a block).

#pragma once

// Scan family dir (0 rows, 1 columns, 2 diagonals, 3 anti-diagonals): warp w takes line w,
// lane l its l-th cell (y, x); head/tail: the line itself starts/ends there.
__device__ __forceinline__ void line_cell(int dir, int* y, int* x, bool* head, bool* tail) {
    int w = threadIdx.x >> 5, l = threadIdx.x & 31;
    if (dir == 0) { *y = w; *x = l; *head = l == 0; *tail = l == 31; }
    else if (dir == 1) { *y = l; *x = w; *head = l == 0; *tail = l == 31; }
    else if (dir == 2) {
        *y = l; *x = (w + l) & 31;
        *head = l == 0 || *x == 0; *tail = l == 31 || *x == 31;
    } else {
        *y = l; *x = (w - l) & 31;
        *head = l == 0 || *x == 31; *tail = l == 31 || *x == 0;
    }
}

// This lane's segment on line family dir, packed: first lane | last lane << 8 | blocked << 16
// | the cell's index in the halo tile (y + 1) * HT + x + 1 << 20.
__device__ __forceinline__ unsigned line_segments(int dir, unsigned char (*bs)[TILE + 1]) {
    int y, x, l = threadIdx.x & 31;
    bool head, tail;
    line_cell(dir, &y, &x, &head, &tail);
    bool blk = bs[y][x] != 0;
    unsigned b = __ballot_sync(FULL, blk);
    unsigned heads = __ballot_sync(FULL, head) | b | (b << 1);  // a blocked cell ends the one before
    unsigned tails = __ballot_sync(FULL, tail) | b | (b >> 1);
    unsigned first = 31 - __clz(heads & ((2u << l) - 1u));     // lane 0 is always a head
    unsigned last = __ffs(tails & ~((1u << l) - 1u)) - 1;      // lane 31 is always a tail
    unsigned cell = (unsigned)((y + 1) * HT + x + 1);
    return first | (last << 8) | ((blk ? 1u : 0u) << 16) | (cell << 20);
}

// *f = min(*f, v) where x >= y: a compare and a predicated min. Written as C, the compiler
// makes it two compares and a select, and a scan's step is then four instructions with the
// shuffle instead of three; the scans are most of a settle's instructions (SASS, nvdisasm).
__device__ __forceinline__ void min_where_ge(int* f, int v, int x, int y) {
    asm("{\n\t.reg .pred q;\n\tsetp.ge.s32 q, %1, %2;\n\t@q min.s32 %0, %0, %3;\n\t}"
        : "+r"(*f)
        : "r"(x), "r"(y), "r"(v));
}

// One scan of family dir over the tile (seg: line_segments); returns whether this thread's
// cell decreased.
__device__ __forceinline__ bool scan_line(int dir, unsigned seg, int (*gs)[HT]) {
    int l = threadIdx.x & 31;
    int step = dir < 2 ? 10 : 14;
    int first = seg & 0xFF, last = (seg >> 8) & 0xFF;
    bool blk = (seg >> 16) & 1u;
    int* cell = &gs[0][0] + (seg >> 20);
    int gv = *cell;
    // forward: min over l' in [first, l] of g[l'] - step*l', then + step*l; backward alike.
    int f = blk ? BIG : gv - step * l;
    int b = blk ? BIG : gv + step * l;
#pragma unroll
    for (int d = 1; d < 32; d <<= 1) {
        int f2 = __shfl_up_sync(FULL, f, d);
        int b2 = __shfl_down_sync(FULL, b, d);
        min_where_ge(&f, f2, l - d, first);
        min_where_ge(&b, b2, last, l + d);
    }
    int cand = min(f + step * l, b - step * l);
    if (!blk && cand < gv) {
        *cell = cand;
        return true;
    }
    return false;
}
