"""Ranging, the median filter, trilateration on known geometry, LF override, heading, quality."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.rfid.localiser import Localiser, least_squares, triangle_centroid
from drivers.rfid.protocol import Read
from drivers.rfid.rssi import ReadModel, distance_from_rssi, rssi_at
from drivers.rfid.tags import Tag, TagMap, TagMapFile

UHF = {"AAAA0001": (0.0, 0.0), "AAAA0002": (4.0, 0.0), "AAAA0003": (0.0, 4.0),
       "AAAA0004": (4.0, 4.0)}
LF = {"BBBB0001": (1.0, 1.0), "BBBB0002": (1.2, 1.0), "BBBB0003": (1.1, 1.2)}


def small_map() -> TagMap:
    tags = [Tag(id=i, kind="uhf", x=x, y=y) for i, (x, y) in UHF.items()]
    tags += [Tag(id=i, kind="lf", x=x, y=y) for i, (x, y) in LF.items()]
    return TagMap(TagMapFile(width_m=5.0, height_m=5.0, tags=tags))


def feed_exact(loc: Localiser, p: tuple[float, float], t: float, reads: int = 5) -> None:
    """Noise-free reads of every UHF tag as seen from p (RSSI to one decimal, as on the wire)."""
    for tid, xy in UHF.items():
        r = round(float(rssi_at(math.dist(p, xy))), 1)
        for k in range(reads):
            loc.add(Read(tid, r, t - 0.01 * k))


def test_ranging_is_the_papers_formula() -> None:
    # A = 45.8 dB at 1 m, n = 3: |RSSI| = 45.8 + 30 log10(d).
    assert float(rssi_at(1.0)) == pytest.approx(-45.8)
    assert float(rssi_at(10.0)) == pytest.approx(-75.8)
    assert float(distance_from_rssi(-75.8)) == pytest.approx(10.0)
    assert float(distance_from_rssi(-45.8 - 15.0)) == pytest.approx(10 ** 0.5)
    d = np.array([0.3, 1.0, 2.5, 7.0])
    np.testing.assert_allclose(distance_from_rssi(rssi_at(d)), d)


def test_median_of_reads_ignores_an_outlier() -> None:
    loc = Localiser(small_map(), method="centroid", n_reads=5)
    good = round(float(rssi_at(2.0)), 1)
    for k, r in enumerate([good, good + 0.4, -20.0, good - 0.4, good]):  # -20 dBm: a spike
        loc.add(Read("AAAA0001", r, 10.0 + 0.01 * k))
    idx, d, _ = loc._ranges(10.05)
    assert list(idx) == [0]
    assert d[0] == pytest.approx(2.0, rel=0.01)


def test_only_the_last_n_reads_count() -> None:
    loc = Localiser(small_map(), n_reads=3)
    for k in range(6):  # the first three say 1 m, the last three 3 m
        r = float(rssi_at(1.0 if k < 3 else 3.0))
        loc.add(Read("AAAA0001", r, 5.0 + 0.01 * k))
    _, d, _ = loc._ranges(5.1)
    assert d[0] == pytest.approx(3.0, rel=0.01)


@pytest.mark.parametrize("p", [(1.0, 1.0), (2.0, 3.0), (3.3, 0.7)])
def test_trilateration_on_exact_ranges(p: tuple[float, float]) -> None:
    centres = np.array([UHF["AAAA0001"], UHF["AAAA0002"], UHF["AAAA0003"]])
    d = np.hypot(*(centres - p).T)
    np.testing.assert_allclose(triangle_centroid(centres, d), p, atol=1e-9)
    np.testing.assert_allclose(least_squares(centres, d, np.array([2.0, 2.0])), p, atol=1e-6)


def test_triangle_centroid_when_ranges_miss_each_other() -> None:
    # Ranges too short to meet (each 1.5 m to tags 4 m apart): the paper's triangle still
    # forms from the gap midpoints and its centroid lies inside the tags' triangle.
    centres = np.array([UHF["AAAA0001"], UHF["AAAA0002"], UHF["AAAA0003"]])
    p = triangle_centroid(centres, np.array([1.5, 1.5, 1.5]))
    assert 0 < p[0] < 4 and 0 < p[1] < 4 and p[0] + p[1] < 4
    np.testing.assert_allclose(p, [4 / 3, 4 / 3], atol=1e-9)  # symmetric gaps → centroid


def test_least_squares_beats_centroid_on_noisy_ranges() -> None:
    rng = np.random.default_rng(1)
    centres = np.array(list(UHF.values()))
    err_c, err_l = [], []
    for _ in range(300):
        p = rng.uniform(0.5, 3.5, 2)
        d = np.hypot(*(centres - p).T) * 10 ** (rng.normal(0, 1.5, 4) / 30)
        order = np.argsort(d)
        c = triangle_centroid(centres[order[:3]], d[order[:3]])
        err_c.append(np.hypot(*(c - p)))
        err_l.append(np.hypot(*(least_squares(centres[order], d[order], c) - p)))
    assert np.median(err_l) < np.median(err_c)


@pytest.mark.parametrize("method", ["centroid", "lsq"])
def test_localiser_finds_a_still_user(method: str) -> None:
    loc = Localiser(small_map(), method=method)
    feed_exact(loc, (1.5, 2.5), t=3.0)
    est = loc.estimate(3.0)
    assert est is not None and est.source == "uhf"
    assert math.hypot(est.x - 1.5, est.y - 2.5) < 0.02
    assert 0.0 < est.quality < 1.0


def test_no_pose_from_fewer_than_three_tags_or_stale_reads() -> None:
    loc = Localiser(small_map(), window_s=0.5)
    loc.add(Read("AAAA0001", -50.0, 1.0))
    loc.add(Read("AAAA0002", -50.0, 1.0))
    assert loc.estimate(1.0) is None
    feed_exact(loc, (2.0, 2.0), t=1.0)
    assert loc.estimate(1.0) is not None
    assert loc.estimate(2.0) is None  # every read older than the window


@pytest.mark.parametrize(
    ("seen", "expected"),
    [
        (["BBBB0001"], (1.0, 1.0)),  # one tag: its position
        (["BBBB0001", "BBBB0002"], (1.1, 1.0)),  # two: the midpoint
        (["BBBB0001", "BBBB0002", "BBBB0003"], (1.1, 16 / 15)),  # three: the centroid
    ],
)
def test_lf_read_overrides_uhf(seen: list[str], expected: tuple[float, float]) -> None:
    loc = Localiser(small_map())
    feed_exact(loc, (3.0, 3.0), t=7.0)  # UHF says (3, 3)…
    for tid in seen:
        loc.add(Read(tid, -40.0, 7.0))  # …the floor says otherwise, and wins
    est = loc.estimate(7.0)
    assert est is not None and est.source == "lf" and est.n_tags == len(seen)
    assert (est.x, est.y) == pytest.approx(expected)
    assert est.quality == 1.0


def test_lf_read_expires_into_a_hold_then_uhf() -> None:
    loc = Localiser(small_map(), lf_window_s=0.05, lf_hold_s=0.3)
    loc.add(Read("BBBB0001", -40.0, 7.0))
    feed_exact(loc, (3.0, 3.0), t=7.2)
    held = loc.estimate(7.2)
    assert held is not None and held.source == "lf-hold"
    assert (held.x, held.y) == pytest.approx((1.0, 1.0))  # one fix: no speed to carry on
    assert 0.5 < held.quality < 1.0
    est = loc.estimate(7.4)
    assert est is not None and est.source == "uhf"


def test_heading_from_successive_positions() -> None:
    loc = Localiser(small_map(), heading_min_m=0.15)
    assert loc.heading == pytest.approx(math.pi / 2)  # no motion yet: facing north
    for k, x in enumerate([1.0, 1.1, 1.2, 1.3, 1.4]):  # walking east…
        t = 1.0 + 0.1 * k
        feed_exact(loc, (x, 1.0), t)
        est = loc.estimate(t)
    assert est is not None and abs(est.heading) < 0.1
    for k, y in enumerate([1.2, 1.4, 1.6, 1.8]):  # …then south-west, diagonally
        t = 2.0 + 0.1 * k
        feed_exact(loc, (1.4 - (y - 1.0), 2.0 - y), t)
        est = loc.estimate(t)
    assert est is not None and est.heading == pytest.approx(-3 * math.pi / 4, abs=0.1)


def test_quality_falls_with_noise() -> None:
    tag_map = small_map()
    qualities = {}
    for sigma in (0.5, 6.0):
        model = ReadModel.for_tags(tag_map, sigma_read_db=sigma, sigma_tag_db=0.0, dropout=0.0,
                                   seed=3)
        model.lf_xy = np.empty((0, 2))
        model.lf_ids = []
        loc = Localiser(tag_map)
        q = []
        for k in range(50):
            for read in model.round(2.2, 1.7, 0.1 * k):
                loc.add(read)
            est = loc.estimate(0.1 * k)
            if est is not None:
                q.append(est.quality)
        qualities[sigma] = float(np.median(q))
    assert qualities[0.5] > qualities[6.0]


def test_unknown_method_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown method"):
        Localiser(small_map(), method="magic")
