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


def test_a_tls_load_run_is_the_shipped_deployment_for_its_users(tmp_path):
    """``guidebelt load --tls``: the daemon's config is what ``guidebelt certs`` writes for the
    load users (their access rules), on the run's port; the generator is the simulator."""
    pytest.importorskip("cryptography")
    from daemon.service.config import load_config
    from sim.load import _deployment

    env, sim = _deployment(LoadSpec(users=3), 7447, tmp_path)
    daemon = load_config(env["GUIDEBELT_CONFIG"]).zenoh
    assert daemon.access is not None and daemon.access.users == ["load000", "load001", "load002"]
    assert daemon.tls is not None and env["GUIDEBELT_ZENOH__LISTEN"] == '["tls/127.0.0.1:7447"]'
    assert sim.connect == ["tls/127.0.0.1:7447"] and sim.tls is not None
    assert sim.tls.certificate.endswith("sim.pem")
