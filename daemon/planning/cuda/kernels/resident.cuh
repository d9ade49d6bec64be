// The resident loop (included by fast.cu): one launch serves planning calls until it is told
// to stop or has been idle for `idle_us`, so a replanning step costs the host a few stores into
// mapped memory instead of a launch.
//
// The host's mailbox `mail` is page-locked host memory mapped into the device: the params
// words (PARAM_*), MB_STOP, MB_POST and MB_COUNT, then the delta raw
// (take_delta). The host writes a call's params and delta, then MB_POST = seq and MB_COUNT =
// the delta's length, last and in one 8-byte store (x86 keeps stores in order). Block 0's
// thread 0 polls the last four words in one PCIe read, an acquire; on a new seq its block
// reads the params and the delta, whose length it knows, in one round trip, checks the
// delta and copies params and encoded delta into device memory, and
// it publishes the command to the other blocks in ctrl[C_CMD] and ctrl[C_GO], a generation
// count that only grows, which they poll in L2. Every block reads the params from device
// memory: 132 blocks reading the same host words queue their PCIe reads one behind another
// for about 100 µs, one block's reads do not. The checks on the device spare the host's
// Python a numpy call per check, which costs most right after the host did other work.
//
// The host never needs to know whether a loop is running: a call it posts just as the loop
// ends idle is left unserved, the host sees the stream idle with its done word unset, and
// launches again; a new loop serves the mailbox if MB_POST differs from the done word.
#pragma once
#include "abi.cuh"

#define CMD_RUN 1
#define CMD_EXIT 2

// Block 0, a posted call's params and delta: the params words go to device memory as they
// are; the host writes the delta raw (cells as int64 after the params words, then one byte
// per cell, 1 = blocked) and block 0 checks and encodes it into device memory (params +
// PARAMS, cell * 2 + blocked) before any block reads it. Returns 0, or the REJECT_* bits:
// then nothing is applied and the call ends with only the done word.
// Reads of mapped host memory queue one behind another on the SM (a hundred threads' 4-byte
// reads cost twice one read), so the mailbox comes in 16-byte chunks, each read once, all at
// once: a pass of up to TAKE_CELLS cells costs one PCIe round trip for a few chunks.
#define TAKE_CELLS 1024   // cells per pass: 512 chunks of cells, 66 of value bytes, 2 of params
__device__ __noinline__ int take_delta(const int* mail, int* params, int n, int cells_total) {
    __shared__ int4 s_chunk[TAKE_CELLS / 2 + TAKE_CELLS / 16 + 4];
    __shared__ int2 s_last;  // the last cell of the previous pass
    const int4* chunks = (const int4*)mail;
    const int values_at = 4 * PARAMS + 8 * n;  // byte offset of the value bytes
    const int k = threadIdx.x;
    int bad = 0;
    for (int i0 = 0; i0 == 0 || i0 < n; i0 += TAKE_CELLS) {
        // This pass's chunks: its cells (16-byte aligned: i0 is even), its value bytes, and
        // on the first pass the params words.
        const int m = min(TAKE_CELLS, n - i0);
        const int cells_from = (4 * PARAMS + 8 * i0) / 16, ncells = (8 * m + 15) / 16;
        const int values_from = (values_at + i0) / 16;
        const int nvalues = (values_at + i0 + m + 15) / 16 - values_from;
        const int nparams = i0 == 0 ? PARAMS / 4 : 0;
        int at = -1;  // the chunk this thread reads
        if (k < ncells) at = cells_from + k;
        else if (k < ncells + nvalues) at = values_from + k - ncells;
        else if (k < ncells + nvalues + nparams) at = k - ncells - nvalues;
        if (at >= 0) s_chunk[k] = __ldcv(chunks + at);
        __syncthreads();
        const int2* cells = (const int2*)s_chunk;
        const signed char* values = (const signed char*)(s_chunk + ncells);
        int2 c = make_int2(-1, -1);
        if (k < m) {
            c = cells[k];
            int2 before = k > 0 ? cells[k - 1] : (i0 > 0 ? s_last : make_int2(-1, -1));
            int blocked = values[values_at + i0 + k - 16 * values_from] != 0;
            if (c.y != 0 || (unsigned)c.x >= (unsigned)cells_total) bad |= REJECT_RANGE;
            else if (before.y == 0 && c.x <= before.x) bad |= REJECT_ORDER;
            params[PARAMS + i0 + k] = 2 * c.x + blocked;
        }
        if (i0 == 0 && k < PARAM_USED) params[k] = ((const int*)(s_chunk + ncells + nvalues))[k];
        __syncthreads();  // every thread has read the chunks (and s_last) before the next pass
        if (k == m - 1) s_last = c;
    }
    int range = __syncthreads_or(bad & REJECT_RANGE);
    int order = __syncthreads_or(bad & REJECT_ORDER);
    return (range ? REJECT_RANGE : 0) | (order ? REJECT_ORDER : 0);
}

// Block 0: wait for a posted call, the stop word or the idle limit; copy a call's params and
// delta into device memory; publish the command. A rejected delta ends its call here (the
// rejection bits, then the done word) and block 0 waits for the next one. *served: the seq
// of the last call taken (thread 0).
__device__ __noinline__ int take_command(const int* mail, int* params, unsigned* ctrl, int* io,
                            int* served, unsigned idle_us, int cells_total) {
    __shared__ int s_cmd, s_count;
    while (true) {
        if (threadIdx.x == 0) {
            unsigned long long since = global_ns();
            int cmd = CMD_EXIT;
            while (true) {
                // One PCIe read (seq, stop, post, count), an acquire: the params and delta
                // read after it are the ones the host wrote before the post.
                int4 box = load_acquire_sys(mail + MB_BOX);
                if (box.y) break;
                if (box.z != *served) {
                    ctrl[C_STAMP + 8] = (unsigned)global_ns();  // the post seen (phases.py)
                    *served = box.z;
                    s_count = box.w;
                    cmd = CMD_RUN;
                    break;
                }
                if (global_ns() - since > 1000ull * idle_us) break;
                __nanosleep(200);
            }
            s_cmd = cmd;
        }
        __syncthreads();
        if (s_cmd != CMD_RUN) break;
        int reject = take_delta(mail, params, s_count, cells_total);
        if (!reject) break;
        if (threadIdx.x == 0) {
            io[IO_REJECT] = reject;
            __threadfence_system();
            ((volatile int*)io)[IO_DONE] = *served;
        }
    }
    if (threadIdx.x == 0) {
        ctrl[C_CMD] = (unsigned)s_cmd;
        // The command, and the params and delta the block wrote before its last barrier,
        // before the generation that announces them (one fence: it covers the block's writes).
        __threadfence();
        atomicAdd(ctrl + C_GO, 1u);
    }
    return s_cmd;
}

// The other blocks: wait for generation *gen + 1 and return its command.
__device__ int await_command(unsigned* ctrl, unsigned* gen) {
    __shared__ int s_cmd;
    if (threadIdx.x == 0) {
        while (load_acquire(ctrl + C_GO) == *gen) __nanosleep(100);
        *gen += 1;
        s_cmd = (int)((volatile unsigned*)ctrl)[C_CMD];
    }
    __syncthreads();
    return s_cmd;
}

// The loop. mail: the host's mailbox (mapped); params: device memory the loop copies each
// call's params words into; limit: the cells an EDS repair may raise before it gives up for
// a plan from scratch (fast.cu). ctrl[C_GO] and ctrl[C_BASE] carry over from launch to launch.
extern "C" __global__ void __launch_bounds__(THREADS, 1)
plan_resident(int* g, unsigned char* blocked, unsigned char* raised, int* params,
              unsigned* flags, unsigned* ctrl, int h, int w, int2* exits, int4* segs, int* io,
              int cap, const int* mail, unsigned limit, unsigned idle_us) {
    // Thread 0's state across calls lives in shared memory: registers held across plan_call
    // would push its own values into spills (ptxas -v).
    __shared__ unsigned s_bar, s_gen;
    __shared__ int s_served;
    if (threadIdx.x == 0) {
        s_bar = ((volatile unsigned*)ctrl)[C_BASE];
        s_gen = ((volatile unsigned*)ctrl)[C_GO];
        // The done word is the seq of the last call served, by this loop or an earlier launch.
        s_served = __ldcv(io + IO_DONE);
    }
    // Every block has read C_GO before block 0 can move it.
    grid_barrier(ctrl, &s_bar);
    while (true) {
        int cmd = blockIdx.x == 0 ? take_command(mail, params, ctrl, io, &s_served, idle_us, h * w)
                                  : await_command(ctrl, &s_gen);
        if (cmd != CMD_RUN) break;
        plan_call(g, blocked, raised, params, params + PARAMS, flags, ctrl, h, w, exits, segs, io,
                  cap, limit, &s_bar);
    }
    // Nothing arrives at a barrier after the exit command: every block's target is the same.
    if (blockIdx.x == 0 && threadIdx.x == 0) ctrl[C_BASE] = s_bar;
}
