// The user's bound B for fast.cu's focused repair (included by fast.cu).
//
// fast.cu's argument for the focused repair uses one property of the value a deferral is
// decided against: it is >= g*(focus), the focus's exact cost in the map after the call's
// delta (the final g(focus)). g(focus) as read has it: an upper bound that only falls. B has
// it too:
// - What it is. The host names in PARAM_LAST_PATH the seq of the call that extracted the
//   last path whole (PATH_DONE), if no call ran since (cuda/planner.py; else 0). That call's
//   walk_segments marked each of the path's cells with its seq (marks, SLOT_MARKS). In round
//   0, before anything writes g, the focus's g and mark are read: if the mark is that seq, B
//   is that g, else INF. If this call's delta newly blocks any cell marked with that seq
//   (anywhere on the path, behind the user too), B is INF.
// - Why B >= g*(focus). The extraction steps only to a neighbour n with g(n) + c == g(cur)
//   (load_codes) and stops at the goal (g == 0), so the rest of the marked path from the
//   focus costs exactly g(focus) as it was when the path was read (the GPU tests check the
//   path read against reference_path and its cost against the user's exact g at every step
//   of their walks, tests/daemon/planning/cuda/test_focused_repair.py), and no call wrote g since
//   (the host's condition; round 0 writes blocked and raised, not g). Its cells had finite g,
//   so they were free (a blocked cell holds INF after every call: raised and reset, or reset
//   by the cut-over, whose level is at most its old g), its moves join 8-neighbours, and only
//   this delta changed the map since. The delta blocks none of its cells, and freed cells only
//   add moves, so it is still a path to the goal: g*(focus) <= its cost = B.
// - Where it is unknown. A first call, a plan(), an update() or a path query since the last
//   path, a path read in pieces (PATH_MORE), DSS and settle send 0: B = INF, the behaviour
//   without it. The focus off the path (its mark is another seq): INF. A delta that blocks a
//   cell of the path: INF, even where the cell lies behind the user. A goal change is a
//   plan(). Marks of older calls hold other seqs (seq grows by one a call and wraps only after
//   2^31 calls). So B is INF or the cost of a real path of the new map, never below
//   g*(focus); a B below it would defer a tile on the user's shortest path, and the path read
//   would not be the reference path.
// - What it buys. Every threshold is min(g(focus), B). After a cut-over the focus's g is
//   usually reset to INF (keep_below_change), so with g alone the relaxation defers nothing
//   until the wave reaches the user and floods the map beyond the level; with B the cut-over
//   puts aside the tiles whose key level + h exceeds B instead of flagging them
//   (cut_over.cuh, (4)), and the relaxation defers from its first visit.
#pragma once
#include "abi.cuh"

// Round 0, after the delta (every thread of the call): `path_cut`: this thread newly blocked a
// cell marked with `last`; `first`: the call's thread 0, which loaded the focus's mark and g
// before the delta. Both words are read after the round's barrier (user_bound).
__device__ __forceinline__ void publish_user(unsigned* ctrl, int last, bool path_cut, bool first,
                                             int focus_mark, int focus_g) {
    if (path_cut) ctrl[C_USER_CUT] = 1u;  // the same value from any thread: no atomic
    if (last && first && focus_mark == last && focus_g < INF)
        ctrl[C_USER] = (unsigned)(INF - focus_g);
}

// After round 0's barrier, in every thread: B, or INF where it is unknown or cancelled.
__device__ __forceinline__ int user_bound(const unsigned* ctrl, int last) {
    if (!last) return INF;
    const unsigned user = ((volatile const unsigned*)ctrl)[C_USER];
    const unsigned cut = ((volatile const unsigned*)ctrl)[C_USER_CUT];
    return user && !cut ? INF - (int)user : INF;
}
