"""Mutual TLS and access control on real zenoh sessions against the real daemon.

The daemon listens on tls/127.0.0.1 with certificates made by ``protocol.certificates`` and
the access rules ``protocol.access`` generates from the topic table. The attacker holds a
real certificate of this deployment, user ann's, and tries to act on bob. Every node here is
a zenoh *client* of the daemon, so the daemon routes between them: what it does not forward
is what its rules refused, not a quirk of peer-to-peer routing.
"""

from __future__ import annotations

import dataclasses
import json
import threading
import time

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")
pytest.importorskip("cryptography")

from zenoh.handlers import Callback  # noqa: E402

from protocol import codec  # noqa: E402
from protocol import session as wire  # noqa: E402
from protocol import topics as T  # noqa: E402
from protocol.certificates import issue, load_ca, make_ca  # noqa: E402
from protocol.deployment import certify  # noqa: E402
from protocol.messages import (  # noqa: E402
    BeltPattern,
    Goal,
    GoalCell,
    MapDelta,
    MapSnapshot,
    NavStatus,
    PatternKind,
    UserSettings,
)
from protocol.settings import TlsSettings, ZenohSettings, load_node_settings  # noqa: E402
from protocol.topics import Role  # noqa: E402

USERS = ("ann", "bob", "dan")


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    """What ``guidebelt certs`` writes for ann, bob and dan with the mapper and sim services,
    once for the module; and a stranger's CA with a certificate that also says ``user:ann``."""
    root = tmp_path_factory.mktemp("tls")
    nodes = {n.common_name: n for n in certify(root, list(USERS), [Role.MAPPER, Role.SIM])}
    stranger_ca = make_ca(root / "stranger")
    forged = issue(stranger_ca, "user:ann", root / "stranger", "user-ann")
    # Signed by the deployment's CA, but for a user the daemon's [zenoh.access] does not list:
    # her table is ann's with carol's certificate.
    unlisted = issue(load_ca(root), "user:carol", root, "user-carol")
    carol = root / "user-carol.toml"
    carol.write_text(nodes["user:ann"].toml.read_text().replace("user-ann.", "user-carol."))
    nodes["user:carol"] = dataclasses.replace(
        nodes["user:ann"], common_name="user:carol", pair=unlisted, toml=carol
    )
    return root, nodes, forged


@pytest.fixture(scope="module")
def daemon(certs):
    from daemon.service.embedded import DaemonThread
    from tests.conftest import daemon_threads, warm_up

    warm_up()
    _, nodes, _ = certs
    written = load_node_settings(nodes["daemon"].toml)  # the [zenoh] table for guidebelt.toml
    assert written.access is not None and written.access.users == list(USERS)

    def on(port: int) -> ZenohSettings:
        return written.model_copy(update={"listen": [f"tls/127.0.0.1:{port}"]})

    # cell_m: the 50-cell courtyard of the walk below is 10 m wide.
    with DaemonThread(zenoh_on=on, backend="cpu", snapshot_timeout_s=0.5, cell_m=0.2) as d:
        yield d
    deadline = time.monotonic() + 3.0  # no leaks: the loop and every user's worker are gone
    while daemon_threads() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not daemon_threads(), daemon_threads()


def as_client(settings: ZenohSettings, port: int) -> ZenohSettings:
    # A client of the daemon, so the daemon routes between the nodes (see the module's doc).
    return settings.model_copy(update={"mode": "client", "connect": [f"tls/127.0.0.1:{port}"]})


def open_as(certs, daemon, cn: str) -> zenoh.Session:
    _, nodes, _ = certs
    return wire.open_session(as_client(load_node_settings(nodes[cn].toml), daemon.port))


@pytest.fixture
def sessions(certs, daemon):
    opened: dict[str, zenoh.Session] = {}

    def get(cn: str) -> zenoh.Session:
        if cn not in opened:
            opened[cn] = open_as(certs, daemon, cn)
        return opened[cn]

    yield get
    for s in opened.values():
        s.close()


class Inbox:
    """Samples on a key, as decoded messages."""

    def __init__(self, model) -> None:
        self.model = model
        self.got: list = []

    def __call__(self, sample) -> None:
        self.got.append(codec.decode(self.model, sample.payload.to_bytes()))

    def wait(self, pred=lambda got: bool(got), timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if pred(self.got):
                return True
            time.sleep(0.02)
        return pred(self.got)


def goal_at(row: int, col: int) -> bytes:
    return codec.encode(Goal(target=GoalCell(row=row, col=col), stamp=time.time()))


def delta(seq: int) -> bytes:
    cells, values = np.array([0], dtype=np.int64), np.array([1], dtype=np.uint8)
    return codec.encode(MapDelta.from_arrays(seq, (20, 20), cells, values, time.time()))


# -- who may connect ------------------------------------------------------------------------


@pytest.mark.timeout(60)
def test_a_peer_without_a_deployment_certificate_cannot_connect(certs, daemon):
    root, nodes, forged = certs
    port = daemon.port
    stranger = nodes["user:ann"].settings.model_copy(
        update={
            "tls": TlsSettings(
                root_ca=str(root / "ca.pem"),
                certificate=str(forged.certificate),
                private_key=str(forged.private_key),
            )
        }
    )
    attempts = {
        "plain tcp to the TLS port": ZenohSettings(
            mode="client", connect=[f"tcp/127.0.0.1:{port}"]
        ),
        "TLS without a certificate": None,
        "a certificate from another CA": as_client(stranger, port),
    }
    for what, settings in attempts.items():
        if settings is None:
            # The daemon's CA trusted, no client certificate offered: what a phone app that
            # skipped enrolment would do. Written as zenoh's own config, since guidebelt's
            # settings always present a certificate.
            config = zenoh.Config.from_json5(
                json.dumps(
                    {
                        "mode": "client",
                        "connect": {"endpoints": [f"tls/127.0.0.1:{port}"]},
                        "scouting": {"multicast": {"enabled": False}},
                        "transport": {
                            "link": {"tls": {"root_ca_certificate": str(root / "ca.pem")}}
                        },
                    }
                )
            )
            opener = lambda c=config: zenoh.open(c)  # noqa: E731
        else:
            opener = lambda s=settings: wire.open_session(s)  # noqa: E731
        with pytest.raises(zenoh.ZError):
            opener().close()
        assert daemon.daemon.runners == {} or "ann" not in daemon.daemon.runners, what


@pytest.mark.timeout(60)
def test_a_certified_node_the_daemon_does_not_list_may_do_nothing(sessions, daemon):
    """carol's certificate is the deployment's, but she is not in [zenoh.access]: she may
    connect, and every message she sends is refused (no junk users in the daemon's table)."""
    carol = sessions("user:carol")
    status = Inbox(NavStatus)
    sub = wire.declare_subscriber(carol, T.STATUS, Callback(status), "carol")
    time.sleep(0.3)
    wire.put(carol, T.GOAL, "carol", goal_at(5, 5))
    wire.put(carol, T.POSE, "carol", b"junk")
    time.sleep(0.5)
    assert "carol" not in daemon.daemon.runners and status.got == []
    assert [r for r in wire.alive(carol, T.ALIVE, timeout=0.5) if r.ok is not None] == []
    sub.undeclare()


# -- what a certified user may do ----------------------------------------------------------


@pytest.mark.timeout(90)
def test_ann_reaches_her_own_session_and_not_anothers(sessions, daemon):
    """dan is no other test's victim: that the daemon never heard of him is this test's."""
    ann, dan = sessions("user:ann"), sessions("user:dan")
    ann_status, dan_status, ann_spying = (
        Inbox(NavStatus), Inbox(NavStatus), Inbox(NavStatus),
    )  # fmt: skip
    subs = [
        wire.declare_subscriber(ann, T.STATUS, Callback(ann_status), "ann"),
        wire.declare_subscriber(dan, T.STATUS, Callback(dan_status), "dan"),
        # Ann listens for every user's status, and for dan's by name: neither is granted.
        wire.declare_subscriber(ann, T.STATUS, Callback(ann_spying), None),
        wire.declare_subscriber(ann, T.STATUS, Callback(ann_spying), "dan"),
    ]
    time.sleep(0.3)
    wire.put(ann, T.GOAL, "dan", goal_at(5, 5))  # dan's goal, from ann's phone
    wire.put(ann, T.SETTINGS_SET, "dan", codec.encode(UserSettings(intensity=1, stamp=time.time())))
    wire.put(ann, T.GOAL, "ann", goal_at(5, 5))  # her own: arrives
    assert ann_status.wait(), "ann's own goal never reached the daemon"
    time.sleep(0.5)  # room for dan's forged goal to have arrived, had it been let through
    assert "dan" not in daemon.daemon.runners, "the daemon saw a goal for dan from ann"
    assert dan_status.got == []
    # Ann's wildcard subscription hears her own status only; her subscription to dan's none.
    assert ann_spying.got == [s for s in ann_spying.got if s in ann_status.got]
    # Bob's own goal still arrives, and ann hears nothing of it.
    heard_by_ann = len(ann_spying.got)
    wire.put(dan, T.GOAL, "dan", goal_at(5, 5))
    assert dan_status.wait()
    time.sleep(0.3)
    assert len(ann_spying.got) == heard_by_ann
    replies = list(wire.get(ann, T.STATUS_QUERY, "dan", timeout=1.0))
    assert [r for r in replies if r.ok is not None] == [], "ann read dan's status by query"
    for s in subs:
        s.undeclare()


@pytest.mark.timeout(90)
def test_ann_cannot_drive_bobs_belt(sessions):
    ann, bob, belt = sessions("user:ann"), sessions("user:bob"), sessions("belt:bob")
    patterns, settings = Inbox(BeltPattern), Inbox(UserSettings)
    subs = [
        wire.declare_subscriber(belt, T.BELT, Callback(patterns), "bob"),
        wire.declare_subscriber(belt, T.SETTINGS, Callback(settings), "bob"),
    ]
    time.sleep(0.3)
    forged = BeltPattern(
        seq=1, map_seq=0, kind=PatternKind.GUIDE, motors=(255, 255, 255, 255), ttl_ms=5000,
        stamp=time.time(),
    )
    wire.put(ann, T.BELT, "bob", codec.encode(forged))
    # The route from the daemon to bob's belt is open: bob's own setting reaches it.
    wire.put(
        bob, T.SETTINGS_SET, "bob", codec.encode(UserSettings(intensity=40, stamp=time.time()))
    )
    assert settings.wait(lambda got: any(s.intensity == 40 for s in got))
    time.sleep(0.3)
    assert [p for p in patterns.got if p.motors == forged.motors] == []
    for s in subs:
        s.undeclare()


@pytest.mark.timeout(90)
def test_ann_cannot_answer_snapshot_queries_nor_write_maps(sessions):
    """After a sequence gap the daemon asks ``guidebelt/bob/map/source``: the mapper is asked,
    ann's queryable, ready with a forged snapshot, never is. Nor do ann's own deltas reach
    the daemon: only the mapper writes maps (her gap would have been asked for too)."""
    ann, mapper = sessions("user:ann"), sessions("mapper")
    asked: dict[str, list[str]] = {"ann": [], "mapper": []}

    def answer(who: str, fill: int):
        def on_query(query) -> None:
            user = T.user_of(query.key_expr)
            asked[who].append(user)
            snap = MapSnapshot.from_array(99, np.full((20, 20), fill, np.uint8), time.time())
            wire.reply(query, T.MAP_SOURCE, user, codec.encode(snap))

        return Callback(on_query, indirect=False)

    queryables = [
        wire.declare_queryable(ann, T.MAP_SOURCE, answer("ann", 0), "bob"),
        wire.declare_queryable(mapper, T.MAP_SOURCE, answer("mapper", 1), None),
    ]
    time.sleep(0.3)
    wire.put(mapper, T.MAP_DELTA, "bob", delta(0))
    wire.put(mapper, T.MAP_DELTA, "bob", delta(5))  # a gap: the daemon asks for a snapshot
    wire.put(ann, T.MAP_DELTA, "ann", delta(0))
    wire.put(ann, T.MAP_DELTA, "ann", delta(7))  # would be a gap too, were it let in
    deadline = time.monotonic() + 5.0
    while "bob" not in asked["mapper"] and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.5)
    assert "bob" in asked["mapper"], "the daemon never asked for bob's snapshot"
    assert asked["ann"] == []
    assert "ann" not in asked["mapper"], "ann's deltas reached the daemon"
    for q in queryables:
        q.undeclare()


# -- what the rules let through ------------------------------------------------------------


@pytest.mark.timeout(120)
def test_guidance_works_end_to_end_under_the_rules(sessions):
    """The legitimate flow, every hop through the access rules: the simulator (mapper,
    localiser and walker) walks ann to her goal, set from her phone; her belt driver finds
    the daemon's liveliness token and its settings query answered."""
    from sim.courtyard import make_courtyard
    from sim.node import SimNode

    ann, sim, belt = sessions("user:ann"), sessions("sim"), sessions("belt:ann")
    assert any(r.ok is not None for r in wire.alive(belt, T.ALIVE))
    scenario = make_courtyard(50, 0.2, seed=3)
    assert scenario.cell_m == 0.2  # the daemon fixture's cell
    node = SimNode(sim, "ann", scenario)
    result: dict = {}
    stop = threading.Event()
    walker = threading.Thread(target=lambda: result.setdefault("r", node.run(stop, 10**4, 60)))
    walker.start()
    try:
        time.sleep(0.3)  # the map and the first poses before the goal
        wire.put(ann, T.GOAL, "ann", goal_at(*scenario.goal))
        walker.join(70)
    finally:
        stop.set()
        walker.join(5)
        node.close()
    assert not walker.is_alive()
    assert result["r"].arrived, result["r"].reason
    # ann is a user of the daemon now: her belt driver's start-up query is answered.
    settings = [r.ok for r in wire.get(belt, T.SETTINGS_QUERY, "ann") if r.ok is not None]
    assert codec.decode(UserSettings, settings[0].payload.to_bytes()).intensity is not None


# -- what the daemon says at start --------------------------------------------------------


@pytest.mark.parametrize(
    "zenoh_table, level, said",
    [
        ({"listen": ["tcp/127.0.0.1:7447"]}, "INFO", "no TLS: loopback only"),
        ({}, "INFO", "no TLS: loopback only"),
        ({"listen": ["tcp/0.0.0.0:7447"]}, "WARNING", "no TLS and endpoints beyond this host"),
        ({"connect": ["tcp/192.168.1.10:7447"]}, "WARNING", "no TLS and endpoints beyond"),
        ("tls", "WARNING", "mutual TLS without access control"),
        ("tls+access", "INFO", "mutual TLS, access control by certificate name"),
    ],
)
def test_the_daemon_says_at_start_who_may_connect(certs, caplog, zenoh_table, level, said):
    from daemon.service.config import DaemonConfig
    from daemon.service.queries import say_who_may_connect

    _, nodes, _ = certs
    if zenoh_table == "tls+access":
        settings = nodes["daemon"].settings
    elif zenoh_table == "tls":
        settings = nodes["daemon"].settings.model_copy(update={"access": None})
    else:
        settings = ZenohSettings(**zenoh_table)
    caplog.set_level("INFO", logger="guidebelt.daemon")
    say_who_may_connect(DaemonConfig(backend="cpu", zenoh=settings).zenoh)
    lines = [(r.levelname, r.getMessage()) for r in caplog.records]
    assert len(lines) == 1 and lines[0][0] == level and lines[0][1].startswith(said), lines


@pytest.mark.timeout(60)
def test_the_command_line_joins_with_the_table_certs_wrote(certs, daemon):
    """``guidebelt goal --zenoh-config user-ann.toml`` reaches ann's session over TLS, and a
    config naming a missing certificate is one line and exit 2."""
    from typer.testing import CliRunner

    from cli.app import app

    _, nodes, _ = certs
    endpoint = f"tls/127.0.0.1:{daemon.port}"
    table = str(nodes["user:ann"].toml)
    args = ["goal", "ann", "4", "4", "--cell", "--wait", "1", "--zenoh-config", table]
    run = CliRunner().invoke(app, [*args, "--connect", endpoint])
    assert "goal sent to ann" in run.output, run.output
    assert len(run.output.strip().splitlines()) >= 2, "no status came back"
    broken = nodes["user:ann"].toml.with_name("broken.toml")
    broken.write_text(nodes["user:ann"].toml.read_text().replace("user-ann.key", "gone.key"))
    run = CliRunner().invoke(app, ["goal", "ann", "4", "4", "--zenoh-config", str(broken)])
    assert run.exit_code == 2 and "gone.key not found" in run.output, run.output
