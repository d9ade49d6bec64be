// The resident loop (included by fast.cu): one launch per device serves the planning calls of
// every fast planner of the process until it is told to stop or has been idle for `idle_us`,
// so a replanning step costs the host a few stores into mapped memory instead of a launch,
// and users stepping in turn never stop one loop to launch another (before, each planner had
// a loop of its own: ~0.2 ms a step and stalls of ~45 ms with two users or more).
//
// The planners' buffers are described by a table in device memory (`slots`, SLOT_WORDS uint64
// words a slot: the pointers and sizes plan_call takes), written by the host when a planner
// attaches. A planner's mailbox (params and raw delta) and io (results, done word) are its
// own; what the host posts goes to the loop's box instead: the slot (or -k, a batch of k
// calls listed after the box, BOX_QUEUE), the stop word, a generation that grows with every
// post, the delta's length (BOX_*), the last two in one 8-byte store. Block 0's thread 0
// polls the box in one PCIe read and publishes the post as a batch in a ring in the loop's
// ctrl (C_QUEUE, BATCH_RING entries) with the generation ctrl[C_GO].
//
// Batches (issue 28: a thousand users at 10 Hz): the calls of a batch run side by side, each
// on a group of the launch's blocks (GBLOCK of GSIZE, grid_sync.cuh): a focused repair at
// 400² touches a few of its 169 tiles, so a call on every SM left most of them waiting at its
// barriers, and one call at a time capped the device at ~9,200 steps/s. A group's first
// block takes its call's delta, and a barrier of the group publishes it. A single post runs
// as before batches: block 0 takes its delta before publishing it, and its group is the grid.
//
// Barriers: a call's barriers count in its planner's own ctrl (the target starts at the
// planner's ctrl[C_BASE], which its last call's last block left equal to the arrivals), so
// planners never share a count; the loop's own ctrl counts only the launch's first barrier
// and carries C_GO and the generation served (C_SERVED) from launch to launch.
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


// Block 0: wait for a post, the stop word or the idle limit, and publish it as the ring's
// `entry` (abi.BATCH_WORDS): [calls (0: the loop ends), delta taken, (slot, length) pairs].
// A single post's delta is taken here, a rejected one ended here (rejection bits, then the
// done word = the call's seq). *served: the generation taken last (thread 0).
__device__ __noinline__ void take_batch(const int* box, const unsigned long long* slots,
                                        unsigned* ctrl, int* entry, int* served,
                                        unsigned idle_us) {
    __shared__ int s_k, s_slot, s_count;
    __shared__ unsigned long long s_d[SLOT_WORDS];
    while (true) {
        if (threadIdx.x == 0) {
            unsigned long long since = global_ns();
            int k = 0;
            while (true) {
                // One PCIe read, an acquire: the mailboxes and the queue read after it hold
                // what the host wrote before the post.
                int4 b = load_acquire_sys(box);
                if (b.y) break;
                if (b.z != *served) {
                    *served = b.z;
                    k = b.x >= 0 ? 1 : min(-b.x, BATCH_MAX);
                    s_slot = b.x;
                    s_count = b.w;
                    break;
                }
                if (global_ns() - since > 1000ull * idle_us) break;
                __nanosleep(200);
            }
            s_k = k;
        }
        __syncthreads();
        const int k = s_k;
        if (k == 0) {
            if (threadIdx.x == 0) entry[0] = 0;
            break;
        }
        if (s_slot < 0) {
            // The queue: two pairs a 16-byte chunk, every chunk read at once.
            const int n = 2 * k, chunks = (n + 3) / 4;
            if ((int)threadIdx.x < chunks) {
                int4 c = __ldcv((const int4*)(box + BOX_QUEUE) + threadIdx.x);
                int* to = entry + 2 + 4 * threadIdx.x;
                to[0] = c.x;
                to[1] = c.y;
                if (4 * (int)threadIdx.x + 2 < n) {
                    to[2] = c.z;
                    to[3] = c.w;
                }
            }
            if (threadIdx.x == 0) {
                entry[0] = k;
                entry[1] = 0;
            }
            break;
        }
        const int slot = s_slot;
        if (threadIdx.x < SLOT_WORDS) s_d[threadIdx.x] = __ldcg(slots + SLOT_WORDS * slot + threadIdx.x);
        __syncthreads();
        unsigned* planner_ctrl = (unsigned*)s_d[SLOT_CTRL];
        if (threadIdx.x == 0) planner_ctrl[C_STAMP + 8] = (unsigned)global_ns();  // phases.py
        int* params = (int*)s_d[SLOT_PARAMS];
        int reject = take_delta((const int*)s_d[SLOT_MAIL], params, s_count,
                                (int)(s_d[SLOT_H] * s_d[SLOT_W]));
        if (!reject) {
            if (threadIdx.x == 0) {
                entry[0] = 1;
                entry[1] = 1;
                entry[2] = slot;
                entry[3] = s_count;
            }
            break;
        }
        if (threadIdx.x == 0) {
            int* io = (int*)s_d[SLOT_IO];
            io[IO_REJECT] = reject;
            __threadfence_system();
            ((volatile int*)io)[IO_DONE] = ((volatile int*)params)[PARAM_SEQ];
        }
        __syncthreads();  // s_d and s_slot are rewritten by the next post
    }
    __syncthreads();
    if (threadIdx.x == 0) {
        // The entry, and the params and delta the block wrote, before the generation that
        // announces them (a fence is cumulative over the block's barrier above).
        __threadfence();
        atomicAdd(ctrl + C_GO, 1u);
    }
}

// A group's call whose delta its first block refused: every block of the group arrives, the
// last one sets the rejection bits and the done word (nothing was applied).
__device__ void reject_call(unsigned* pctrl, const unsigned long long* d, int reject,
                            unsigned* bar) {
    if (grid_arrive_last(pctrl, bar) && threadIdx.x == 0) {
        int* io = (int*)d[SLOT_IO];
        pctrl[C_REJECT] = 0u;
        pctrl[C_BASE] = *bar;
        io[IO_REJECT] = reject;
        __threadfence_system();
        ((volatile int*)io)[IO_DONE] = __ldcg((const int*)d[SLOT_PARAMS] + PARAM_SEQ);
    }
}

// Every block: the calls of the batch at `entry`, min(calls, blocks) groups of consecutive
// blocks, group i serving calls i, i + groups, ... Returns false when the loop ends.
__device__ bool serve_batch(const unsigned long long* slots, unsigned* ctrl, const int* entry) {
    __shared__ int4 s_head;  // calls, delta taken, the first call's slot and length
    __shared__ unsigned long long s_d[SLOT_WORDS];
    __shared__ unsigned s_call_bar;
    __shared__ int s_reject;
    if (threadIdx.x == 0) s_head = __ldcg((const int4*)entry);
    __syncthreads();
    const int4 head = s_head;
    const int k = head.x;
    if (k == 0) return false;
    const unsigned blocks = gridDim.x, groups = min((unsigned)k, blocks);
    const unsigned grp = blockIdx.x * groups / blocks;
    const unsigned first = (grp * blocks + groups - 1) / groups;
    const unsigned next = ((grp + 1) * blocks + groups - 1) / groups;
    for (int e = grp; e < k; e += groups) {
        if (threadIdx.x == 0) {
            s_gblock = blockIdx.x - first;
            s_gsize = next - first;
        }
        if (threadIdx.x < SLOT_WORDS) {
            int slot = e == 0 ? head.z : __ldcg(entry + 2 + 2 * e);
            s_d[threadIdx.x] = __ldcg(slots + SLOT_WORDS * slot + threadIdx.x);
        }
        __syncthreads();
        unsigned* pctrl = (unsigned*)s_d[SLOT_CTRL];
        // plan_call reads the target after its first barrier.
        if (threadIdx.x == 0) s_call_bar = ((volatile unsigned*)pctrl)[C_BASE];
        if (e != 0 || !head.y) {
            if (GBLOCK == 0) {
                if (threadIdx.x == 0) pctrl[C_STAMP + 8] = (unsigned)global_ns();
                int reject = take_delta((const int*)s_d[SLOT_MAIL], (int*)s_d[SLOT_PARAMS],
                                        __ldcg(entry + 3 + 2 * e),
                                        (int)(s_d[SLOT_H] * s_d[SLOT_W]));
                if (threadIdx.x == 0) pctrl[C_REJECT] = (unsigned)reject;
            }
            grid_barrier(pctrl, &s_call_bar);  // the params and delta, to the whole group
            if (threadIdx.x == 0) s_reject = ((volatile int*)pctrl)[C_REJECT];
            __syncthreads();
            if (s_reject) {
                reject_call(pctrl, s_d, s_reject, &s_call_bar);
                __syncthreads();  // s_d is rewritten for the next call
                continue;
            }
        }
        plan_call((int*)s_d[SLOT_G], (unsigned char*)s_d[SLOT_BLOCKED],
                  (unsigned char*)s_d[SLOT_RAISED], (const int*)s_d[SLOT_PARAMS],
                  (const int*)s_d[SLOT_PARAMS] + PARAMS, (unsigned*)s_d[SLOT_FLAGS], pctrl,
                  (int)s_d[SLOT_H], (int)s_d[SLOT_W], (int2*)s_d[SLOT_EXITS],
                  (int4*)s_d[SLOT_SEGS], (int*)s_d[SLOT_IO], (int)s_d[SLOT_CAP],
                  (unsigned)s_d[SLOT_LIMIT], &s_call_bar);
        __syncthreads();  // s_d is rewritten for the next call
    }
    // The block is done with the entry: its reads of it returned long before (the calls used
    // them), so block 0 may write the ring's slot again once every block has counted.
    if (threadIdx.x == 0) atomicAdd(ctrl + C_TAKEN, 1u);
    return true;
}

// The loop. slots: the table (device memory); ctrl: the loop's own words (IO_PATH) and the
// ring of batches (zero at first); box: the host's four words and its queue (mapped).
extern "C" __global__ void __launch_bounds__(THREADS, 1)
plan_users(const unsigned long long* slots, unsigned* ctrl, const int* box, unsigned idle_us) {
    __shared__ unsigned s_bar, s_gen, s_taken;
    __shared__ int s_served;
    whole_grid_group();
    if (threadIdx.x == 0) {
        s_bar = ((volatile unsigned*)ctrl)[C_BASE];
        s_gen = ((volatile unsigned*)ctrl)[C_GO];
        s_served = ((volatile int*)ctrl)[C_SERVED];
        s_taken = ((volatile unsigned*)ctrl)[C_TAKEN];
    }
    // Every block has read C_GO before block 0 can move it.
    grid_barrier(ctrl, &s_bar);
    int* ring = (int*)(ctrl + C_QUEUE);
    for (unsigned j = 0;; ++j) {
        int* entry = ring + (j % BATCH_RING) * BATCH_WORDS;
        if (blockIdx.x == 0) {
            // The entry held batch j - BATCH_RING: every block must be done with it.
            if (threadIdx.x == 0 && j >= BATCH_RING) {
                const unsigned need = gridDim.x * (j + 1 - BATCH_RING);
                while (load_acquire(ctrl + C_TAKEN) - s_taken < need) __nanosleep(100);
            }
            __syncthreads();
            take_batch(box, slots, ctrl, entry, &s_served, idle_us);
        } else {
            if (threadIdx.x == 0) {
                while (load_acquire(ctrl + C_GO) == s_gen) __nanosleep(100);
                s_gen += 1;
            }
        }
        __syncthreads();
        if (!serve_batch(slots, ctrl, entry)) break;
    }
    if (blockIdx.x == 0 && threadIdx.x == 0) {
        ctrl[C_BASE] = s_bar;
        ctrl[C_SERVED] = (unsigned)s_served;
    }
}
