"""Every registered planner guides the daemon's demo to arrival (issue 22): the real daemon on
an embedded zenoh session, the simulated world and walker, the planner chosen by name."""

from __future__ import annotations

import threading

import pytest

from cli.demo_world import run_with_daemon
from daemon.planning.registry import PLANNERS

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize("planner", list(PLANNERS))
def test_the_daemon_demo_arrives_with_every_planner(planner, tmp_path):
    threads_before = threading.active_count()
    out = tmp_path / f"{planner}.png"
    arrived = run_with_daemon(grid=50, unknown=0.4, seed=0, backend="cpu", follow="belt",
                              out=out, planner=planner, guide_hz=100)  # fmt: skip
    assert arrived, f"{planner}: the demo walk did not arrive"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert threading.active_count() <= threads_before + 1  # zenoh's own pool may stay
