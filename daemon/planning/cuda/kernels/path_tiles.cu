// Path extraction by tile jumps as a launch of its own (the planner's `path`, and the rest
// of a path longer than the buffer): every tile's exits, the hops, the segments
// (path_exits.cuh), with a grid barrier between the phases. After a repair, fast.cu runs the
// same phases in its own launch and recomputes only the tiles whose exits changed.

#include "grid_sync.cuh"
#include "path_exits.cuh"

// exits: BORDER per tile; segs[k] = (entry cell, cells, offset of its first cell in the path).
extern "C" __global__ void __launch_bounds__(128)
path_tiles(const int* g, int h, int w, int start, int2* exits, int4* segs, int* out, int cap,
           unsigned* ctrl, unsigned bar_base) {
    __shared__ __align__(16) int gs[HT][HT];  // aligned: walk_segments stores int2 pairs in it
    __shared__ unsigned char code[TILE][TILE];
    whole_grid_group();
    unsigned bar = bar_base;
    int ntiles = ((w + TILE - 1) / TILE) * ((h + TILE - 1) / TILE);
    for (int t = blockIdx.x; t < ntiles; t += gridDim.x) tile_exits(g, h, w, t, start, exits, ctrl, gs, code);
    grid_barrier(ctrl, &bar);
    if (blockIdx.x == 0 && threadIdx.x == 0) hop_segments(g, w, start, exits, segs, out, cap, ctrl);
    grid_barrier(ctrl, &bar);
    walk_segments(g, h, w, segs, out, ctrl, gs, code);
}
