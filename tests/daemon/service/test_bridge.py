"""The bridge settles on zenoh's thread what the loop need not see: a shed user's poses and
deltas are not even sent to the daemon (only the guided users' streams are subscribed to
while anyone is shed), every watched user's latest pose is timed as it arrives, and a message
nobody subscribes to is known as such (zenoh's matching status)."""

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
def test_shed_users_streams_are_not_sent_to_the_daemon_and_arrivals_are_timed():
    port = free_port()
    heard: list[tuple[Topic, str, float]] = []

    def keys() -> list[tuple[str, str]]:
        return sorted((t.name, k) for t, k, _ in heard)

    async def scenario() -> None:
        session = open_session(loopback(listen_port=port))
        peer = open_peer(port)
        bridge = Bridge(
            session,
            asyncio.get_running_loop(),
            lambda topic, key, payload, arrived: heard.append((topic, key, arrived)),
            lambda topic, query: query.drop(),
        )
        bob_pose = peer.declare_publisher(T.POSE.key("bob"))
        try:
            bridge.start()
            bridge.watch("ann")
            bridge.watch("bob")
            path_key = T.PATH.key("ann")
            assert not bridge.listened(path_key)  # nobody subscribes to ann's path yet
            sub = peer.declare_subscriber(path_key, lambda sample: None)
            assert await until(lambda: bridge.listened(path_key))
            sub.undeclare()
            # Nobody shed: every user's stream is heard, a new one's (eve) too, not timed.
            peer.put(T.POSE.key("eve"), b"{}")
            assert await until(lambda: len(heard) == 1)
            assert bridge.pose_heard_at("eve") is None
            bridge.mute("bob", True)  # bob shed: only ann's streams are subscribed to now
            assert await until(lambda: not bob_pose.matching_status.matching)
            heard.clear()
            sent = time.time()
            for user in ("ann", "bob", "eve"):
                peer.put(T.POSE.key(user), b"{}")
                peer.put(T.MAP_DELTA.key(user), b"GBMD")
            assert await until(lambda: len(heard) == 2)
            await asyncio.sleep(0.2)  # nothing more comes: bob's and eve's were not sent
            assert keys() == [("map_delta", T.MAP_DELTA.key("ann")), ("pose", T.POSE.key("ann"))]
            ann_at = bridge.pose_heard_at("ann")
            assert ann_at == next(a for t, _, a in heard if t is T.POSE)
            assert sent - 1.0 < ann_at <= time.time()
            assert bridge.pose_heard_at("bob") is None
            bridge.mute("bob", False)  # guided again: every stream heard, each sample once
            assert await until(lambda: bob_pose.matching_status.matching)
            heard.clear()
            for user in ("ann", "bob"):
                peer.put(T.POSE.key(user), f'{{"u": "{user}"}}'.encode())
            assert await until(lambda: len(heard) >= 2)  # both came, however slow the machine
            await asyncio.sleep(0.3)  # and no second copy of either
            assert keys() == [("pose", T.POSE.key("ann")), ("pose", T.POSE.key("bob"))]
            assert bridge.pose_heard_at("bob") is not None
            bridge.forget_user("bob")
            assert bridge.pose_heard_at("bob") is None
        finally:
            bridge.close()
            peer.close()
            session.close()

    asyncio.run(scenario())
