"""The view over real zenoh and a real server: frames on the WebSocket, a restarted daemon
found again, bad samples counted and skipped, nothing ever published."""

from __future__ import annotations

import json
import time

import pytest


def wait_for(cond, timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return False


def fake_daemon(port: int):
    """A session listening where the daemon would, holding the daemon's liveliness token."""
    from protocol import session as wire
    from protocol import topics as T
    from protocol.session import loopback, open_session

    session = open_session(loopback(listen_port=port))
    return session, wire.declare_token(session, T.ALIVE)


def belt(seq: int, motors: tuple[int, int, int, int]) -> bytes:
    from protocol import codec
    from protocol.messages import BeltPattern, PatternKind

    msg = BeltPattern(seq=seq, map_seq=0, kind=PatternKind.GUIDE, motors=motors, ttl_ms=500,
                      stamp=time.time())  # fmt: skip
    return codec.encode(msg)


@pytest.mark.timeout(60)
def test_frames_follow_the_wire_and_the_daemon_is_found_again_after_a_restart() -> None:
    import zenoh
    from websockets.sync.client import connect

    from daemon.service.embedded import free_port
    from protocol import session as wire
    from protocol import topics as T
    from protocol.session import loopback, open_session
    from viewer.server import ServeSettings, ViewThread

    port = free_port()
    daemon, token = fake_daemon(port)
    session = open_session(loopback(connect_port=port))
    try:
        with ViewThread(session, ServeSettings(port=free_port(), hz=20)) as view:
            assert wait_for(lambda: view.state.daemon_alive)
            # Liveliness can arrive before the view's subscriptions reach the daemon's
            # session (a loaded machine): publish until the view has the pattern.
            first = belt(1, (200, 0, 0, 0))
            assert wait_for(lambda: _motors(view) == [200, 0, 0, 0] or _put(daemon, first))
            wire.put(daemon, T.BELT, "ann", b"{not json")
            assert wait_for(lambda: view.node.rejected == 1)
            url = f"ws://127.0.0.1:{view.settings.port}/ws"
            with connect(url) as ws:
                frames = [json.loads(ws.recv(timeout=5)) for _ in range(5)]
            assert frames[-1]["users"]["ann"]["belt"]["motors"] == [200, 0, 0, 0]
            assert frames[-1]["stamp"] > frames[0]["stamp"]  # fresh frames, not one resent
            assert view.node.rejected == 1  # the bad sample skipped, counted, the view alive

            # The daemon goes, and comes back on the same port: the view hears it again.
            token.undeclare()
            daemon.close()
            assert wait_for(lambda: not view.state.daemon_alive)
            daemon, token = fake_daemon(port)
            assert wait_for(lambda: view.state.daemon_alive, 20.0)
            assert view.state.wanting_snapshot() == ["ann"]  # its map is asked for again
            again = belt(2, (0, 90, 0, 90))
            assert wait_for(lambda: _motors(view) == [0, 90, 0, 90] or _put(daemon, again))
            # Read-only: the view declared subscribers and a liveliness watch, no publisher.
            assert not any(isinstance(e, zenoh.Publisher) for e in view.node._entities)
    finally:
        token.undeclare()
        daemon.close()
        session.close()


def _motors(view):
    user = view.state.frame()["users"].get("ann")
    return user and user["belt"] and user["belt"]["motors"]


def _put(daemon, payload: bytes) -> bool:
    """Publish once more (until the link to the view is up, which zenoh makes on its own)."""
    from protocol import session as wire
    from protocol import topics as T

    wire.put(daemon, T.BELT, "ann", payload)
    return False
