"""Tags that carry the map: payloads, map deltas, and the visibility graph planning on them."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from pydantic import ValidationError

from daemon.planning.grid import OCCUPIED
from daemon.planning.inflation import InflatedMap
from daemon.planning.visgraph.planner import VisGraphPlanner
from drivers.rfid.tag_payload import ObstacleBook, ObstaclePayload, decode, encode
from sim.courtyard import make_courtyard
from sim.tag_payloads import obstacle_payloads

SQUARE = ((1.0, 1.0), (2.0, 1.0), (2.0, 2.0), (1.0, 2.0))


def _apply(grid: np.ndarray, book: ObstacleBook, seq: int) -> None:
    delta = book.delta(seq, float(seq))
    assert delta is not None and delta.seq == seq
    grid.reshape(-1)[delta.cell_array()] = delta.value_array()


def test_a_payload_survives_the_tag_and_fits_its_memory() -> None:
    hexagon = ((1.0, 0.0), (2.0, 0.5), (2.0, 1.5), (1.0, 2.0), (0.0, 1.5), (0.0, 0.5))
    p = ObstaclePayload(obstacle=7, x=2.0, y=0.5, vertices=hexagon)
    raw = encode(p)
    assert len(raw) == 32  # 256 bits, six feature points
    assert decode(raw) == p


@pytest.mark.parametrize(
    ("raw", "why"),
    [
        (b"\x01\x00", "shorter than its header"),
        (struct.pack("<BHHHB", 2, 0, 0, 0, 3) + b"\0" * 12, "version 2"),
        (struct.pack("<BHHHB", 1, 0, 0, 0, 7) + b"\0" * 28, "7 feature points"),
        (struct.pack("<BHHHB", 1, 0, 0, 0, 4) + b"\0" * 12, "does not hold 4"),
        # Clockwise, a concave dart and a five-pointed star: none is the paper's polygon.
        (encode(ObstaclePayload(obstacle=1, x=1, y=1, vertices=SQUARE))[:8]
         + struct.pack("<8H", 100, 100, 100, 200, 200, 200, 200, 100), "not a convex"),
        (struct.pack("<BHHHB", 1, 0, 0, 0, 4) + struct.pack("<8H", 0, 0, 200, 100, 0, 200, 50, 100),
         "not a convex"),
        (struct.pack("<BHHHB", 1, 0, 0, 0, 5)
         + struct.pack("<10H", 200, 400, 80, 40, 390, 260, 10, 260, 320, 40), "cross themselves"),
    ],
 ids=["short", "version", "seven", "truncated", "clockwise", "concave", "star"],
)  # fmt: skip
def test_bad_payloads_are_rejected_whole_and_the_book_keeps_going(raw, why) -> None:
    with pytest.raises((ValueError, ValidationError), match=why):
        decode(raw)
    book = ObstacleBook((40, 40), 0.1)
    assert not book.read(raw) and why.split()[0] in book.rejected[0]
    assert book.delta(0, 0.0) is None
    off_map = ObstaclePayload(obstacle=2, x=1, y=1, vertices=((3.0, 3.0), (5.0, 3.0), (4.0, 5.0)))
    assert not book.read(encode(off_map)) and "past the map" in book.rejected[-1]
    assert book.read(encode(ObstaclePayload(obstacle=1, x=1, y=1, vertices=SQUARE)))


def test_a_courtyards_tags_rebuild_its_known_obstacles_cell_for_cell() -> None:
    scenario = make_courtyard(100, 0.2, 0)
    payloads = obstacle_payloads(scenario.known, scenario.cell_m)
    book = ObstacleBook(scenario.shape, scenario.cell_m)
    new = [book.read(raw) for raw in payloads]
    assert sum(new) == len(book._pending) and sum(new) < len(payloads)  # one per obstacle
    grid = np.zeros(scenario.shape, dtype=np.uint8)
    _apply(grid, book, 0)
    assert np.array_equal(grid == OCCUPIED, scenario.known == OCCUPIED)
    assert all(len(v) <= 6 for v in book.polygons.values())
    # Read again (the user walks past the same tags): nothing new, no delta.
    assert not any(book.read(raw) for raw in payloads)
    assert book.delta(1, 1.0) is None


def test_the_visibility_graph_plans_around_the_obstacles_the_tags_carried() -> None:
    scenario = make_courtyard(100, 0.2, 0)
    book = ObstacleBook(scenario.shape, scenario.cell_m)
    for raw in obstacle_payloads(scenario.known, scenario.cell_m):
        book.read(raw)
    grid = np.zeros(scenario.shape, dtype=np.uint8)
    _apply(grid, book, 0)
    from_tags, from_survey = VisGraphPlanner(fallback=False), VisGraphPlanner(fallback=False)
    from_tags.plan(InflatedMap(grid, scenario.radius_cells).blocked, scenario.goal)
    from_survey.plan(InflatedMap(scenario.known, scenario.radius_cells).blocked, scenario.goal)
    path = from_tags.path(scenario.start)
    assert len(path) and tuple(path[-1]) == tuple(scenario.goal)
    assert not np.any(scenario.known[path[:, 0], path[:, 1]] == OCCUPIED)
    assert len(from_tags.pieces()) == len(from_survey.pieces())
    assert np.array_equal(from_survey.path(scenario.start), path)
    assert from_tags.last_length == pytest.approx(from_survey.last_length)


def test_an_obstacle_moved_frees_the_cells_it_left() -> None:
    book = ObstacleBook((40, 40), 0.1)
    book.read(encode(ObstaclePayload(obstacle=3, x=1, y=1, vertices=SQUARE)))
    grid = np.zeros((40, 40), dtype=np.uint8)
    _apply(grid, book, 0)
    assert int((grid == OCCUPIED).sum()) == 100  # 1 m square, 10 cm cells
    moved = tuple((x + 0.5, y) for x, y in SQUARE)
    assert book.read(encode(ObstaclePayload(obstacle=3, x=1.5, y=1, vertices=moved)))
    _apply(grid, book, 1)
    rows, cols = np.nonzero(grid == OCCUPIED)
    assert rows.size == 100
    xs = (cols + 0.5) * 0.1
    assert xs.min() == pytest.approx(1.55) and xs.max() == pytest.approx(2.45)
