"""What the view keeps of each user: folded in order, bounded whatever comes."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from protocol.messages import (
    BeltPattern,
    Goal,
    GoalCell,
    MapDelta,
    MapSnapshot,
    NavPath,
    PatternKind,
    VoiceCue,
)
from viewer.app import png_of
from viewer.state import CUES_KEPT, ViewState


def delta(seq: int, cells: list[int], value: int = 1, shape=(10, 12)) -> MapDelta:
    return MapDelta.from_arrays(seq, shape, np.array(cells), np.full(len(cells), value), 1.0)


def test_deltas_in_sequence_build_the_map_and_a_gap_asks_for_a_snapshot() -> None:
    state = ViewState()
    state.fold("ann", delta(0, [0, 5]))
    state.fold("ann", delta(1, [13]))
    occ, version = state.map_of("ann")
    assert occ.shape == (10, 12) and version == 2
    assert occ.reshape(-1)[[0, 5, 13]].tolist() == [1, 1, 1] and occ.sum() == 3
    assert state.wanting_snapshot() == []
    state.fold("ann", delta(3, [20]))  # 2 went missing
    assert state.wanting_snapshot() == ["ann"]
    full = np.zeros((10, 12), np.uint8)
    full[4, 4] = 1
    state.fold("ann", MapSnapshot.from_array(3, full, 2.0))
    assert state.wanting_snapshot() == []
    occ, _ = state.map_of("ann")
    assert occ.sum() == 1 and occ[4, 4] == 1
    state.fold("ann", delta(4, [0]))
    assert state.map_of("ann")[0].sum() == 2


def test_a_delta_before_any_map_waits_for_the_snapshot() -> None:
    state = ViewState()
    state.fold("bob", delta(7, [1]))
    assert state.map_of("bob") is None and state.wanting_snapshot() == ["bob"]


def test_cues_and_users_are_bounded() -> None:
    state = ViewState(max_users=2)
    for i in range(50):
        state.fold("ann", VoiceCue(text=f"cue {i}", kind="direction", stamp=float(i)))
    for name in ("bob", "cat", "dan"):
        state.fold(name, VoiceCue(text="hi", kind="direction", stamp=1.0))
    frame = state.frame()
    assert list(frame["users"]) == ["ann", "bob"] and state.ignored == 2
    assert [c["text"] for c in frame["users"]["ann"]["cues"]] == [
        f"cue {i}" for i in range(50 - CUES_KEPT, 50)
    ]


def test_frame_places_the_goal_and_carries_the_belt_and_latency() -> None:
    state = ViewState()
    state.fold("ann", delta(0, [0]))
    state.fold("ann", Goal(target=GoalCell(row=2, col=3), stamp=1.0))
    path = NavPath(cells=[(9, 3), (8, 3)], cost=10, cell_m=0.2, height=10, width=12,
                   pose_stamp=100.0, stamp=100.01)  # fmt: skip
    state.fold("ann", path, received=100.05)
    belt = BeltPattern(
        seq=1, map_seq=4, kind=PatternKind.GUIDE, motors=(10, 20, 0, 0), ttl_ms=500, stamp=1
    )
    state.fold("ann", belt)
    user = json.loads(json.dumps(state.frame()))["users"]["ann"]
    # Row 2 of 10, 0.2 m cells: 7.5 cells up from the bottom edge; col 3: 3.5 cells east.
    assert user["goal"] == pytest.approx({"x": 0.7, "y": 1.5})
    assert user["latency_ms"] == pytest.approx(50.0)
    belt_seen = {"kind": "guide", "motors": [10, 20, 0, 0], "period_ms": 0, "seq": 1, "map_seq": 4}
    assert user["belt"] == belt_seen
    assert user["path"] == [[9, 3], [8, 3]]


def test_png_of_the_map_reads_back_row_for_row() -> None:
    from matplotlib.image import imread

    occ = np.zeros((5, 7), np.uint8)
    occ[0, 0], occ[4, 6] = 1, 2
    img = imread(io.BytesIO(png_of(occ)), format="png")
    assert img.shape == (5, 7)
    assert img[0, 0] < 0.2 and img[2, 2] == 1.0 and 0.7 < img[4, 6] < 0.9
