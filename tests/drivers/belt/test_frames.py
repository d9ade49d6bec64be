"""The frame protocol: Python and C agree with vectors.json byte for byte."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.belt import frames as F
from drivers.belt import hil

VECTORS = json.loads((Path(F.__file__).parent / "vectors.json").read_text())


def test_crc_is_ccitt_false():
    assert VECTORS["crc"]["algorithm"] == "CRC-16/CCITT-FALSE"
    assert F.crc16(b"123456789") == int(VECTORS["crc"]["check"], 16) == 0x29B1


@pytest.mark.parametrize("vector", VECTORS["frames"], ids=lambda v: v["name"])
def test_python_encodes_and_decodes_frames(vector):
    raw = bytes.fromhex(vector["hex"])
    (frame,) = F.Parser().feed(raw)
    assert F.encode(frame.ftype, frame.seq, frame.payload) == raw
    msg = frame.decode()
    # Host frames whose payload is no more than one number carry no message class.
    simple = (F.FrameType.STOP, F.FrameType.PING, F.FrameType.INTENSITY, F.FrameType.BUTTON_ACK)
    assert msg is not None or frame.ftype in simple
    if isinstance(msg, F.Pattern | F.Ack | F.Heartbeat | F.Button | F.Status):
        assert msg.payload() == frame.payload


def test_new_frame_types_decode_to_what_was_encoded():
    (button,) = F.Parser().feed(
        F.encode(F.FrameType.BUTTON, 3, F.Button(9, 1, F.PressKind.LONG).payload())
    )
    assert button.decode() == F.Button(9, 1, F.PressKind.LONG)
    status = F.Status(battery_mv=3650, intensity=25, pending=2, presses=70, presses_dropped=1)
    (frame,) = F.Parser().feed(F.encode(F.FrameType.STATUS, 4, status.payload()))
    assert frame.decode() == status
    # A press kind this side does not know is no press: refused like an unknown type.
    bad = F.encode(F.FrameType.BUTTON, 5, bytes([1, 0, 0, 3]))
    assert F.Parser().feed(bad)[0].decode() is None


def test_python_scales_intensity_like_the_vectors():
    for case in VECTORS["intensity"]:
        assert F.scale_level(case["level"], case["intensity"]) == case["out"], case


@settings(max_examples=300, deadline=None)
@given(
    a=st.integers(0, 255), b=st.integers(0, 255), intensity=st.integers(0, 100),
)  # fmt: skip
def test_intensity_keeps_shape_floor_and_direction(a, b, intensity):
    sa, sb = F.scale_level(a, intensity), F.scale_level(b, intensity)
    assert (sa == 0) == (a == 0)  # a motor that is off stays off, one that is on stays on
    assert sa <= a and sa >= (a * F.INTENSITY_FLOOR_PCT) // 100  # never below the floor
    if a >= b:
        assert sa >= sb  # the stronger motor stays the stronger
    if a + b >= 40:  # a GUIDE blend: the direction's fraction moves by rounding only
        assert abs(sa / max(sa + sb, 1) - a / (a + b)) <= 1.5 / (sa + sb)


@pytest.mark.parametrize("case", VECTORS["parser"], ids=lambda v: v["name"])
def test_python_parser_matches_vectors(case):
    p = F.Parser()
    got = p.feed(bytes.fromhex(case["input"]))
    if case["timeout_at_end"]:
        p.timeout()
    assert [dict(type=f.ftype, seq=f.seq, payload=f.payload.hex()) for f in got] == case["frames"]
    assert vars(p.counters()) == case["counters"]


def _frame_check(lines: list[str]) -> list[str]:
    out = subprocess.run(
        [str(hil.FRAME_CHECK)], input="\n".join(lines) + "\n", capture_output=True, text=True,
        timeout=10, check=True,
    )  # fmt: skip
    return out.stdout.splitlines()


def test_c_side_matches_vectors(simavr_built):
    """firmware/frame.c, compiled for the host, against the same vectors."""
    assert _frame_check(["C " + b"123456789".hex()]) == ["crc 29b1"]
    for v in VECTORS["frames"]:
        raw = bytes.fromhex(v["hex"])
        (frame,) = F.Parser().feed(raw)
        payload = frame.payload.hex() or "-"
        assert _frame_check([f"E {frame.ftype} {frame.seq} {payload}"]) == [f"frame {v['hex']}"]
    cases = VECTORS["intensity"]
    got = _frame_check([f"S {c['level']} {c['intensity']}" for c in cases])
    assert got == [f"level {c['out']}" for c in cases]
    for case in VECTORS["parser"]:
        lines = _frame_check([f"P {case['input']} {int(case['timeout_at_end'])}"])
        want = [f"frame {f['type']} {f['seq']} {f['payload'] or '-'}" for f in case["frames"]]
        c = case["counters"]
        want.append(
            f"counters {c['rx_frames']} {c['crc_errors']} {c['oversized']} "
            f"{c['truncated']} {c['malformed']}"
        )
        assert lines == want, case["name"]


@settings(max_examples=200, deadline=None)
@given(noise=st.binary(max_size=80), cut=st.integers(min_value=0, max_value=20))
def test_parser_finds_a_good_frame_after_any_garbage(noise, cut):
    good = F.pattern_frame(9, F.Pattern((1, 2, 3, 4), 0, 300))
    p = F.Parser()
    p.feed(noise + good[:cut])
    p.timeout()  # the line went quiet: whatever was pending is dropped
    assert p.feed(good) == [F.Frame(F.FrameType.PATTERN, 9, good[6:-2])]


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=200))
def test_parser_never_keeps_more_than_one_frame(data):
    p = F.Parser()
    p.feed(data)
    assert len(p.buf) < F.MAX_FRAME


def _random_stream(rng) -> bytes:
    """Good frames, flipped bits, cut frames, oversized headers and noise, mixed."""
    out = b""
    for _ in range(rng.randint(1, 6)):
        motors = tuple(rng.randint(0, 255) for _ in range(4))
        frame = rng.choice([
            F.pattern_frame(rng.randint(0, 0xFFFF), F.Pattern(motors, rng.randint(0, 5000),
                                                              rng.randint(50, 5000))),
            F.ping_frame(rng.randint(0, 0xFFFF)),
            F.stop_frame(rng.randint(0, 0xFFFF)),
        ])  # fmt: skip
        kind = rng.randint(0, 4)
        if kind == 1:
            bit = rng.randrange(len(frame) * 8)
            frame = bytearray(frame)
            frame[bit // 8] ^= 1 << (bit % 8)
            frame = bytes(frame)
        elif kind == 2:
            frame = frame[: rng.randrange(1, len(frame))]
        elif kind == 3:
            frame = bytes([F.START, F.VERSION, 1, rng.randint(25, 255)]) + rng.randbytes(8)
        elif kind == 4:
            frame = rng.randbytes(rng.randint(0, 12)) + frame
        out += frame
    return out


def test_c_and_python_parsers_agree_on_random_streams(simavr_built):
    import random

    rng = random.Random(6)
    streams = [(_random_stream(rng), rng.random() < 0.3) for _ in range(300)]
    lines = _frame_check([f"P {data.hex() or '-'} {int(to)}" for data, to in streams])
    want = []
    for data, to in streams:
        p = F.Parser()
        frames = p.feed(data)
        if to:
            p.timeout()
        want += [f"frame {f.ftype} {f.seq} {f.payload.hex() or '-'}" for f in frames]
        c = p.counters()
        want.append(f"counters {c.rx_frames} {c.crc_errors} {c.oversized} {c.truncated} "
                    f"{c.malformed}")  # fmt: skip
    assert lines == want
