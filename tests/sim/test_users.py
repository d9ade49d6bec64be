"""``guidebelt bench --users`` (``sim/users.py``) on the CPU backend: recorded walks replayed
by several users, round-robin and at a rate, every path checked against the recording."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.app import app
from sim.scenarios import make_scenario
from sim.users import Replay, record, round_robin, run_users

pytestmark = pytest.mark.timeout(60)


def test_replayed_users_step_their_own_walks_round_robin(tmp_path):
    cache = tmp_path / "walks.pkl"
    row = run_users("courtyard", 50, 0.4, "cpu", 3, walks=2, cache=cache)
    recs = [record(make_scenario("courtyard", 50, 0.4, k)) for k in range(2)]
    # users 0 and 2 replay walk 0, user 1 walk 1: every step once
    assert row["steps"] == 2 * recs[0].steps + recs[1].steps > 0
    assert row["walks"] == 2 and row["mode"] == "round-robin"
    assert 0 < row["median"] <= row["p99"] <= row["max"]
    assert cache.exists()  # a second process replays these walks without walking them
    again = run_users("courtyard", 50, 0.4, "cpu", 1, walks=2, cache=cache)
    assert again["steps"] == recs[0].steps


def test_a_path_that_differs_from_the_recording_stops_the_bench():
    from daemon.planning.registry import make_planner

    rec = record(make_scenario("courtyard", 50, 0.4, 5))
    at = next(i for i, op in enumerate(rec.ops) if op[0] == "step" and len(op[4]) > 1)
    op = rec.ops[at]
    wrong = type(rec)(ops=[*rec.ops[:at], (*op[:4], op[4][::-1].copy()), *rec.ops[at + 1 :]])
    with pytest.raises(AssertionError, match="differs"):
        round_robin([Replay(make_planner("eds", "cpu"), wrong, 0)])


def test_users_at_a_rate_are_served_when_due():
    row = run_users("courtyard", 50, 0.4, "cpu", 4, walks=2, hz=20.0, seconds=0.5)
    assert row["mode"] == "rate" and isinstance(row["kept_up"], bool)
    # four users at 20 Hz for half a second: each one's steps fell due 10 times
    assert row["steps"] == 40
    assert row["median"] >= row["own"]["median"] > 0


def test_users_on_threads_of_their_own_are_served_when_due():
    """The daemon's form: a thread per user; every step due is served, each path checked
    against the recording, and no thread is left behind."""
    import threading

    before = set(threading.enumerate())
    row = run_users("courtyard", 50, 0.4, "cpu", 4, walks=2, hz=20.0, seconds=0.5, threads=True)
    assert row["mode"] == "rate threads" and isinstance(row["kept_up"], bool)
    assert row["steps"] == 40
    assert row["median"] >= row["own"]["median"] > 0
    assert set(threading.enumerate()) == before


def test_the_cli_prints_a_row_per_user_count(tmp_path):
    out = tmp_path / "users.json"
    result = CliRunner().invoke(
        app,
        ["bench", "--users", "1,2", "--grid", "50", "--unknown", "0.4", "--backend", "cpu",
         "--walks", "1", "--json", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "users 1 round-robin" in result.output and "users 2 round-robin" in result.output
    import json

    rows = json.loads(out.read_text())
    assert [r["users"] for r in rows] == [1, 2]
    assert np.isclose(rows[1]["steps"], 2 * rows[0]["steps"])


def test_kept_up_means_at_the_rate_and_within_a_period():
    from sim.users import kept_up

    on_time = np.full(1000, 2.0)  # ms late
    assert kept_up(on_time, total_s=1.0, due_per_s=1000, period_ms=100)
    # every step served, but a backlog: most of them half a second late
    assert not kept_up(np.full(1000, 466.0), total_s=1.0, due_per_s=1000, period_ms=100)
    # on time, but a third fewer steps a second than fell due
    assert not kept_up(on_time[:600], total_s=1.0, due_per_s=1000, period_ms=100)
    assert not kept_up(np.array([]), total_s=1.0, due_per_s=1000, period_ms=100)
