"""Every message survives encode → decode; bad bytes are refused whole, with the right code."""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import codec
from protocol.messages import (
    MAX_DELTA_CELLS,
    BeltPattern,
    Goal,
    GoalCell,
    GoalLandmark,
    GoalMetres,
    Health,
    MapDelta,
    MapSnapshot,
    NavPath,
    NavState,
    NavStatus,
    PatternKind,
    Pose,
    Proximity,
    VoiceCue,
)

NOW = 1_790_000_000.25

EXAMPLES = [
    Pose(x=1.5, y=2.25, heading=-0.5, stamp=NOW, quality=0.8),
    Goal(target=GoalCell(row=3, col=4), stamp=NOW),
    Goal(target=GoalMetres(x=1.0, y=9.5), stamp=NOW),
    Goal(target=GoalLandmark(name="fountain"), stamp=NOW),
    BeltPattern(
        seq=7, map_seq=3, kind=PatternKind.GUIDE, motors=(200, 0, 0, 55), ttl_ms=700, stamp=NOW
    ),
    VoiceCue(text="Turn right, 3 metres", kind="direction", stamp=NOW),
    NavStatus(state=NavState.NO_PATH, reason="walled in", code="no_path", stamp=NOW, rejected=2),
    Health(daemon_id="d", uptime_s=3.0, users=["a"], backend="cpu", rejected=0, stamp=NOW),
    NavPath(
        cells=[(5, 5), (4, 5)], cost=10, cell_m=0.1, height=9, width=9, pose_stamp=NOW, stamp=NOW
    ),
    MapDelta.from_arrays(9, (200, 300), np.array([0, 59_999]), np.array([1, 2]), NOW),
    MapSnapshot.from_array(4, np.eye(30, dtype=np.uint8), NOW),
]


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(msg):
    assert codec.decode(type(msg), codec.encode(msg)) == msg


@settings(max_examples=50, deadline=None)
@given(
    h=st.integers(1, 300),
    w=st.integers(1, 300),
    n=st.integers(0, 500),
    seq=st.integers(0, 2**32 - 1),
    seed=st.integers(0, 2**16),
)
def test_delta_binary_round_trip_keeps_every_cell(h, w, n, seq, seed):
    rng = np.random.default_rng(seed)
    cells = rng.integers(0, h * w, n)
    values = rng.integers(0, 3, n).astype(np.uint8)
    data = codec.encode(MapDelta.from_arrays(seq, (h, w), cells, values, NOW))
    assert len(data) == codec.HEADER.size + 5 * n  # compact: 5 bytes a cell, no JSON
    back = codec.decode(MapDelta, data)
    assert (back.seq, back.height, back.width) == (seq, h, w)
    assert np.array_equal(back.cell_array(), cells)
    assert np.array_equal(back.value_array(), values)
    # A producer's own arrays packed straight to bytes (the mapper's path) give the same bytes.
    packed = codec.delta_bytes(seq, h, w, NOW, cells.astype("<u4").tobytes(), values.tobytes())
    assert packed == data


def _maybe(lo: float, hi: float):
    return st.none() | st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@settings(max_examples=100, deadline=None)
@given(ahead=_maybe(0.0, 50.0), nearest=_maybe(0.0, 50.0), bearing=_maybe(-4.0, 4.0),
       frame_stamp=st.floats(0.0, 4e9), stamp=st.floats(0.0, 4e9))  # fmt: skip
def test_proximity_bytes_decode_to_the_models_message(ahead, nearest, bearing, frame_stamp,
                                                      stamp):  # fmt: skip
    """The mapper's packed proximity is read back as the model it stands for, to the bit:
    tiny, huge and negative-zero figures, and None, included."""
    msg = Proximity(ahead_m=ahead, nearest_m=nearest, bearing=bearing, frame_stamp=frame_stamp,
                    stamp=stamp)  # fmt: skip
    data = codec.proximity_bytes(ahead, nearest, bearing, frame_stamp, stamp)
    assert codec.decode(Proximity, data) == msg
    assert json.loads(data) == json.loads(codec.encode(msg))


def header(magic=b"GBMD", version=1, seq=0, h=10, w=10, n=0) -> bytes:
    return struct.pack("<4sHHIIIdI", magic, version, 0, seq, h, w, NOW, n)


@pytest.mark.parametrize(
    ("data", "code"),
    [
        (b"", "malformed"),
        (b"GBMD", "malformed"),
        (header(magic=b"XXXX"), "malformed"),
        (header(version=9), "malformed"),
        (header(n=2) + b"\x00" * 9, "malformed"),  # one byte short
        (header(n=MAX_DELTA_CELLS + 1), "oversized"),  # refused before reading the body
        (header(n=1) + struct.pack("<I", 100) + b"\x01", "invalid"),  # cell 100 of a 10 x 10 map
        (header(n=1) + struct.pack("<I", 5) + b"\x07", "invalid"),  # occupancy 7
        (header(h=0), "invalid"),
    ],
)
def test_bad_deltas_are_refused_with_a_code(data, code):
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(MapDelta, data)
    assert err.value.code == code


@pytest.mark.parametrize(
    ("cells", "values", "ok"),
    [
        ((99, 0, 42), b"\x00\x01\x02", True),  # the last cell of a 10 x 10 map, every value
        ((0xFFFFFFFF,), b"\x01", False),  # the largest uint32, read unsigned
        ((1, 100, 2), b"\x01\x01\x01", False),  # one cell past the end among good ones
        ((1, 2, 3), b"\x01\x03\x00", False),  # 3: just past UNKNOWN
        ((1, 2), b"\x02\xff", False),
    ],
)
def test_a_deltas_cells_and_values_are_checked_at_their_bounds(cells, values, ok):
    data = header(n=len(values)) + struct.pack(f"<{len(cells)}I", *cells) + values
    if ok:
        delta = codec.decode(MapDelta, data)
        assert delta.cell_array().tolist() == list(cells) and delta.values == values
        return
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(MapDelta, data)
    assert err.value.code == "invalid"


def test_snapshot_refuses_wrong_sizes_and_zip_bombs():
    def snap(body: bytes, h=10, w=10) -> bytes:
        return struct.pack("<4sHHIIIdI", b"GBMS", 1, 0, 0, h, w, NOW, len(body)) + body

    assert codec.decode(MapSnapshot, snap(zlib.compress(bytes(100)))).array().shape == (10, 10)
    for body in (zlib.compress(bytes(99)), zlib.compress(bytes(10**7)), b"not zlib"):
        with pytest.raises(codec.DecodeError) as err:
            codec.decode(MapSnapshot, snap(body))
        assert err.value.code == "invalid"


@pytest.mark.parametrize(
    ("kind", "payload", "code"),
    [
        (Pose, b"\xff\xfe", "malformed"),
        (Pose, b'{"x": 1,', "malformed"),
        (Pose, b"[1, 2]", "wrong_type"),
        (Pose, json.dumps({"x": "1m", "y": 0, "heading": 0, "stamp": 1}).encode(), "wrong_type"),
        (
            Pose,
            json.dumps({"x": 1, "y": 0, "heading": 0, "stamp": 1, "z": 0}).encode(),
            "unknown_field",
        ),
        (Pose, json.dumps({"x": 1, "y": 0, "heading": 0}).encode(), "invalid"),
        (Pose, json.dumps({"x": 1, "y": 0, "heading": 0, "stamp": -5}).encode(), "invalid"),
        (
            Goal,
            json.dumps({"target": {"kind": "gps", "lat": 1}, "stamp": 1}).encode(),
            "wrong_type",
        ),
        (
            Goal,
            json.dumps(
                {"target": {"kind": "cell", "row": 1, "col": 1, "x": 1}, "stamp": 1}
            ).encode(),
            "unknown_field",
        ),
    ],
)
def test_bad_json_is_refused_with_a_code(kind, payload, code):
    with pytest.raises(codec.DecodeError) as err:
        codec.decode(kind, payload)
    assert err.value.code == code


def _path_model_bytes(cells: np.ndarray, meta: dict) -> bytes:
    """The path message as the daemon built it before ``PathBytes`` (``StepOutput.path``)."""
    return codec.encode(NavPath.model_construct(cells=[tuple(rc) for rc in cells.tolist()], **meta))


def test_path_bytes_are_the_path_messages_step_after_step():
    """``PathBytes`` keeps the cells' JSON while the cells are equal: every message equals the
    model's own bytes, whatever changed from the last one (stamps only, cells, types)."""
    straight = np.array([(r, 100) for r in range(179, 19, -1)], np.int32)
    bent = np.array([(179, c) for c in range(100, 90, -1)] + [(r, 90) for r in range(178, 20, -1)])
    meta = dict(cost=1600, cell_m=0.05, height=200, width=200, pose_stamp=1764230000.123456,
                stamp=1764230000.2345678, map_seq=17)  # fmt: skip
    steps = [
        (straight, meta),
        (straight, {**meta, "pose_stamp": 1764230000.173456, "stamp": 1764230000.28}),
        (straight.copy(), {**meta, "stamp": 1764230000.33, "map_seq": 18}),
        (bent, {**meta, "cost": 1700, "stamp": 1e10}),
        (bent[1:], {**meta, "cost": 1690, "cell_m": 1}),  # an int for a float field
        (straight[:1], {k: v for k, v in meta.items() if k != "map_seq"}),  # the default
        (straight[:0], {**meta, "cost": 0, "pose_stamp": 1e-7}),
        (bent, {**meta, "cost": np.int64(1700)}),  # a numpy integer: the model's way
    ]
    encoder = codec.PathBytes()
    for cells, m in steps:
        got = encoder(cells, m)
        assert got == _path_model_bytes(cells, m)
        assert codec.decode(NavPath, got).cells == [tuple(rc) for rc in cells.tolist()]
    # Cells refilled in place: compared by value, not by the array.
    cells = straight.copy()
    first = encoder(cells, meta)
    cells[5:, 1] += 1
    assert encoder(cells, meta) == _path_model_bytes(cells, meta)
    assert encoder(cells, meta) != first
