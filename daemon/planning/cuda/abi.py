"""Every number the host and the kernels exchange, written once.

The kernels read these from ``kernels/abi.cuh``, which is generated from this module
(``python -m daemon.planning.cuda.abi`` rewrites it; a CI test fails when it is stale), so a
word that moves here moves on both sides. INF and the neighbour order come from ``grid.py``:
the device breaks ties between predecessors exactly as the CPU does.

Buffers (int32 words unless said otherwise):

- **params** (device memory, then the delta): what one planning call does.
- **mailbox** (page-locked host memory mapped into the device): the params words, the
  ``MB_*`` words, then the raw delta; the resident loop copies params and encoded delta into
  the params buffer.
- **ctrl** (device memory, ``IO_PATH`` words): barrier counts, flag counts, statistics; the
  call's last block copies ``ctrl[0 : IO_DONE]`` into io.
- **io** (mapped host memory): the copied ctrl words, ``IO_REJECT``, the done word, then the
  path from ``IO_PATH``: cell count, status (``PATH_*``), then row and column of each cell.
"""

from __future__ import annotations

from pathlib import Path

from ..grid import DIAGONAL, INF, NEIGHBOUR_COST, NEIGHBOUR_DC, NEIGHBOUR_DR, STRAIGHT

TILE = 32
"""Cells per side of the square tile a block relaxes in shared memory."""
THREADS = TILE * TILE
"""Threads of a planning block: one per cell of its tile."""
BORDER = 4 * TILE - 4
"""Cells on a tile's perimeter: the path's exits kept per tile."""

# params: [ndelta, mode, start, goal, seq, (the mailbox's MB_STOP, MB_POST, MB_COUNT), focus,
# unused x 3], then the delta (cell * 2 + blocked). focus: the cell an EDS repair is focused on
# (the user's; -1: settle everything).
PARAM_NDELTA, PARAM_MODE, PARAM_START, PARAM_GOAL, PARAM_SEQ = range(5)
PARAM_FOCUS = 8
PARAM_USED = 9
PARAMS = 12
"""Words before the delta (a whole number of 16-byte chunks: the loop reads the mailbox so)."""
MODE_DSS, MODE_EDS = 0, 1

# mailbox words after the params: the four block 0 polls in one read.
MB_BOX = 4
MB_STOP = 5
"""Host: 1 asks the loop to end."""
MB_POST = 6
"""Host: the seq of the call posted last; with the delta's length in MB_COUNT, one 8-byte store."""
MB_COUNT = 7

# The shared loop's box (mapped, 16 bytes, polled in one read): the slot of the call posted
# last (or -k: a batch of k calls, listed from BOX_QUEUE), the stop word, the post's
# generation and its delta's length (the last two in one 8-byte store).
BOX_SLOT, BOX_STOP, BOX_POST, BOX_COUNT = range(4)
BOX_QUEUE = 4
"""A batch's calls in the box after its four words: (slot, delta length) pairs."""
BATCH_MAX = 256
"""Calls in one batch at most (the box's queue; a larger due set goes as several batches)."""
BATCH_RING = 4
"""Batches the loop's ctrl holds at once (``C_QUEUE``): block 0 publishes a batch while
blocks still serve the three before it."""
BATCH_WORDS = 4 + 2 * BATCH_MAX
"""A batch in the loop's ctrl: its call count (0: the loop ends), whether block 0 took the
first call's delta already, then the (slot, delta length) pairs; two words spare, so that
every batch starts 16-byte aligned (its first four words are one read)."""

# A slot of the shared loop's table (uint64 words in device memory): one planner's buffers.
SLOT_G, SLOT_BLOCKED, SLOT_RAISED, SLOT_PARAMS, SLOT_FLAGS, SLOT_CTRL = range(6)
SLOT_EXITS, SLOT_SEGS, SLOT_IO, SLOT_MAIL, SLOT_H, SLOT_W, SLOT_CAP, SLOT_LIMIT = range(6, 14)
SLOT_WORDS = 16

# ctrl words.
C_BAR = 0
"""Grid barrier arrivals (only ever grows)."""
C_CNT = 2
"""Three rotating sums of the tile flags set for the next round."""
C_CUT = 5
"""EDS: the cells raised when the call gave up its repair for a plan from scratch (0: it did
not; ``C_RAISED`` is then 0)."""
C_KEEP = 6
"""EDS cut-over: ``INF`` minus the level below which the old field is kept (``cut_over.cuh``;
0: no bound yet). Zeroed by the call's last block."""
C_EXITS = 7
"""Tiles whose path exits were recomputed."""
C_ROUNDS = 8
"""Grid-wide rounds, plus the relaxation's longest chain of tile visits."""
C_TILES = 9
"""Tile visits, all phases."""
C_SWEEPS = 10
"""In-tile sweeps, summed over visits."""
C_RAISED = 11
"""Cells EDS raised to INF (counted as they are raised: the cut-over's measure)."""
C_CHANGED = 12
"""Cells whose g the relaxation lowered."""
C_LONGEST = 13
"""The relaxation's longest chain of tile visits."""
C_BASE = 14
"""The barrier count the last loop ended with (the next one starts there)."""
C_STAMP = 16
"""Nine words: the global timer (ns, low 32 bits) at the call's phase boundaries, written by
block 0 (``STAMP_PHASES`` in ``scripts/profile_cuda_phases.py``), then when the loop saw the
call's post: the phases' device time per call."""
C_RAISE_RING = 25
"""EDS: three rotating sums of the cells raised in a round (beside ``C_CNT``'s, zeroed with
them): every block adds them up after each barrier to decide the cut-over, so no visit waits
for an atomic's return to compare the running total with the limit."""
C_RELEASE = 32
"""The barrier's release word, a cache line away from the arrivals."""

# The link profile's words (ctrl; written only by a build with GB_PROFILE, kernels/profile.cuh,
# which scripts/profile_cuda_links.py sets): per call, sums over the call. PF_R_*: the
# relaxation's visits, summed over every block (SM cycles, but the queue in ns); PF_A_*: the
# raise visits, likewise; PF_B_*: block 0's grid barriers; PF_T_LAG: block 0's exit from the
# relaxation after the last visit ended (ns); PF_CYCLES, PF_NS: block 0's clock and the global
# timer over the call (the cycles' rate).
PF_R_VISITS, PF_R_TAKE, PF_R_IDLE_N, PF_R_IDLE = 28, 29, 30, 31
PF_R_LOAD, PF_R_SETTLE, PF_R_STORE, PF_R_FLAG, PF_R_QUEUE, PF_R_QUEUE_N = range(33, 39)
PF_A_VISITS = 39
PF_A_TAKE, PF_A_LOAD, PF_A_FIX, PF_A_VISIT = range(43, 47)
PF_B_N, PF_B_ARRIVE, PF_B_WAIT, PF_B_LEAVE, PF_B_LAG = range(47, 52)
PF_T_LAG, PF_CYCLES, PF_NS = 52, 53, 54
FLAG_SEGMENTS = 7
"""Words per tile of ``fast``'s flags; 8 in the link profile's build (``kernels/profile.cuh``)."""
P_SEG = 40
"""Two words: the start's own path segment (exit, cells)."""
P_NSEGS = 42
"""Path segments listed by the hops."""
C_GO = 56
"""The resident loop's command generation."""
C_CMD = 57
"""The command of the current generation."""
C_SLOT = 58
"""The shared loop's ctrl (``resident.py``): the slot whose call the current generation
runs (-1: the loop ends)."""
C_SERVED = 59
"""The shared loop's ctrl: the post generation the last launch served (the next one starts
there)."""
C_TAKEN = 60
"""The shared loop's ctrl: blocks that finished a batch (only grows; block 0 reuses a ring
entry once every block has finished the batch it held)."""
C_REJECT = 61
"""A planner's ctrl: the REJECT_* bits of the delta its group's first block took, read by
the group after a barrier (0 between calls)."""
C_QUEUE = 64
"""The shared loop's ctrl: the ring of BATCH_RING batches (BATCH_WORDS each) from here."""
CTRL_READ = 13
"""ctrl words the host reads back as statistics (C_BAR .. C_CHANGED)."""
PATH_CTRL = 64
"""Words of a ctrl buffer the path kernel alone uses (barrier, release, segments)."""

# io words.
IO_REJECT = 58
"""Why the loop refused a call's delta (REJECT_* bits); 0 after any served call."""
REJECT_RANGE, REJECT_ORDER = 1, 2
"""A cell outside the map; cells not strictly increasing (the host sorts and posts again)."""
IO_DONE = 60
"""Set to the call's seq when everything it wrote is visible."""
IO_PATH = 64
"""The path: count, status, then (row, column) pairs."""
PATH_DONE, PATH_MORE, PATH_NONE, PATH_BROKEN = range(4)
"""Path status: complete; the buffer filled up (continue from the last cell); no path; g
is not a consistent field."""

_WORDS = (
    "TILE", "THREADS", "BORDER",
    "PARAM_NDELTA", "PARAM_MODE", "PARAM_START", "PARAM_GOAL", "PARAM_SEQ", "PARAM_FOCUS",
    "PARAM_USED", "PARAMS",
    "MODE_DSS", "MODE_EDS",
    "MB_BOX", "MB_STOP", "MB_POST", "MB_COUNT",
    "C_BAR", "C_CNT", "C_CUT", "C_KEEP", "C_EXITS", "C_ROUNDS", "C_TILES", "C_SWEEPS", "C_RAISED",
    "C_CHANGED", "C_LONGEST", "C_BASE", "C_STAMP", "C_RAISE_RING", "C_RELEASE", "P_SEG", "P_NSEGS",
    "PF_R_VISITS", "PF_R_TAKE", "PF_R_IDLE_N", "PF_R_IDLE", "PF_R_LOAD", "PF_R_SETTLE",
    "PF_R_STORE", "PF_R_FLAG", "PF_R_QUEUE", "PF_R_QUEUE_N", "PF_A_VISITS", "PF_A_TAKE",
    "PF_A_LOAD", "PF_A_FIX", "PF_A_VISIT", "PF_B_N", "PF_B_ARRIVE", "PF_B_WAIT", "PF_B_LEAVE",
    "PF_B_LAG", "PF_T_LAG", "PF_CYCLES", "PF_NS",
    "C_GO", "C_CMD", "C_SLOT", "C_SERVED",
    "C_TAKEN", "C_REJECT", "C_QUEUE",
    "BOX_SLOT", "BOX_STOP", "BOX_POST", "BOX_COUNT", "BOX_QUEUE", "BATCH_MAX", "BATCH_RING",
    "BATCH_WORDS",
    "SLOT_G", "SLOT_BLOCKED", "SLOT_RAISED", "SLOT_PARAMS", "SLOT_FLAGS", "SLOT_CTRL",
    "SLOT_EXITS", "SLOT_SEGS", "SLOT_IO", "SLOT_MAIL", "SLOT_H", "SLOT_W", "SLOT_CAP",
    "SLOT_LIMIT", "SLOT_WORDS",
    "CTRL_READ", "PATH_CTRL",
    "IO_REJECT", "REJECT_RANGE", "REJECT_ORDER", "IO_DONE", "IO_PATH",
    "PATH_DONE", "PATH_MORE", "PATH_NONE", "PATH_BROKEN",
)  # fmt: skip

HEADER = Path(__file__).with_name("kernels") / "abi.cuh"


def header() -> str:
    """The text of ``kernels/abi.cuh``."""
    values = globals()

    def array(name: str, items: object) -> str:
        return f"__constant__ int {name}[8] = {{{', '.join(str(int(v)) for v in items)}}};"

    lines = [
        "// Generated by `python -m daemon.planning.cuda.abi` from daemon/planning/cuda/abi.py",
        "// and daemon/planning/grid.py. Do not edit: change the Python and regenerate.",
        "#pragma once",
        "",
        f"#define INF {int(INF):#x}",
        f"#define STRAIGHT {STRAIGHT}",
        f"#define DIAGONAL {DIAGONAL}",
        *(f"#define {name} {int(values[name])}" for name in _WORDS),
        "",
        "// The neighbours in grid.NEIGHBOUR_* order: the first that fits wins a tie.",
        array("NB_DR", NEIGHBOUR_DR),
        array("NB_DC", NEIGHBOUR_DC),
        array("NB_COST", NEIGHBOUR_COST),
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    HEADER.write_text(header())
    print(f"wrote {HEADER}")
