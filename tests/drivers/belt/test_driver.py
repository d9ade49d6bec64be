"""The driver against the simulated belt: reconnects, zenoh patterns, health, STOP."""

from __future__ import annotations

import asyncio
import contextlib
import socket
import time

import pytest

from drivers.belt import frames as F
from drivers.belt.driver import BeltLink
from drivers.belt.service import BeltService
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltHealth, BeltPattern, PatternKind
from protocol.session import loopback, open_session


async def _until(predicate, timeout: float, step: float = 0.01) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        await asyncio.sleep(step)
    return predicate()


@pytest.mark.timeout(40)
def test_driver_reconnects_within_1_s_and_the_belt_resumes(belt):
    motors = (60, 70, 80, 90)

    async def scenario() -> None:
        link = BeltLink(belt.link)
        task = asyncio.create_task(link.run())
        try:
            await asyncio.wait_for(link.connected.wait(), 3)
            link.show(F.Pattern(motors, 0, 5000))
            assert await asyncio.to_thread(belt.wait_levels, motors, 2.0)
            for attempt in range(2):  # twice: the second restart reuses the same link
                belt.stop(kill=True)  # SIGKILL: no clean-up, the symlink is left stale
                assert await _until(lambda: not link.connected.is_set(), 1.0)
                restarted = time.monotonic()
                await asyncio.to_thread(belt.start)
                event = await asyncio.to_thread(belt.wait_levels, motors, 2.0)
                assert event is not None, f"belt did not resume after restart {attempt}"
                # From the port's return (the new process's pty and link in place): the
                # process's own start-up (a Python interpreter for the mock) is not the
                # driver's doing.
                took = event.mono - belt.ready_at
                print(f"{belt.kind}: restart {attempt}: pattern back {took * 1000:.0f} ms after "
                      f"the port returned ({(event.mono - restarted) * 1000:.0f} ms after the "
                      "restart began)")  # fmt: skip
                assert took < 1.0
                assert link.connected.is_set()
            assert link.reconnects == 2
            assert link.health()["connected"] is True
        finally:
            link.close()
            await asyncio.wait_for(task, 2)

    asyncio.run(scenario())


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.timeout(40)
def test_zenoh_patterns_reach_the_belt_health_is_published_and_daemon_loss_stops_it(belt):
    port = _free_port()
    driver_session = open_session(loopback(listen_port=port))
    daemon_session = open_session(loopback(connect_port=port))
    healths: list[BeltHealth] = []
    health_sub = wire.declare_subscriber(
        daemon_session,
        T.BELT_HEALTH,
        lambda s: healths.append(BeltHealth.model_validate_json(s.payload.to_bytes())),
        "alice",
    )
    token = wire.declare_token(daemon_session, T.ALIVE)
    motors = (30, 0, 0, 220)

    async def scenario() -> None:
        service = BeltService(driver_session, "alice", BeltLink(belt.link), health_period_s=0.1)
        task = asyncio.create_task(service.run())
        try:
            assert await _until(lambda: service.daemons_alive == 1, 5)
            await asyncio.wait_for(service.link.connected.wait(), 3)
            wire.put(daemon_session, T.BELT, "alice", b'{"seq": "not a pattern"}')
            pattern = BeltPattern(seq=1, map_seq=0, kind=PatternKind.GUIDE, motors=motors,
                                  period_ms=0, ttl_ms=5000, stamp=time.time())  # fmt: skip
            wire.put(daemon_session, T.BELT, "alice", codec.encode(pattern))
            assert await asyncio.to_thread(belt.wait_levels, motors, 3.0)
            assert service.rejected == 1
            assert await _until(lambda: healths and healths[-1].acks > 0
                                and healths[-1].belt_state == "active", 3)  # fmt: skip
            h = healths[-1]
            assert h.connected and h.latency_ms is not None and h.dropped == 0
            print(f"{belt.kind}: ack round trip {h.latency_ms:.2f} ms (median)")
            token.undeclare()  # the daemon goes away: STOP, long before the 5 s TTL
            lost = time.monotonic()
            event = await asyncio.to_thread(belt.wait_levels, (0, 0, 0, 0), 2.0)
            assert event is not None and event.mono - lost < 0.5
            assert await _until(lambda: healths[-1].belt_state == "stopped", 2)
        finally:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    try:
        asyncio.run(scenario())
    finally:
        health_sub.undeclare()
        daemon_session.close()
        driver_session.close()


@pytest.mark.timeout(60)
def test_guidebelt_belt_process_drives_the_simulated_belt(belt_kind, tmp_path):
    """The demo's path: ``start_simulated_belt`` runs ``guidebelt belt`` as a process."""
    from drivers.belt.hil import start_simulated_belt

    port = _free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    session = open_session(loopback(listen_port=port))
    healths: list[BeltHealth] = []
    sub = wire.declare_subscriber(
        session,
        T.BELT_HEALTH,
        lambda s: healths.append(BeltHealth.model_validate_json(s.payload.to_bytes())),
        "bob",
    )
    motors = (0, 0, 255, 0)
    try:
        with start_simulated_belt(belt_kind, "bob", [endpoint], tmp_path / "tty") as belt:
            deadline = time.monotonic() + 20  # the driver process imports zenoh first
            while time.monotonic() < deadline and not (healths and healths[-1].connected):
                time.sleep(0.05)
            assert healths and healths[-1].connected
            pattern = BeltPattern(seq=1, map_seq=0, kind=PatternKind.TURN_AROUND, motors=motors,
                                  period_ms=0, ttl_ms=5000, stamp=time.time())  # fmt: skip
            wire.put(session, T.BELT, "bob", codec.encode(pattern))
            assert belt.wait_levels(motors, 3.0) is not None
        # Leaving stopped the driver (its parting STOP) and then the belt.
        assert any(e.level == 0 and e.motor == 2 for e in belt.events[-4:])
    finally:
        sub.undeclare()
        session.close()


@pytest.mark.timeout(30)
def test_driver_reopens_a_port_that_went_silent(belt):
    """The port stays but the belt stops talking (here: the process is frozen)."""
    import signal

    async def scenario() -> None:
        link = BeltLink(belt.link)
        task = asyncio.create_task(link.run())
        try:
            await asyncio.wait_for(link.connected.wait(), 3)
            assert await _until(lambda: link.heartbeat is not None, 2)
            belt.proc.send_signal(signal.SIGSTOP)
            frozen = time.monotonic()
            try:
                # The pty is still there, so the link reopens it at once: count reopenings.
                assert await _until(lambda: link.reconnects == 1, 3)
                noticed = time.monotonic() - frozen
                print(f"{belt.kind}: silence noticed after {noticed:.2f} s")
                assert noticed >= 0.9  # SILENCE_S, not sooner
            finally:
                belt.proc.send_signal(signal.SIGCONT)
            thawed = time.monotonic()
            assert await _until(lambda: link.heartbeat_at and link.heartbeat_at > thawed, 2)
            assert link.connected.is_set() and link.reconnects == 1
        finally:
            link.close()
            await asyncio.wait_for(task, 2)

    asyncio.run(scenario())


def test_every_copy_of_a_press_is_acked_and_handed_on_once(monkeypatch):
    """The belt repeats a press until acked: the link acks each copy (an earlier ack may be
    the one lost) and publishes the press once; a press number seen again later is new."""
    got: list[F.Button] = []
    link = BeltLink("/dev/null-belt", on_button=got.append)
    acks: list[bytes] = []
    monkeypatch.setattr(link, "_write", acks.append)
    press = F.Button(7, 1, F.PressKind.SHORT)
    for t in (10.0, 10.1, 10.2):
        link._on_press(press, t)
    assert got == [press] and link.presses == 1
    assert [F.Parser().feed(a)[0].ftype for a in acks] == [F.FrameType.BUTTON_ACK] * 3
    assert {F.Parser().feed(a)[0].payload for a in acks} == {(7).to_bytes(2, "little")}
    link._on_press(press, 10.2 + 3.5)  # after the belt's own 2 s: a new press (the belt reset)
    assert got == [press, press]
