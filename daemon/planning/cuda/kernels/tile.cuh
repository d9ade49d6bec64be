// What the kernels derive from the tile size, beside the generated words of abi.cuh (TILE,
// INF, the neighbours in grid.NEIGHBOUR_* order, the buffers' word indices).
#pragma once
#include "abi.cuh"

#define HT (TILE + 2)  // a tile and its one-cell halo
#define FULL 0xFFFFFFFFu
