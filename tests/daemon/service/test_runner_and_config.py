"""The service around the navigator: the runner's coalescing, config, systemd notify, journald."""

from __future__ import annotations

import asyncio
import logging
import socket
import threading
import time

import numpy as np
import pytest

from daemon.navigation import Navigator
from daemon.service.config import DaemonConfig, load_config
from daemon.service.logs import JournalFormatter
from daemon.service.runner import Pacing, UserRunner
from daemon.service.sdnotify import Notifier
from protocol import codec
from protocol.messages import (
    BeltPattern,
    Goal,
    GoalCell,
    MapDelta,
    NavPath,
    NavStatus,
    PatternKind,
    Pose,
    StatusCode,
)

SHAPE = (30, 30)


def delta(seq, cells, values, shape=SHAPE) -> MapDelta:
    return MapDelta.from_arrays(seq, shape, np.array(cells), np.array(values), time.time())


def pose(cell, stamp=None) -> Pose:
    r, c = cell
    return Pose(
        x=(c + 0.5) / 10, y=(SHAPE[0] - r - 0.5) / 10, heading=1.57, stamp=stamp or time.time()
    )


def goal(r, c) -> Goal:
    return Goal(target=GoalCell(row=r, col=c), stamp=time.time())


def test_the_latest_pose_wins_and_deltas_coalesce_in_the_runner():
    published: list[tuple[str, bytes]] = []

    async def scenario():
        navigator = Navigator("u", DaemonConfig(backend="cpu").navigator_settings())
        pacing = Pacing(slots=1)
        runner = UserRunner(
            navigator, lambda k, b: published.append((k, b)), lambda *a: None, 1.0, pacing=pacing
        )
        poses = [pose((20, c), stamp=time.time() - 0.01 * (5 - c)) for c in range(5)]
        # The worker takes its inbox once it holds a step slot: here all arrive while another
        # user's step holds the only one, so one step takes them all, with the last pose.
        with pacing.slots:
            runner.put_delta(delta(0, [], []))
            runner.put_goal(goal(3, 15))
            for p in poses:
                runner.put_pose(p)
            await asyncio.sleep(0.05)  # the worker woke and waits for the slot
        for _ in range(200):
            await asyncio.sleep(0.01)
            if any(k.endswith("/path") for k, _ in published):
                break
        await runner.close()
        return poses, runner.navigator.steps

    poses, steps = asyncio.run(scenario())
    paths = [codec.decode(NavPath, b) for k, b in published if k.endswith("/path")]
    assert len(paths) == 1 and steps == 1
    assert paths[0].pose_stamp == poses[-1].stamp and paths[0].cells[0] == (20, 4)
    assert published[-1][0].endswith("/status")  # close(): the final status comes last


def test_a_step_that_raises_stops_the_user_and_says_why():
    published: list[tuple[str, bytes]] = []

    class Broken(Navigator):
        def step(self, inbox, now):
            raise RuntimeError("a bug in the step")

    async def scenario():
        navigator = Broken("u", DaemonConfig(backend="cpu").navigator_settings())
        runner = UserRunner(navigator, lambda k, b: published.append((k, b)), lambda *a: None, 1.0)
        runner.put_pose(pose((20, 3)))
        for _ in range(200):
            await asyncio.sleep(0.01)
            if any(k.endswith("/status") for k, _ in published):
                break
        assert runner.serving  # the failed step did not end the user's worker
        await runner.close()
        assert not runner.serving
        for _ in range(200):  # the worker's thread ends once its last words are out
            if not any(t.name == "plan-u" for t in threading.enumerate()):
                break
            await asyncio.sleep(0.01)
        assert not any(t.name == "plan-u" for t in threading.enumerate())

    asyncio.run(scenario())
    belts = [codec.decode(BeltPattern, b) for k, b in published if k.endswith("/belt")]
    statuses = [codec.decode(NavStatus, b) for k, b in published if k.endswith("/status")]
    assert belts[0].kind == PatternKind.STOP
    assert statuses[0].code == StatusCode.INTERNAL and "a bug in the step" in statuses[0].reason


def test_the_planners_work_between_steps_comes_after_the_output_and_outside_the_lag():
    """The runner asks for ``between_steps`` once the step's output is published; the step's
    lag is measured before it (an input that comes meanwhile waits for it, and its lag says so),
    and a failure there is logged while the user is still served."""
    events: list[str] = []
    lags: list[float] = []

    class Idle(Navigator):
        def between_steps(self) -> None:
            events.append("between")
            time.sleep(1.0)  # far longer than a 30 x 30 step
            events.append("done")
            if events.count("done") == 2:
                raise RuntimeError("a bug between steps")

    async def scenario():
        navigator = Idle("u", DaemonConfig(backend="cpu").navigator_settings())
        pacing = Pacing(slots=1)
        pacing.record = lambda user, lag, cpu, urgent=True: lags.append(lag)  # type: ignore
        runner = UserRunner(navigator, lambda k, b: events.append(k.rsplit("/", 1)[1]),
                            lambda *a: None, 1.0, pacing=pacing)  # fmt: skip
        with pacing.slots:  # the first step takes all three: it guides
            runner.put_delta(delta(0, [], []))
            runner.put_goal(goal(3, 15))
            runner.put_pose(pose((20, 3)))
            await asyncio.sleep(0.05)
        for seq in (1, 2):  # map changes step at once: each once the work between is done
            while events.count("done") < seq:
                await asyncio.sleep(0.01)
            runner.put_delta(delta(seq, [5 * 30 + seq], [1]))
        while len(lags) < 3:
            await asyncio.sleep(0.01)
        assert runner.serving
        await runner.close()

    asyncio.run(scenario())
    first = events.index("between")
    assert "belt" in events[:first] and "status" in events[:first]  # the answer went first
    assert events.count("between") >= 3 and max(lags) < 1000.0


def test_config_file_environment_and_arguments_in_that_order(tmp_path, monkeypatch):
    path = tmp_path / "g.toml"
    path.write_text('backend = "reference"\nlang = "es"\n[zenoh]\nlisten = ["tcp/127.0.0.1:1"]\n')
    monkeypatch.setenv("GUIDEBELT_LANG", "en")
    monkeypatch.setenv("GUIDEBELT_ZENOH__MULTICAST_SCOUTING", "false")
    cfg = load_config(path, max_users=3)
    assert (cfg.backend, cfg.lang, cfg.max_users) == ("reference", "en", 3)
    assert cfg.zenoh.listen == ["tcp/127.0.0.1:1"] and cfg.zenoh.multicast_scouting is False
    path.write_text("bakend = 'cpu'\n")
    with pytest.raises(ValueError, match="bakend"):
        load_config(path)
    with pytest.raises(FileNotFoundError):
        load_config(tmp_path / "missing.toml")


def test_notifier_speaks_systemds_datagram_protocol(tmp_path, monkeypatch):
    addr = str(tmp_path / "n.sock")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(addr)
    sock.settimeout(2)
    monkeypatch.setenv("WATCHDOG_USEC", "4000000")
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    n = Notifier(addr)
    try:
        assert n.ready("up") and sock.recv(100) == b"READY=1\nSTATUS=up"
        assert n.watchdog() and sock.recv(100) == b"WATCHDOG=1"
        assert n.stopping() and sock.recv(100) == b"STOPPING=1"
        assert n.watchdog_interval_s() == 2.0
    finally:
        n.close()
        sock.close()
    assert not Notifier("").ready()  # outside systemd: a no-op


def test_journal_lines_carry_priority_and_fields():
    rec = logging.LogRecord("guidebelt.x", logging.WARNING, "", 0, "rejected", (), None)
    rec.fields = {"user": "ann", "reason": "pose is 2 s old"}
    line = JournalFormatter().format(rec)
    assert line == '<4>guidebelt.x: rejected user=ann reason="pose is 2 s old"'


def test_a_pose_alone_waits_for_the_guide_period_and_a_map_change_steps_at_once():

    async def scenario():
        steps: list[tuple[float, bool]] = []

        class Counting(Navigator):
            def step(self, inbox, now):
                steps.append((time.monotonic(), bool(inbox.deltas)))
                return super().step(inbox, now)

        navigator = Counting("u", DaemonConfig(backend="cpu").navigator_settings())
        # A pose alone: at most once a second, so a map change stepped at once (well inside
        # the second) is told apart from one paced like a pose on a loaded machine too.
        pacing = Pacing(slots=1, guide_hz=1.0)
        runner = UserRunner(navigator, lambda k, b: None, lambda *a: None, 1.0, pacing=pacing)
        runner.put_delta(delta(0, [], []))
        runner.put_goal(goal(3, 15))
        runner.put_pose(pose((20, 3)))
        deadline = time.monotonic() + 5.0
        while not steps:  # the first step ran (waited for: a loaded machine may be slow)
            assert time.monotonic() < deadline, "no first step"
            await asyncio.sleep(0.01)
        t0 = time.monotonic()
        for _ in range(10):  # poses at 50 Hz for 0.2 s: coalesced into one later step
            runner.put_pose(pose((20, 3)))
            await asyncio.sleep(0.02)
        runner.put_delta(delta(1, [5], [1]))  # a map change does not wait
        sent = time.monotonic()
        while not [t for t, d in steps if d and t >= sent]:
            assert time.monotonic() < deadline + 5.0, "the map change was never stepped"
            await asyncio.sleep(0.01)
        await runner.close()
        return steps, t0, sent

    steps, t0, sent = asyncio.run(scenario())
    pose_steps = [t for t, d in steps if not d and t > t0]
    assert len(pose_steps) <= 2  # 0.2 s of 50 Hz poses: one or two steps, not ten
    delta_steps = [t for t, d in steps if d and t >= sent]
    # At once: a pose alone would have waited up to a second after the first step.
    assert len(delta_steps) == 1 and delta_steps[0] - sent < 0.5
