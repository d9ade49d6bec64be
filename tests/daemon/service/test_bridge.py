"""The bridge settles on zenoh's thread what the loop need not see: a shed user's poses and
deltas are dropped there, every watched user's latest pose is timed as it arrives, and a
message nobody subscribes to is known as such (zenoh's matching status)."""

from __future__ import annotations

import asyncio
import time

import pytest

from daemon.service.bridge import Bridge
from daemon.service.embedded import free_port, open_peer
from protocol import topics as T
from protocol.session import loopback, open_session
from protocol.topics import Topic


async def until(check, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(0.02)
    return True


@pytest.mark.timeout(60)
def test_shed_users_inputs_stop_on_zenohs_thread_and_arrivals_are_timed():
    port = free_port()
    heard: list[tuple[Topic, str, float]] = []

    async def scenario() -> None:
        session = open_session(loopback(listen_port=port))
        peer = open_peer(port)
        bridge = Bridge(
            session,
            asyncio.get_running_loop(),
            lambda topic, key, payload, arrived: heard.append((topic, key, arrived)),
            lambda topic, query: query.drop(),
        )
        try:
            bridge.start()
            bridge.watch("ann")
            bridge.watch("bob")
            bridge.mute("bob", True)
            path_key = T.PATH.key("ann")
            assert not bridge.listened(path_key)  # nobody subscribes to ann's path yet
            sub = peer.declare_subscriber(path_key, lambda sample: None)
            assert await until(lambda: bridge.listened(path_key))
            sub.undeclare()
            sent = time.time()
            for user in ("ann", "bob"):
                peer.put(T.POSE.key(user), b"{}")
                peer.put(T.MAP_DELTA.key(user), b"GBMD")
            peer.put(T.POSE.key("eve"), b"{}")  # no session: passed on, not timed
            assert await until(lambda: len(heard) == 3)
            assert await until(lambda: bridge.pose_heard_at("bob") is not None)
            await asyncio.sleep(0.2)  # nothing more comes for bob
            assert sorted((t.name, k) for t, k, _ in heard) == [
                ("map_delta", T.MAP_DELTA.key("ann")),
                ("pose", T.POSE.key("ann")),
                ("pose", T.POSE.key("eve")),
            ]
            # bob's pose reached the daemon although the loop never saw it: a missing pose of
            # bob's is the daemon's doing (overloaded), not bob's localiser's.
            bob_at = bridge.pose_heard_at("bob")
            assert bob_at is not None and sent - 1.0 < bob_at <= time.time()
            assert bridge.pose_heard_at("ann") == next(a for t, _, a in heard if t is T.POSE)
            assert bridge.pose_heard_at("eve") is None
            bridge.mute("bob", False)  # guided again: bob's inputs reach the loop
            peer.put(T.POSE.key("bob"), b"{}")
            assert await until(lambda: any(k == T.POSE.key("bob") for _, k, _ in heard))
            bridge.forget_user("bob")
            assert bridge.pose_heard_at("bob") is None
        finally:
            bridge.close()
            peer.close()
            session.close()

    asyncio.run(scenario())
