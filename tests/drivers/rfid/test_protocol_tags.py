"""The line protocol (bad reads rejected and counted) and the tag map (file, validation, layout)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drivers.rfid.protocol import BadLine, ReadFilter, checksum, format_read, parse_line
from drivers.rfid.tags import TagMap, generate

EPC = "E2801160600002080A7C8F31"


def line(body: str) -> bytes:
    return f"{body}*{checksum(body)}\n".encode()


def test_format_and_parse_round_trip() -> None:
    raw = format_read(EPC, -58.46, 123456)
    assert raw == line(f"TAG,{EPC},-58.5,123456")
    read = parse_line(raw, t=12.5)
    assert read is not None
    assert (read.tag_id, read.rssi, read.t, read.reader_ms) == (EPC, -58.5, 12.5, 123456)
    assert parse_line(raw.replace(b"\n", b"\r\n"), 0.0) == parse_line(raw, 0.0)


def test_info_and_empty_lines_are_not_reads() -> None:
    assert parse_line(b"#READY fw=1.2\n", 0.0) is None
    assert parse_line(b"\r\n", 0.0) is None


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (b"hello world\n", "garbage"),
        (b"\xff\xfe\x00TAG\n", "garbage"),
        (line(f"TAG,{EPC.lower()},-58.5,1"), "garbage"),  # ids are upper-case hex
        (line(f"TAG,{EPC},-58.55,1"), "garbage"),  # two decimals
        (line(f"TAG,{EPC},abc,1"), "garbage"),
        (line(f"TAG,{EPC},-58.5,99999999999"), "garbage"),  # 11 digits of reader time
        (line(f"TAG,{EPC},-58.5,4294967296"), "garbage"),  # 2^32
        (line("TAG," + "A" * 40 + ",-58.5,1"), "garbage"),  # id too long
        (b"TAG," + EPC.encode() + b",-58.5,1*00\n", "checksum"),
        (f"TAG,{EPC},-58.5,1".encode() + b"\n", "garbage"),  # no checksum at all
        (line(f"TAG,{EPC},12.0,1"), "impossible_rssi"),  # stronger than 0 dBm
        (line(f"TAG,{EPC},-130.0,1"), "impossible_rssi"),  # under the sensitivity
        (b"TAG," + b"A" * 200 + b"\n", "garbage"),  # overlong
    ],
)
def test_bad_lines_are_rejected_with_a_reason(raw: bytes, reason: str) -> None:
    with pytest.raises(BadLine) as err:
        parse_line(raw, 0.0)
    assert err.value.reason == reason


def test_filter_counts_every_rejection_and_keeps_going() -> None:
    filt = ReadFilter({EPC})
    stream = [
        format_read(EPC, -50.0, 1),
        b"garbage\n",
        line(f"TAG,{EPC},5.0,2"),
        format_read("ABCDEF0123", -50.0, 3),  # well formed, but not in the tag map
        b"TAG," + EPC.encode() + b",-50.0,4*00\n",
        b"#antenna ok\n",
        format_read(EPC, -51.0, 5),
    ]
    reads = [r for raw in stream if (r := filt.feed(raw, 1.0)) is not None]
    assert [r.rssi for r in reads] == [-50.0, -51.0]
    assert filt.counts() == {
        "accepted": 2,
        "garbage": 1,
        "checksum": 1,
        "impossible_rssi": 1,
        "unknown_tag": 1,
        "info": 1,
    }


def courtyard_like() -> np.ndarray:
    occ = np.zeros((60, 60), dtype=np.uint8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 1
    occ[20:30, 10:25] = 1  # a box
    return occ


def test_generator_puts_uhf_tags_on_corners_and_lf_on_free_floor() -> None:
    occ = courtyard_like()
    tag_map = generate(occ, 0.1, lf_layout="floor")
    xy = {(round(x, 2), round(y, 2)) for x, y in tag_map.uhf_xy}
    # The box spans rows 20..29, cols 10..24 → x 1.0..2.5, y (60-30)*0.1=3.0..4.0.
    for corner in [(1.0, 4.0), (2.5, 4.0), (1.0, 3.0), (2.5, 3.0)]:
        assert corner in xy
    # Every LF tag lies on free floor, on the 20 cm lattice.
    rows = 59 - np.floor(tag_map.lf_xy[:, 1] / 0.1).astype(int)
    cols = np.floor(tag_map.lf_xy[:, 0] / 0.1).astype(int)
    assert not occ[rows, cols].any()
    np.testing.assert_allclose((tag_map.lf_xy - 0.1) / 0.2, np.round((tag_map.lf_xy - 0.1) / 0.2),
                               atol=1e-9)
    assert tag_map.lf_range_m == 0.1
    # Every free spot has three UHF tags within the reader's 5 m.
    free = np.argwhere(occ == 0)
    pts = np.column_stack([(free[:, 1] + 0.5) * 0.1, (59 - free[:, 0] + 0.5) * 0.1])
    dist = np.hypot(pts[:, None, 0] - tag_map.uhf_xy[None, :, 0],
                    pts[:, None, 1] - tag_map.uhf_xy[None, :, 1])
    assert ((dist <= 5.0).sum(axis=1) >= 3).all()


def test_layouts() -> None:
    occ = courtyard_like()
    none = generate(occ, 0.1, lf_layout="none")
    corners = generate(occ, 0.1, lf_layout="corners")
    floor = generate(occ, 0.1, lf_layout="floor")
    assert len(none.lf_ids) == 0 < len(corners.lf_ids) < len(floor.lf_ids)
    assert len(set(floor.uhf_ids) | set(floor.lf_ids)) == len(floor.uhf_ids) + len(floor.lf_ids)
    with pytest.raises(ValueError, match="lf_layout"):
        generate(occ, 0.1, lf_layout="everywhere")


def test_tag_map_file_round_trip(tmp_path) -> None:
    tag_map = generate(courtyard_like(), 0.1, seed=4)
    path = tmp_path / "tags.json"
    tag_map.dump(path)
    again = TagMap.load(path)
    assert again.uhf_ids == tag_map.uhf_ids and again.lf_ids == tag_map.lf_ids
    np.testing.assert_allclose(again.uhf_xy, tag_map.uhf_xy)


def _file(tmp_path, tags, **kw) -> str:
    doc = {"format": "guidebelt-tagmap", "version": 1, "width_m": 5.0, "height_m": 5.0,
           "tags": tags, **kw}
    p = tmp_path / "t.json"
    p.write_text(json.dumps(doc))
    return str(p)


UHF3 = [{"id": f"AAAA000{i}", "kind": "uhf", "x": float(i), "y": 1.0} for i in range(3)]


@pytest.mark.parametrize(
    ("tags", "extra", "message"),
    [
        (UHF3[:2], {}, "at least 3 UHF"),
        ([*UHF3, UHF3[0]], {}, "duplicate"),
        ([*UHF3, {"id": "BBBB", "kind": "lf", "x": 9.0, "y": 1.0}], {}, "outside the map"),
        ([*UHF3, {"id": "bbbb", "kind": "lf", "x": 1.0, "y": 1.0}], {}, "pattern"),
        ([*UHF3, {"id": "BBBB", "kind": "hf", "x": 1.0, "y": 1.0}], {}, "kind"),
        (UHF3, {"colour": "red"}, "Extra inputs"),
        (UHF3, {"lf_range_m": -1}, "greater than 0"),
    ],
)
def test_tag_map_validation(tmp_path, tags, extra, message) -> None:
    with pytest.raises(ValueError, match=message):
        TagMap.load(_file(tmp_path, tags, **extra))


def test_tag_map_unreadable(tmp_path) -> None:
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(ValueError, match="cannot read tag map"):
        TagMap.load(p)
    with pytest.raises(ValueError, match="cannot read tag map"):
        TagMap.load(tmp_path / "missing.json")
