// The resident loop (included by fast.cu): one launch per device serves the planning calls of
// every fast planner of the process until it is told to stop or has been idle for `idle_us`,
// so a replanning step costs the host a few stores into mapped memory instead of a launch,
// and users stepping in turn never stop one loop to launch another (before, each planner had
// a loop of its own: ~0.2 ms a step and stalls of ~45 ms with two users or more).
//
// The planners' buffers are described by a table in device memory (`slots`, SLOT_WORDS uint64
// words a slot: the pointers and sizes plan_call takes), written by the host
// when a planner attaches. A planner's mailbox (params and raw delta) and io (results, done
// word) are its own; what the host posts goes to the loop's box
// instead: the slot, the stop word, a generation that grows with every post, the delta's
// length (BOX_*), the last two in one 8-byte store. Block 0's thread 0 polls the box in one
// PCIe read, takes the slot's descriptor and delta (take_delta) and publishes the slot in
// ctrl[C_SLOT] with the generation ctrl[C_GO]; every block then reads the descriptor from L2
// and runs plan_call over that planner's buffers.
//
// Barriers: a call's grid barriers count in its planner's own ctrl (the target starts at the
// planner's ctrl[C_BASE], which its last call's last block left equal to the arrivals), so
// planners never share a count; the loop's own ctrl counts only the launch's first barrier
// and carries C_GO, C_SLOT and the generation served (C_SERVED) from launch to launch.
//
// The host never needs to know whether a loop is running: a call it posts just as the loop
// ends idle is left unserved, the host sees the stream idle with its done word unset, and
// launches again; a new loop serves the box if its generation differs from C_SERVED.
#pragma once
#include "abi.cuh"

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


// Block 0: wait for a post, the stop word or the idle limit; the posted slot's descriptor
// into d (every thread of block 0 reads it), its params and delta into its device params. A
// rejected delta ends its call here (rejection bits, then the done word = the call's seq).
// Returns the slot, or -1: the loop ends. *served: the generation taken last (thread 0).
__device__ __noinline__ int take_call(const int* box, const unsigned long long* slots,
                                      unsigned* ctrl, unsigned long long* d, int* served,
                                      unsigned idle_us) {
    __shared__ int s_slot, s_count;
    while (true) {
        if (threadIdx.x == 0) {
            unsigned long long since = global_ns();
            int slot = -1;
            while (true) {
                // One PCIe read, an acquire: the planner's mailbox read after it holds what
                // the host wrote before the post.
                int4 b = load_acquire_sys(box);
                if (b.y) break;
                if (b.z != *served) {
                    *served = b.z;
                    slot = b.x;
                    s_count = b.w;
                    break;
                }
                if (global_ns() - since > 1000ull * idle_us) break;
                __nanosleep(200);
            }
            s_slot = slot;
        }
        __syncthreads();
        const int slot = s_slot;
        if (slot < 0) break;
        if (threadIdx.x < SLOT_WORDS) d[threadIdx.x] = __ldcg(slots + SLOT_WORDS * slot + threadIdx.x);
        __syncthreads();
        unsigned* planner_ctrl = (unsigned*)d[SLOT_CTRL];
        if (threadIdx.x == 0) planner_ctrl[C_STAMP + 8] = (unsigned)global_ns();  // phases.py
        int* params = (int*)d[SLOT_PARAMS];
        int reject = take_delta((const int*)d[SLOT_MAIL], params, s_count,
                                (int)(d[SLOT_H] * d[SLOT_W]));
        if (!reject) break;
        if (threadIdx.x == 0) {
            int* io = (int*)d[SLOT_IO];
            io[IO_REJECT] = reject;
            __threadfence_system();
            ((volatile int*)io)[IO_DONE] = ((volatile int*)params)[PARAM_SEQ];
        }
        __syncthreads();  // d and s_slot are rewritten by the next post
    }
    if (threadIdx.x == 0) {
        ctrl[C_SLOT] = (unsigned)s_slot;
        // The slot, and the params and delta the block wrote before its last barrier, before
        // the generation that announces them.
        __threadfence();
        atomicAdd(ctrl + C_GO, 1u);
    }
    return s_slot;
}

// The other blocks: wait for generation *gen + 1 and return its slot (-1: the loop ends).
__device__ int await_call(unsigned* ctrl, unsigned* gen) {
    __shared__ int s_slot;
    if (threadIdx.x == 0) {
        while (load_acquire(ctrl + C_GO) == *gen) __nanosleep(100);
        *gen += 1;
        s_slot = (int)((volatile unsigned*)ctrl)[C_SLOT];
    }
    __syncthreads();
    return s_slot;
}

// The loop. slots: the table (device memory); ctrl: the loop's own IO_PATH words (zero at
// first); box: the host's four words (mapped).
extern "C" __global__ void __launch_bounds__(THREADS, 1)
plan_users(const unsigned long long* slots, unsigned* ctrl, const int* box, unsigned idle_us) {
    __shared__ unsigned s_bar, s_gen, s_call_bar;
    __shared__ int s_served;
    __shared__ unsigned long long s_d[SLOT_WORDS];
    if (threadIdx.x == 0) {
        s_bar = ((volatile unsigned*)ctrl)[C_BASE];
        s_gen = ((volatile unsigned*)ctrl)[C_GO];
        s_served = ((volatile int*)ctrl)[C_SERVED];
    }
    // Every block has read C_GO before block 0 can move it.
    grid_barrier(ctrl, &s_bar);
    while (true) {
        int slot = blockIdx.x == 0 ? take_call(box, slots, ctrl, s_d, &s_served, idle_us)
                                   : await_call(ctrl, &s_gen);
        if (slot < 0) break;
        if (blockIdx.x != 0 && threadIdx.x < SLOT_WORDS)
            s_d[threadIdx.x] = __ldcg(slots + SLOT_WORDS * slot + threadIdx.x);
        __syncthreads();
        unsigned* pctrl = (unsigned*)s_d[SLOT_CTRL];
        // plan_call reads the target after its first barrier.
        if (threadIdx.x == 0) s_call_bar = ((volatile unsigned*)pctrl)[C_BASE];
        plan_call((int*)s_d[SLOT_G], (unsigned char*)s_d[SLOT_BLOCKED],
                  (unsigned char*)s_d[SLOT_RAISED], (const int*)s_d[SLOT_PARAMS],
                  (const int*)s_d[SLOT_PARAMS] + PARAMS, (unsigned*)s_d[SLOT_FLAGS], pctrl,
                  (int)s_d[SLOT_H], (int)s_d[SLOT_W], (int2*)s_d[SLOT_EXITS],
                  (int4*)s_d[SLOT_SEGS], (int*)s_d[SLOT_IO], (int)s_d[SLOT_CAP],
                  (unsigned)s_d[SLOT_LIMIT], &s_call_bar);
        __syncthreads();  // s_d is rewritten for the next call
    }
    if (blockIdx.x == 0 && threadIdx.x == 0) {
        ctrl[C_BASE] = s_bar;
        ctrl[C_SERVED] = (unsigned)s_served;
    }
}
