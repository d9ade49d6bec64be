"""The sensor's geometry: range, field of view, and the delta it reports."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN
from sim.sensor import Sensor

pytestmark = pytest.mark.timeout(30)

SHAPE = (81, 81)
CENTRE = (40, 40)


def offsets(seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rr, cc = np.divmod(seen, SHAPE[1])
    return rr - CENTRE[0], cc - CENTRE[1]


@pytest.mark.parametrize("heading_deg", [90.0, 0.0, 45.0, -135.0, 180.0])
def test_cells_seen_lie_within_range_and_the_field_of_view(heading_deg):
    sensor = Sensor(range_cells=30, fov_deg=80)
    heading = math.radians(heading_deg)
    dr, dc = offsets(sensor.visible(SHAPE, CENTRE, heading))
    dist = np.hypot(dr, dc)
    assert dist.max() <= 30
    bearing = np.arctan2(-dr, dc)
    off = np.abs((bearing - heading + math.pi) % (2 * math.pi) - math.pi)
    assert np.all(off[dist > 0] <= math.radians(40) + 1e-9)
    assert np.any(dist == 0)  # the user's own cell
    # straight ahead at full range is seen, straight behind is not
    ahead = (round(-30 * math.sin(heading)), round(30 * math.cos(heading)))
    pairs = set(zip(dr.tolist(), dc.tolist(), strict=True))
    assert ahead in pairs
    assert (-ahead[0] // 2, -ahead[1] // 2) not in pairs


def test_the_field_of_view_is_its_share_of_the_disc():
    narrow = Sensor(range_cells=30, fov_deg=80).visible(SHAPE, CENTRE, 1.0).size
    full = Sensor(range_cells=30, fov_deg=360).visible(SHAPE, CENTRE, 1.0).size
    assert full == np.count_nonzero(
        np.add.outer(np.arange(-30, 31) ** 2, np.arange(-30, 31) ** 2) <= 900
    )
    assert narrow / full == pytest.approx(80 / 360, rel=0.05)


def test_cells_outside_the_map_are_dropped():
    seen = Sensor(range_cells=10, fov_deg=360).visible(SHAPE, (0, 0), 0.0)
    assert seen.min() >= 0 and seen.max() < SHAPE[0] * SHAPE[1]
    rr, cc = np.divmod(seen, SHAPE[1])
    assert np.all(rr <= 10) and np.all(cc <= 10)


def test_sense_reports_only_what_changes_in_view():
    true = np.full(SHAPE, FREE, dtype=np.uint8)
    true[20, 40] = OCCUPIED  # 20 cells north: ahead
    true[60, 40] = OCCUPIED  # 20 cells south: behind
    known = np.full(SHAPE, UNKNOWN, dtype=np.uint8)
    sensor = Sensor(range_cells=30, fov_deg=80)
    cells, values = sensor.sense(true, known, CENTRE, math.pi / 2)
    assert set(values.tolist()) == {int(FREE), int(OCCUPIED)}
    assert 20 * SHAPE[1] + 40 in cells[values == OCCUPIED]
    assert 60 * SHAPE[1] + 40 not in cells
    known.reshape(-1)[cells] = values
    again, _ = sensor.sense(true, known, CENTRE, math.pi / 2)
    assert again.size == 0


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError):
        Sensor(range_cells=0)
    with pytest.raises(ValueError):
        Sensor(range_cells=5, fov_deg=0)
