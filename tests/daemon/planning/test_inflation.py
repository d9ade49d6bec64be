"""InflatedMap: the incremental inflation equals inflation from scratch after any edits."""

from __future__ import annotations

import os

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from daemon.planning.grid import FREE, OCCUPIED, UNKNOWN
from daemon.planning.inflation import InflatedMap, disc_offsets, radius_in_cells

EXAMPLES = int(os.environ.get("GUIDEBELT_HYPOTHESIS_EXAMPLES", "50"))


def from_scratch(occupancy: np.ndarray, radius: int) -> np.ndarray:
    """Blocked = within ``radius`` (centre distance) of an occupied cell, by brute force."""
    h, w = occupancy.shape
    rows, cols = np.nonzero(occupancy == OCCUPIED)
    rr, cc = np.mgrid[0:h, 0:w]
    out = np.zeros((h, w), bool)
    for r, c in zip(rows, cols, strict=True):
        out |= (rr - r) ** 2 + (cc - c) ** 2 <= radius * radius
    return out


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    h=st.integers(1, 24),
    w=st.integers(1, 24),
    radius=st.integers(0, 3),
    seed=st.integers(0, 2**32 - 1),
    n_edits=st.integers(1, 6),
)
def test_incremental_equals_from_scratch(h, w, radius, seed, n_edits):
    rng = np.random.default_rng(seed)
    occ = rng.choice([FREE, OCCUPIED, UNKNOWN], size=(h, w), p=[0.8, 0.1, 0.1]).astype(np.uint8)
    m = InflatedMap(occ, radius)
    np.testing.assert_array_equal(m.blocked, from_scratch(occ, radius))
    for _ in range(n_edits):
        k = int(rng.integers(1, 10))
        cells = rng.integers(0, h * w, k)  # repeats allowed: the last value wins
        values = rng.choice([FREE, OCCUPIED, UNKNOWN], size=k).astype(np.uint8)
        before = m.blocked.copy()
        flipped, now = m.apply(cells, values)
        for c, v in zip(cells, values, strict=True):
            occ.reshape(-1)[c] = v
        expected = from_scratch(occ, radius)
        np.testing.assert_array_equal(m.occupancy, occ)
        np.testing.assert_array_equal(m.blocked, expected)
        changed = np.flatnonzero(before.reshape(-1) != expected.reshape(-1))
        np.testing.assert_array_equal(flipped, changed)
        np.testing.assert_array_equal(now, expected.reshape(-1)[changed])


def test_unknown_is_free_and_radius_conversion():
    occ = np.full((5, 5), UNKNOWN, np.uint8)
    assert not InflatedMap(occ, 2).blocked.any()
    assert radius_in_cells(0.25) == 3 and radius_in_cells(0.2) == 2 and radius_in_cells(0) == 0
    dr, dc = disc_offsets(0)
    assert list(dr) == [0] and list(dc) == [0]
    assert len(disc_offsets(1)[0]) == 5


def test_no_change_reports_nothing():
    m = InflatedMap(np.zeros((4, 4), np.uint8), 1)
    flipped, now = m.apply(np.array([5]), np.array([FREE]))
    assert flipped.size == 0 and now.size == 0
    flipped, _ = m.apply(np.array([5, 6]), np.array([OCCUPIED, OCCUPIED]))
    m2 = InflatedMap(m.occupancy, 1)
    np.testing.assert_array_equal(m.blocked, m2.blocked)
    assert set(flipped.tolist()) == set(np.flatnonzero(m2.blocked).tolist())
