"""The newly blocked cells' clusters by row runs (``clusters.py``): which runs make one
8-connected cluster, and that the order a delta comes in changes neither the clusters nor
the contacts listed for the cut-off search; and the cells of a delta as cells of the padded
map."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.planning.harmonic.clusters import _joined_each, _linked, _runs
from daemon.planning.harmonic.reach import MARGIN, Reach, padded_cells

pytestmark = pytest.mark.timeout(60)


def clusters_of(cells: np.ndarray, width: int) -> list[set[int]]:
    """The clusters ``_linked`` finds, as sets of cells."""
    starts, ends, m = _runs(cells, width)
    head, after = _linked(starts, ends, m, width)
    out = []
    for root in range(m):
        i, cluster = int(head[root]), set()
        while i >= 0:
            cluster |= set(range(int(starts[i]), int(ends[i]) + 1))
            i = int(after[i])
        if cluster:
            out.append(cluster)
    return out


def test_runs_that_touch_at_a_corner_are_one_cluster_and_a_column_apart_two():
    width = 20  # padded rows; cells in columns 1..18
    staircase = [2 * width + 1, 2 * width + 2, 3 * width + 3, 3 * width + 4, 4 * width + 5]
    apart = [8 * width + 1, 8 * width + 2, 8 * width + 3, 9 * width + 5, 9 * width + 6]
    cells = np.array(staircase + apart, dtype=np.int64)
    got = sorted(clusters_of(cells, width), key=min)
    assert got == [
        set(staircase),
        {8 * width + c for c in (1, 2, 3)},
        {9 * width + 5, 9 * width + 6},
    ]


def test_the_order_of_a_delta_changes_neither_the_clusters_nor_the_contacts_listed():
    # A ring (its pocket cut off: the contacts inside and outside do not join) and a blob in
    # the open: ascending, descending (as ``_flips`` hands a sorted delta back) and shuffled.
    h = w = 40
    rr, cc = np.mgrid[0:h, 0:w]
    shape = (np.maximum(np.abs(rr - 12), np.abs(cc - 12)) == 4) | (
        np.maximum(np.abs(rr - 30), np.abs(cc - 28)) <= 3
    )
    cells = np.flatnonzero(shape.reshape(-1))
    new = (cells // w + 1) * (w + 2) + cells % w + 1
    seen = []
    for order in (new, new[::-1].copy(), np.random.default_rng(3).permutation(new)):
        padded = np.ones((h + 2, w + 2), dtype=np.bool_)
        padded[1:-1, 1:-1] = False
        reach = Reach(padded.reshape(-1), 2 * (w + 2) + 2, w + 2)
        reach.blocked[order] = True  # as ``apply``'s flips leave them
        reach.reach[order] = False
        assert len(clusters_of(order, w + 2)) == 2
        contacts = np.empty(reach.blocked.size, dtype=np.int64)
        n = _joined_each(reach.blocked, reach.reach, order, w + 2, h + 2, MARGIN, reach._mark,
                         reach._queue, reach._label, contacts, reach._out)  # fmt: skip
        assert not reach._label.any() and not reach._mark.any()
        seen.append(sorted(contacts[:n].tolist()))
    ring = (np.maximum(np.abs(rr - 12), np.abs(cc - 12)) == 4).reshape(-1)
    near = np.zeros((h + 2) * (w + 2), dtype=bool)
    for r, c in zip(*np.nonzero(ring.reshape(h, w)), strict=True):
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                if 0 <= r + dr < h and 0 <= c + dc < w and not ring[(r + dr) * w + c + dc]:
                    near[(r + dr + 1) * (w + 2) + c + dc + 1] = True
    assert seen[0] == seen[1] == seen[2] == np.flatnonzero(near).tolist()


def test_padded_cells_match_the_exact_division_at_every_row_end_and_in_any_order():
    # The row comes from a floating-point product corrected by one: the cells either side
    # of each row's end are where a product off by one would show.
    for width in (1, 49, 400, 2000, 4099):  # 1/49 rounds low: 49 · (1/49) < 1
        ends = np.arange(1, 2001, dtype=np.int64) * width
        cells = np.unique(np.concatenate((ends - 1, ends, ends + 1, [0])))
        cells = np.random.default_rng(width).permutation(cells)
        want = (cells // width + 1) * (width + 2) + cells % width + 1
        assert np.array_equal(padded_cells(cells, width), want)
