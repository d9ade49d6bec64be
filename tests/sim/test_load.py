"""`guidebelt load` in small: a real daemon process, users with fresh poses and map deltas;
every delta of a guided user is answered by a belt pattern, no stale_pose is ever false."""

from __future__ import annotations

import pytest

from sim.load import LoadSpec, run_against_daemon


@pytest.mark.timeout(120)
def test_three_users_load_a_daemon_process_and_every_delta_is_answered():
    spec = LoadSpec(users=3, grid=60, seconds=3.0, warmup_s=1.0, join_hz=10.0)
    result = run_against_daemon(spec)
    assert result["served"] + result["overloaded"] == 3 and result["served"] >= 1
    assert result["false_stale_pose"] == 0
    # 10 Hz deltas for 3 s per guided user, each answered by the step that applied it.
    assert result["deltas_measured"] >= 20 * result["served"] and result["unanswered"] == 0
    assert 0 < result["p50_ms"] <= result["p99_ms"] <= result["max_ms"]
