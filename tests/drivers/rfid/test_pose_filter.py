"""The pose filter: LF signposts, UHF ranges, steps and compass, heading, honest uncertainty."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.rfid.pose_filter import FilterParams, PoseFilter, _wrap
from drivers.rfid.protocol import Read
from drivers.rfid.rssi import rssi_at
from drivers.rfid.tags import Tag, TagMap, TagMapFile
from protocol.pose_quality import quality_from_sigma

UHF = {"AAAA0001": (1.0, 1.0), "AAAA0002": (3.0, 1.0), "AAAA0003": (2.0, 2.5)}
LF = {"BBBB0001": (2.0, 1.5), "BBBB0002": (2.2, 1.5), "BBBB0003": (6.0, 1.0)}


def tag_map() -> TagMap:
    tags = [Tag(id=i, kind="uhf", x=x, y=y) for i, (x, y) in UHF.items()]
    tags += [Tag(id=i, kind="lf", x=x, y=y) for i, (x, y) in LF.items()]
    return TagMap(TagMapFile(width_m=8.0, height_m=4.0, tags=tags))


def exact_reads(f: PoseFilter, p: tuple[float, float], t: float) -> None:
    for tid, xy in UHF.items():
        f.add(Read(tid, round(float(rssi_at(math.dist(p, xy))), 1), t))


def test_no_pose_before_any_read_then_an_lf_round_pins_it() -> None:
    f = PoseFilter(tag_map())
    assert f.pose(0.0) is None
    f.add(Read("BBBB0001", -40.0, 0.10))
    f.add(Read("BBBB0002", -40.0, 0.101))  # the same round: the paper's midpoint
    pose = f.pose(0.2)
    assert pose is not None and pose.source == "lf"
    assert (pose.x, pose.y) == pytest.approx((2.1, 1.5), abs=1e-9)
    assert pose.sigma_m == pytest.approx(0.05)
    assert pose.quality == pytest.approx(quality_from_sigma(0.05))


def test_uhf_ranges_pull_a_wrong_start_to_the_truth() -> None:
    f = PoseFilter(tag_map(), start=(1.2, 2.3), start_sigma_m=1.0, pedometer=True)
    truth = (2.0, 1.6)
    for k in range(40):
        t = 0.1 * k
        exact_reads(f, truth, t)
        pose = f.pose(t + 0.05)
    assert pose is not None and pose.source == "uhf"
    assert math.dist((pose.x, pose.y), truth) < 0.1
    assert pose.sigma_m < 0.5


def test_one_tags_fixed_offset_is_not_counted_again_and_again() -> None:
    """Standing by the tags, the reads repeat the same offsets: σ must not collapse."""
    sigmas = {}
    for memory in (5.0, 0.0):
        f = PoseFilter(tag_map(), FilterParams(tag_memory_s=memory), start=(2.0, 1.6),
                       pedometer=True)  # fmt: skip
        for k in range(100):
            exact_reads(f, (2.0, 1.6), 0.1 * k)
            f.pose(0.1 * k + 0.05)
        sigmas[memory] = f.sigma_m
    assert sigmas[5.0] > 2 * sigmas[0.0]


def test_steps_carry_the_pose_and_its_uncertainty_grows() -> None:
    f = PoseFilter(tag_map(), start=(0.5, 3.0), start_sigma_m=0.05, pedometer=True)
    s0 = f.sigma_m
    for k in range(1, 9):
        f.step(0.5 * k, 0.5, 0.0)  # east, half a metre a step
    pose = f.pose(4.0)
    assert pose is not None
    assert (pose.x, pose.y) == pytest.approx((4.5, 3.0), abs=1e-6)
    assert pose.sigma_m > s0 + 0.1


def test_mid_stride_the_pose_is_ahead_of_the_last_step_and_falls_back_if_none_comes() -> None:
    f = PoseFilter(tag_map(), start=(0.5, 3.0), start_sigma_m=0.05, pedometer=True)
    f.step(0.5, 0.5, 0.0)
    f.step(1.0, 0.5, 0.0)
    mid = f.pose(1.25)
    assert mid is not None and mid.x == pytest.approx(1.75, abs=1e-6)
    later = f.pose(3.0)  # no step for 2 s: the user stopped
    assert later is not None and later.x == pytest.approx(1.5, abs=1e-6)


def test_a_user_felt_to_stand_has_no_stride_under_way_until_the_next_step() -> None:
    f = PoseFilter(tag_map(), start=(0.5, 3.0), start_sigma_m=0.05, pedometer=True)
    f.step(0.5, 0.5, 0.0)
    f.step(1.0, 0.5, 0.0)
    f.still(1.1)  # the IMU felt no stride: the user stopped, a cadence would carry them on
    stood = f.pose(1.5)
    assert stood is not None and stood.x == pytest.approx(1.5, abs=1e-6)
    f.step(2.0, 0.5, 0.0)  # walking again: the stride is carried on as before
    mid = f.pose(2.25)
    assert mid is not None and mid.x > 2.0 + 0.1


def test_turning_on_the_spot_turns_the_heading_at_once() -> None:
    f = PoseFilter(tag_map(), start=(2.0, 2.0), pedometer=True)
    f.step(0.5, 0.5, 0.0)
    f.step(1.0, 0.5, 0.0)
    f.compass(1.1, math.pi / 2)  # turned left on the spot, mid-cadence
    pose = f.pose(1.1)
    assert pose is not None
    assert pose.heading == pytest.approx(math.pi / 2, abs=1e-6)
    assert (pose.x, pose.y) == pytest.approx((3.0, 2.0), abs=1e-6)  # no stride north


def test_the_compass_bias_and_stride_are_learned_from_signposts() -> None:
    """A compass 10° off and a pedometer 8 % short: walking 4 m east and back between two LF
    signposts, the filter learns both, and eq. 3 follows the walk."""
    bias, short = math.radians(10.0), 0.92
    f = PoseFilter(tag_map(), start=(2.1, 1.0), start_sigma_m=0.05, pedometer=True)
    t, x = 0.0, 2.1
    f.lf(t, (x, 1.0), 1)
    for lap in range(8):
        way = 1.0 if lap % 2 == 0 else -1.0
        for _ in range(8):
            t += 0.5
            x += 0.5 * way
            f.step(t, 0.5 * short, (0.0 if way > 0 else math.pi) + bias)
        f.lf(t, (x, 1.0), 1)  # read as the step lands (a stride later it would be ahead)
        t += 2.0  # a pause at each end: the next lap starts from a standstill
    assert f.s[2] == pytest.approx(bias, abs=math.radians(3.0))
    assert 1.0 + f.s[3] == pytest.approx(1.0 / short, abs=0.03)
    assert abs(_wrap(f.heading - math.pi)) < math.radians(3.0)  # last lap: west
    assert f.heading_eq3 is not None and abs(_wrap(f.heading_eq3 - math.pi)) < math.radians(15)


def test_without_a_pedometer_standing_still_grows_unsure() -> None:
    f = PoseFilter(tag_map(), start=(5.0, 3.5), start_sigma_m=0.1)
    f.pose(0.0)
    assert f.pose(4.0).sigma_m > 1.0  # type: ignore[union-attr]
    g = PoseFilter(tag_map(), start=(5.0, 3.5), start_sigma_m=0.1, pedometer=True)
    g.pose(0.0)
    assert g.pose(4.0).sigma_m == pytest.approx(0.1)  # type: ignore[union-attr]


def test_covariance_stays_symmetric_positive() -> None:
    f = PoseFilter(tag_map(), start=(1.5, 1.5), pedometer=True)
    rng = np.random.default_rng(3)
    for k in range(200):
        t = 0.1 * k
        exact_reads(f, (1.5 + 0.01 * k, 1.5), t)
        if k % 5 == 0:
            f.step(t, 0.05, float(rng.normal(0, 0.05)))
        f.pose(t)
    assert np.allclose(f.P, f.P.T)
    assert np.all(np.linalg.eigvalsh(f.P) > 0)
