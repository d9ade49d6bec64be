// In-tile min-plus scans for tile_relax.cuh.
//
// A warp holds one line of 32 cells of the tile in shared memory (a row, a column or a
// diagonal) and gives every cell min over its segment of g[l'] + step * |l - l'|, so a
// straight or diagonal run of free cells settles in one pass instead of one cell per sweep.
// A segment ends at a blocked cell (which is a segment of its own) or where a diagonal wraps
// round the tile. The map does not change during a visit, so each thread works out its four
// segments and cells once per visit (line_segments); a scan is then 10 shuffles that stop at
// the segment's ends themselves and 10 mins, 32 instructions in all (SASS, sm_90; 48 when a
// compare chose each min). The settle is bound by instruction issue (32 warps a block): the
// cut took 400² DSS plans from 0.173 to 0.158 ms of device time on an H100.

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

// This lane's segment on line family dir, packed so that a scan unpacks each field with one
// instruction (SASS): first lane in byte 0 (a LOP), the cell's byte offset in the halo tile,
// 4 * ((y + 1) * HT + x + 1) < 2^16, in bytes 1-2 (a PRMT), last lane in byte 3 (a shift).
// A blocked cell is a segment of its own (first == last == l), so its value never reaches
// another lane and its own candidate is its g: the scan needs no blocked bit.
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
    unsigned offset = (unsigned)((y + 1) * HT + x + 1) * (unsigned)sizeof(int);
    static_assert(HT * HT * sizeof(int) <= 0x10000, "the cell's offset fits bytes 1-2");
    return first | (offset << 8) | (last << 24);
}

// The value of lane l - d (up) or l + d (down), or this lane's own value where that lane lies
// before first (up) or after last (down). PTX shfl's clamp operand c bounds the source lane
// per thread (c[4:0]; c[12:8], the sub-warp mask, is 0 here), and an out-of-bounds source
// reads the own lane: min(f, shuffled) then needs no compare. That is two instructions a scan
// step instead of three (a compare and a predicated min with the plain shuffle; SASS).
__device__ __forceinline__ int shfl_up_within(int v, int d, unsigned first) {
    int r;
    asm volatile("shfl.sync.up.b32 %0, %1, %2, %3, 0xffffffff;" : "=r"(r) : "r"(v), "r"(d), "r"(first));
    return r;
}

__device__ __forceinline__ int shfl_down_within(int v, int d, unsigned last) {
    int r;
    asm volatile("shfl.sync.down.b32 %0, %1, %2, %3, 0xffffffff;" : "=r"(r) : "r"(v), "r"(d), "r"(last));
    return r;
}

// One scan of family dir over the tile (seg: line_segments); returns whether this thread's
// cell decreased. A blocked cell's candidate is its own g (its segment is itself), so the
// store below never writes one.
__device__ __forceinline__ bool scan_line(int dir, unsigned seg, int (*gs)[HT]) {
    int l = threadIdx.x & 31;
    int step = dir < 2 ? STRAIGHT : DIAGONAL;
    unsigned first = seg & 0xFF, last = seg >> 24;
    int* cell = (int*)((char*)&gs[0][0] + __byte_perm(seg, 0, 0x4421));  // bytes 1-2, zero-extended
    int gv = *cell;
    // forward: min over l' in [first, l] of g[l'] - step*l', then + step*l; backward alike.
    int f = gv - step * l;
    int b = gv + step * l;
#pragma unroll
    for (int d = 1; d < 32; d <<= 1) {
        f = min(f, shfl_up_within(f, d, first));
        b = min(b, shfl_down_within(b, d, last));
    }
    int cand = min(f + step * l, b - step * l);
    if (cand < gv) {
        *cell = cand;
        return true;
    }
    return false;
}
