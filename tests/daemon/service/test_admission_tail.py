"""Admission control judges the lag the promise is made on: the p99 of the steps that answered
an input (map delta, goal, refusal, button), against the budget less the part of the delay the
daemon cannot see (zenoh's way in and out, the client's receive)."""

from __future__ import annotations

import numpy as np

from daemon.service.admission import Admission, AdmissionSettings


def window(adm: Admission, users, now: float, lags, urgent: bool = True) -> None:
    """One step of each user per lag in ``lags``, spread over the second before ``now`` (no
    CPU: the lag alone is judged here)."""
    lags = list(lags)
    for i, lag in enumerate(lags):
        for u in users:
            adm.record(u, lag, 0.0, now - 0.95 + i * 0.9 / len(lags), urgent)


def guided(n: int = 20, **settings: float) -> tuple[Admission, list[str]]:
    adm = Admission(AdmissionSettings(**settings))
    users = [f"u{i:02d}" for i in range(n)]
    for u in users:
        adm.join(u, 0.0)
    return adm, users


def tail(share: float, late_ms: float, n: int = 100, base_ms: float = 5.0) -> np.ndarray:
    """``n`` lags, ``share`` of them ``late_ms``, the rest ``base_ms``, late ones spread out."""
    lags = np.full(n, base_ms)
    lags[np.linspace(0, n - 1, round(share * n)).astype(int)] = late_ms
    return lags


def test_a_tail_the_p95_does_not_see_is_shed_for():
    """3 % of the deltas 100 ms late, the rest 5 ms: the p95 is 5 ms, the p99 100. On the dev
    VM at 100 users such seconds gave a served p99 of 100-140 ms while the p95 judged 12-25."""
    adm, users = guided()
    shed = []
    for t in (10.0, 10.25, 10.5, 10.75):
        window(adm, users, t, tail(0.03, 100.0))
        shed += adm.review(t)[0]
    assert adm.last_p95_ms == 5.0 and adm.last_lag_ms == 100.0
    assert shed == [f"u{i:02d}" for i in range(10, 20)]  # 1 − 40/100 capped at half
    # The old rule (p95 against 60 % of the budget, nothing kept for the unseen) kept all.
    old, users = guided(percentile=95.0, unseen_ms=0.0, shed_fraction=0.6)
    for t in (10.0, 10.25, 10.5, 10.75):
        window(old, users, t, tail(0.03, 100.0))
        assert old.review(t) == ([], [])


def test_the_budget_less_what_the_daemon_cannot_see_is_the_line():
    """A p99 of 45 ms is within the 50 ms budget but not once zenoh's way in and out (~10 ms
    at p99, measured) is added: shed. 35 ms is not."""
    for lag, expect in ((45.0, 3), (35.0, 0)):
        adm, users = guided()
        shed = []
        for t in (10.0, 10.25, 10.5, 10.75):
            window(adm, users, t, tail(0.05, lag))
            shed += adm.review(t)[0]
        assert len(shed) == expect, lag  # 1 − 40/45 of 20, rounded up
    # A budget too small for the headroom keeps half of it for the daemon.
    small, users = guided(lag_budget_ms=16.0)
    for t in (10.0, 10.25, 10.5, 10.75):
        window(small, users, t, tail(0.05, 7.5))
        assert small.review(t) == ([], [])  # 7.5 ≤ 16 / 2, though 16 − 10 = 6


def test_poses_alone_do_not_hide_the_deltas_tail():
    """A pose alone answers no input (its lag is its own step's): two pose steps per delta
    step at 1 ms put the deltas' 2 % at 120 ms under the p99 of all, not of the deltas."""
    adm, users = guided()
    for t in (10.0, 10.25, 10.5, 10.75):
        window(adm, users, t, tail(0.02, 120.0))
        window(adm, users, t, np.full(200, 1.0), urgent=False)
        shed = adm.review(t)[0]
        if shed:
            break
    assert adm.last_lag_ms == 120.0 and len(shed) == 10
    every = np.concatenate([tail(0.02, 120.0), np.full(200, 1.0)])
    assert np.percentile(every, 99) < 40.0  # the p99 of all steps: under the line
    # With no input to answer (a map that does not change), the poses' steps are judged.
    still, users = guided()
    for t in (10.0, 10.25, 10.5, 10.75):
        window(still, users, t, tail(0.05, 120.0), urgent=False)
        shed = still.review(t)[0]
        if shed:
            break
    assert still.last_lag_ms == 120.0 and len(shed) == 10


def test_calm_is_judged_on_the_p99_too():
    """Readmission waits for a p99 under 30 % of the budget the daemon sees (12 ms): at 100
    users on the dev VM a p95 of 5 with a p99 of 20 ms readmitted 6 users in each worker into
    a lag of 100-250 ms."""
    adm, users = guided(min_shed_s=1.0, calm_s=1.0)
    for t in (10.0, 10.6):
        window(adm, users, t, np.full(100, 600.0))  # as many steps as after: the same cost
        adm.review(t)
    assert len(adm.shed) == 10
    guided_now = users[:10]
    for t in np.arange(11.0, 16.0, 0.25):  # p95 5 ms, p99 20 ms: not calm
        window(adm, guided_now, t, tail(0.02, 20.0))
        assert adm.review(t) == ([], []), t
    assert adm.last_p95_ms == 5.0 and adm.last_lag_ms == 20.0
    back = []
    for t in np.arange(16.0, 19.0, 0.25):  # p99 10 ms: calm
        window(adm, guided_now, t, tail(0.02, 10.0))
        back += adm.review(t)[1]
    assert back[0] == "u10"


def test_joining_users_first_steps_are_judged_at_the_p95_against_the_whole_budget():
    """Joins' whole-map steps are the tail while they last (50 users, dev VM: a p99 of 63-70
    ms for a second, 3-17 after): a p99 over the budget with the p95 under it sheds nobody."""
    adm = Admission(AdmissionSettings())
    users = [f"u{i:02d}" for i in range(20)]
    for i, u in enumerate(users):
        adm.join(u, 9.0 + i * 0.08)  # the last joins at 10.52
    for t in (10.0, 10.25, 10.5, 10.75):
        window(adm, users, t, tail(0.03, 70.0))
        assert adm.review(t) == ([], [])
    assert adm.last_lag_ms == 5.0  # the p95, while they join
    for t in (11.75, 12.0, 12.25, 12.5):  # joins over: the same tail is judged at the p99
        window(adm, users, t, tail(0.03, 70.0))
        shed = adm.review(t)[0]
        if shed:
            break
    assert adm.last_lag_ms == 70.0 and shed == [f"u{i:02d}" for i in range(11, 20)]


def test_users_come_back_one_at_a_time_and_a_lag_right_after_sends_them_back_at_once():
    """A quarter of the guided at once (7-10) took a worker of the dev VM at 100 users from a
    p99 of 5-11 ms to 56-105; a lag over the line within ``overshoot_s`` of a readmission is
    that readmission's and is undone at its first review, not after ``sustain_s`` or a wait
    for a drain (those 7 stayed 4.1 s with the p99 going over and under the line)."""
    adm, users = guided(min_shed_s=1.0, calm_s=1.0)
    for t in (10.0, 10.6):
        window(adm, users, t, np.full(100, 600.0))
        adm.review(t)
    assert len(adm.shed) == 10
    back: list[str] = []
    t = 11.0
    while not back:
        window(adm, users[:10], t, np.full(100, 5.0))
        back = adm.review(t)[1]
        t += 0.25
    assert back == ["u10"]  # one, however calm
    for _ in range(3):  # no decision for settle_s after one
        window(adm, users[:11], t, np.full(100, 5.0))
        assert adm.review(t) == ([], [])
        t += 0.25
    # Over the line at the first review after, draining or not: the one brought back goes.
    lags = np.r_[np.full(50, 90.0), np.full(50, 45.0)]  # the newer half under the older
    window(adm, users[:11], t, lags)
    assert adm.review(t) == (["u10"], []) and adm.overshoots == 1 and adm.draining
    # The same lag with no readmission behind it waits out sustain_s and the drain.
    other, users = guided()
    window(other, users, 10.0, np.full(100, 5.0))
    other.review(10.0)
    window(other, users, 10.25, lags)
    assert other.review(10.25) == ([], [])


def test_a_burst_is_waited_out_once_and_bursts_that_come_back_are_the_load():
    """Each user steps every 50 ms, reviewed every 0.25 s. One 0.2 s stall (150 ms lags) is
    waited out as draining; the same stall every 2 s is not, from its second time on: a
    worker of the dev VM at 100 users went over the line 1.2-6 s apart, each time draining,
    and was waited out for 8 s at a p99 of 45-55 ms."""

    def run(lag_at) -> tuple[list[tuple[float, int]], int]:
        adm, users = guided()
        decisions, t, review_at = [], 8.0, 8.25
        while t < 16.0:
            for u in users:
                if not adm.is_shed(u):
                    adm.record(u, lag_at(t), 0.0, t)
            t = round(t + 0.05, 6)
            if t >= review_at:
                shed, _ = adm.review(t)
                if shed:
                    decisions.append((t, len(shed)))
                review_at = round(review_at + 0.25, 6)
        return decisions, adm.drain_waits

    once, waits = run(lambda t: 150.0 if 10.0 <= t < 10.2 else 8.0)
    assert once == [] and waits == 1
    again, waits = run(lambda t: 150.0 if t >= 10.0 and (t - 10.0) % 2.0 < 0.2 else 8.0)
    assert waits == 1 and again and 12.0 < again[0][0] < 13.0  # the second stall sheds
