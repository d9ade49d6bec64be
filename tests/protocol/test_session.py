"""``open_session`` and the declare helpers, on real zenoh sessions on 127.0.0.1."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest
import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Health, NavState, NavStatus
from protocol.session import ZenohSettings, loopback, open_session


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_gossip_follows_multicast_scouting():
    for multicast in (True, False):
        conf = json.loads(ZenohSettings(multicast_scouting=multicast).to_json5())
        assert conf["scouting"]["multicast"]["enabled"] is multicast
        assert conf["scouting"]["gossip"]["enabled"] is multicast
    assert loopback(listen_port=7).multicast_scouting is False
    assert loopback(listen_port=7).listen == ["tcp/127.0.0.1:7"]
    assert loopback(connect_port=8).connect == ["tcp/127.0.0.1:8"]


def test_the_daemon_config_still_takes_zenoh_settings():
    from daemon.service.config import DaemonConfig

    cfg = DaemonConfig(zenoh={"listen": ["tcp/127.0.0.1:7447"], "multicast_scouting": False})
    assert isinstance(cfg.zenoh, ZenohSettings)


@pytest.fixture
def pair():
    port = free_port()
    a = open_session(loopback(listen_port=port))
    b = open_session(loopback(connect_port=port))
    yield a, b
    b.close()
    a.close()


def _until(pred, timeout_s: float = 3.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end and not pred():
        time.sleep(0.02)
    return pred()


@pytest.mark.timeout(30)
def test_publisher_carries_the_table_qos_and_reaches_one_user(pair):
    a, b = pair
    got: list[tuple[str, NavStatus]] = []
    done = threading.Event()

    def on_status(sample: zenoh.Sample) -> None:
        got.append((T.user_of(sample.key_expr), codec.decode(NavStatus, sample.payload.to_bytes())))
        done.set()

    sub = wire.declare_subscriber(b, T.STATUS, Callback(on_status, indirect=False), "ann")
    pub = wire.declare_publisher(a, T.STATUS, "ann")
    other = wire.declare_publisher(a, T.STATUS, "bob")
    try:
        assert pub.congestion_control == zenoh.CongestionControl.BLOCK
        assert pub.priority == zenoh.Priority.INTERACTIVE_HIGH
        assert str(pub.key_expr) == "guidebelt/ann/status"
        msg = NavStatus(state=NavState.IDLE, stamp=1.0)
        assert _until(lambda: (other.put(codec.encode(msg)), pub.put(codec.encode(msg)))
                      and done.is_set())  # fmt: skip
        assert {user for user, _ in got} == {"ann"}
    finally:
        for ent in (sub, pub, other):
            ent.undeclare()


@pytest.mark.timeout(30)
def test_queryable_get_reply_and_liveliness(pair):
    a, b = pair
    health = Health(daemon_id="d", uptime_s=1, users=[], backend="cpu", rejected=0, stamp=1)

    def on_query(query: zenoh.Query) -> None:
        wire.reply(query, T.HEALTH, None, codec.encode(health))
        query.drop()

    queryable = wire.declare_queryable(a, T.HEALTH, Callback(on_query, indirect=False))
    token = wire.declare_token(a, T.ALIVE)
    changes: list[zenoh.SampleKind] = []
    watch = wire.watch_liveliness(b, T.ALIVE, lambda s: changes.append(s.kind))
    try:

        def answers() -> list:
            return [r.ok for r in wire.get(b, T.HEALTH, timeout=1.0) if r.ok is not None]

        assert _until(lambda: bool(answers()))
        assert codec.decode(Health, answers()[0].payload.to_bytes()) == health
        assert any(r.ok is not None for r in wire.alive(b, T.ALIVE))
        assert _until(lambda: zenoh.SampleKind.PUT in changes)
        token.undeclare()
        assert _until(lambda: zenoh.SampleKind.DELETE in changes)
    finally:
        watch.undeclare()
        queryable.undeclare()


def test_a_topic_is_declared_only_as_what_it_is(pair):
    a, _ = pair
    with pytest.raises(ValueError):
        wire.declare_publisher(a, T.HEALTH, None)  # a queryable, not a publication
    with pytest.raises(ValueError):
        wire.declare_token(a, T.POSE)


@pytest.mark.timeout(30)
def test_a_lone_pose_survives_a_link_the_must_arrive_messages_have_filled(pair):
    """A pose put while the link is congested with must-arrive messages (a map delta and a
    goal just before it, a receiver slow to read) is queued, not dropped. With DROP at the
    must-arrive messages' priority, zenoh found their queue full and dropped the pose after
    ``wait_before_drop`` (1 ms): the daemon never heard a user's only pose (2 of 30 rounds
    of ``test_goal_with_no_path_says_so`` with two busy loops beside it). Here the link is
    stalled on purpose: the receiver's first must-arrive callback holds zenoh's reading
    thread, so the sender's queue fills and stays full while the pose is put."""
    listener, sender = pair
    hold, poses = threading.Event(), threading.Event()

    def on_status(_sample: zenoh.Sample) -> None:
        hold.wait(10.0)  # only the first holds: later samples find the event set

    subs = [
        wire.declare_subscriber(listener, T.STATUS, Callback(on_status, indirect=False), "ann"),
        wire.declare_subscriber(
            listener, T.POSE, Callback(lambda _s: poses.set(), indirect=False), "ann"
        ),
    ]
    progress = {"at": time.monotonic(), "stop": False}

    def fill() -> None:  # must-arrive messages until a put blocks on the full link
        payload = bytes(60_000)
        while not progress["stop"]:
            wire.put(sender, T.STATUS, "ann", payload)
            progress["at"] = time.monotonic()

    filler = threading.Thread(target=fill, daemon=True)
    try:
        time.sleep(0.3)  # the subscriptions reach the sender
        filler.start()
        assert _until(lambda: time.monotonic() - progress["at"] > 0.5, 10.0), "never congested"
        wire.put(sender, T.POSE, "ann", b"the only pose")
    finally:
        progress["stop"] = True
        hold.set()
    try:
        assert poses.wait(5.0), "the pose was dropped on the congested link"
    finally:
        filler.join(10.0)
        for sub in subs:
            sub.undeclare()
    assert not filler.is_alive()
