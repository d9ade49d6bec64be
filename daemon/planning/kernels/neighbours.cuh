// Grid constants shared by the kernels: tile size, INF, and the 8 neighbours in
// grid.NEIGHBOUR_* order (the order that breaks ties between predecessors, so every backend
// walks the same cells).
#pragma once

#define TILE 32
#define HT (TILE + 2)  // a tile and its one-cell halo
#define INF 0x3FFFFFFF
#define FULL 0xFFFFFFFFu

__constant__ int NB_DR[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
__constant__ int NB_DC[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
__constant__ int NB_COST[8] = {14, 10, 14, 10, 10, 14, 10, 14};
