"""``user_latencies``: each delta is paired with the first belt pattern decided on a map that
holds it (``map_seq`` ≥ its seq), whatever became of the step's path, and the generator reads
that from the pattern's bytes."""

from __future__ import annotations

import pytest

from protocol import codec
from protocol.messages import BeltPattern, PatternKind
from sim.load import user_latencies
from sim.load_generator import LoadGenerator, UserTrace

MS = 1_000_000  # ns


def _trace() -> UserTrace:
    """Deltas 1..8 sent 100 ms apart from t = 100 ms (1 in the warm-up); the daemon's 20 Hz
    pose steps put a pattern each 50 ms on the map they had, and a delta's own step 4 ms after
    it. Steps 3 and 6's paths would have been lost (latest-wins): the trace has no paths."""
    trace = UserTrace(first_measured=2)
    for i in range(1, 9):
        trace.sends[i] = 100 * i * MS
    applied = 0
    for t in range(0, 1000, 10):  # a pattern per step; steps every 10 ms of which some put
        t_ns = t * MS
        for i, sent in trace.sends.items():
            if i not in (4, 5, 8) and sent + 4 * MS <= t_ns:
                applied = max(applied, i)
        # Deltas 4 and 5 are coalesced: one step at 504 ms applies both; 8 is never answered.
        if t_ns >= 504 * MS:
            applied = max(applied, 5)
        if t % 50 == 0 or any(s + 4 * MS <= t_ns < s + 14 * MS for s in trace.sends.values()):
            trace.belts.append((t_ns, applied))
    return trace


def test_each_delta_is_answered_by_the_first_pattern_on_a_map_that_holds_it():
    lat, unanswered = user_latencies(_trace())
    # 2, 3, 6, 7: their own step's pattern, at the first 10 ms after 4 ms; 4 waited for 5's
    # step (coalesced: 110 ms after it was sent), 5 is answered by that step; 8 never is.
    assert unanswered == 1
    assert lat == pytest.approx([10.0, 10.0, 110.0, 10.0, 10.0, 10.0])


def test_an_earlier_pattern_on_the_old_map_does_not_answer_a_delta():
    """A pose step's pattern right after a delta was sent, but decided before it was applied,
    is no answer: the old pairing (the pattern just before the path) could take a pattern
    that merely arrived between them, or the next path's when a path was dropped."""
    trace = UserTrace(first_measured=1, sends={1: 100 * MS})
    trace.belts = [(101 * MS, 0), (105 * MS, 0), (203 * MS, 0), (209 * MS, 1), (250 * MS, 1)]
    assert user_latencies(trace) == ([pytest.approx(109.0)], 0)


def test_a_pattern_naming_an_older_map_after_a_resync_does_not_undo_an_answer():
    """After a snapshot (map_seq jumps to 6) a late pattern of the old map (4) arrives; the
    newest map seen so far still answers delta 5 from the snapshot's pattern."""
    trace = UserTrace(first_measured=5, sends={5: 0, 6: 100 * MS, 7: 200 * MS})
    trace.belts = [(150 * MS, 6), (160 * MS, 4), (230 * MS, 7)]
    lat, unanswered = user_latencies(trace)
    assert (lat, unanswered) == ([pytest.approx(150.0), 50.0, 30.0], 0)


def test_no_pattern_leaves_every_measured_delta_unanswered():
    trace = UserTrace(first_measured=3, sends={i: i * MS for i in range(1, 6)})
    assert user_latencies(trace) == ([], 3)


def test_the_generator_reads_map_seq_from_the_pattern_bytes():
    """What the daemon encodes: the regex finds ``map_seq``, never ``seq`` (which comes
    first), whatever the numbers."""
    gen = LoadGenerator.__new__(LoadGenerator)
    gen.traces = {"load000": UserTrace()}
    for seq, map_seq in ((7, -1), (8, 0), (2**32 - 1, 12345)):
        raw = codec.encode(
            BeltPattern(seq=seq, map_seq=map_seq, kind=PatternKind.GUIDE,
                        motors=(0, 100, 100, 0), ttl_ms=700, stamp=1.0)
        )  # fmt: skip
        gen._on_belt("load000", seq, raw)
    assert gen.traces["load000"].belts == [(7, -1), (8, 0), (2**32 - 1, 12345)]
