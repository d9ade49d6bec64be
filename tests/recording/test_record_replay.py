"""A recorded walk: read back with the mcap library, in order, each message valid against the
JSON Schema stored with it; replayed into a fresh daemon, the same belt patterns."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest


def record_walk(daemon, out: Path, user: str):
    """The demo walk through ``daemon`` with a recorder beside it; the recorder's counts."""
    from daemon.service.embedded import free_port
    from protocol.session import ZenohSettings, open_session
    from recording.recorder import Recorder
    from sim.live import LiveWalks, endpoints

    port = free_port()
    session = open_session(ZenohSettings(listen=endpoints(port), connect=endpoints(daemon.port)))
    cfg = daemon.config
    meta = {"planner": cfg.planner, "backend": cfg.backend, "cell_m": cfg.cell_m,
            "user_radius_m": cfg.user_radius_m}  # fmt: skip
    try:
        with Recorder(session, out, user, metadata=meta) as rec:
            with LiveWalks(daemon.port, [user], observers=[port], pace_s=0.0) as walks:
                assert walks.join(60)
            time.sleep(0.3)  # the last step's outputs reach the recorder
    finally:
        session.close()
    assert walks.results[user][0].arrived, walks.results[user][0].reason
    return rec.counts


@pytest.fixture(scope="module")
def walk(daemon, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rec") / "walk.mcap"
    counts = record_walk(daemon, out, "rec")
    # Every message heard was written: none dropped, none refused, one file.
    assert counts.dropped == 0 and counts.invalid == 0, counts
    assert counts.written == counts.heard > 100, counts
    assert counts.files == 1
    return out


@pytest.mark.timeout(120)
def test_read_back_in_order_with_valid_schemas(walk: Path) -> None:
    import jsonschema
    from mcap.reader import make_reader

    from protocol import topics as T

    with walk.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        seen: dict[int, int] = {}
        last_time = 0
        keys = set()
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            model = T.topic_of(channel.topic).model
            assert schema.name == f"guidebelt.{model.__name__}"
            jsonschema.validate(json.loads(message.data), json.loads(schema.data))
            # In the file as heard: log times never go back; each key's numbers 0, 1, 2, …
            assert message.log_time >= last_time
            last_time = message.log_time
            assert message.sequence == seen.get(channel.id, -1) + 1
            seen[channel.id] = message.sequence
            keys.add(channel.topic)
    assert summary.statistics.message_count == sum(n + 1 for n in seen.values())
    for topic in (T.MAP_DELTA, T.POSE, T.GOAL, T.PATH, T.STATUS, T.BELT, T.VOICE):
        assert topic.key("rec") in keys, keys


@pytest.mark.timeout(120)
def test_replay_check_into_a_fresh_daemon_finds_no_difference(walk: Path) -> None:
    from daemon.service.embedded import DaemonThread
    from recording.check import check
    from recording.replay import metadata, read

    meta = metadata(walk)
    items = list(read(walk))
    config = {k: meta[k] for k in ("planner", "backend", "cell_m", "user_radius_m")}
    with DaemonThread(**config) as fresh:
        session = fresh.peer()
        try:
            report = check(session, items)
        finally:
            session.close()
    assert report.inputs > 50
    assert report.steps_compared > 50 and report.statuses_compared >= 3, report
    assert report.differences == [], [str(d) for d in report.differences]


@pytest.mark.timeout(60)
def test_check_reports_a_changed_pattern_at_its_input(walk: Path) -> None:
    """The comparison is not blind: one recorded step's pattern altered is one difference,
    named by the pose it planned from; a step the replay never made is one too."""
    from recording.check import compare_steps, split
    from recording.replay import read

    _inputs, outputs, poses = split(list(read(walk)))
    steps = outputs.step_belts(poses)
    assert len(steps) > 50
    key = sorted(steps)[20]
    altered = {**steps, key: ("stop", (255, 255, 255, 255), 0)}
    diffs = compare_steps(steps, altered)
    assert len(diffs) == 1 and diffs[0].after_input == key[1]
    assert diffs[0].recorded == [steps[key]]
    missing = {k: v for k, v in steps.items() if k != key}
    assert [d.after_input for d in compare_steps(steps, missing)] == [key[1]]


@pytest.mark.timeout(60)
def test_replay_drives_a_view_without_any_daemon(walk: Path) -> None:
    """The recorded walk, published back (fast), is what a view shows: the last pattern and
    status recorded are the ones it holds at the end."""
    from daemon.service.embedded import free_port
    from protocol.session import loopback, open_session
    from recording.replay import Player, read
    from viewer.node import WATCHED, ViewNode
    from viewer.state import ViewState

    items = list(read(walk))
    # Poses and paths are latest-wins on the wire (a full queue may drop one at full speed);
    # the rest must arrive, every one.
    drawn = sum(r.topic in WATCHED for r in items)
    must = sum(r.topic in WATCHED and r.topic.qos.congestion == "block" for r in items)
    port = free_port()
    view_session = open_session(loopback(listen_port=port))
    player_session = open_session(loopback(connect_port=port))
    state = ViewState()
    try:
        with ViewNode(view_session, state):
            time.sleep(0.3)  # the two sessions meet before the first sample
            player = Player(player_session, items, speed=0)
            assert player.run() == len(items)
            player.close()
            last = {r.topic.name: r.msg for r in items}

            def belt_seq() -> int | None:
                user = state.frame()["users"].get("rec")
                return user["belt"]["seq"] if user and user["belt"] else None

            end = time.monotonic() + 5  # the last pattern is the last to come
            while time.monotonic() < end and belt_seq() != last["belt"].seq:
                time.sleep(0.05)
            time.sleep(0.2)  # the status published after it
            user = state.frame()["users"]["rec"]
    finally:
        player_session.close()
        view_session.close()
    assert must <= user["messages"] <= drawn
    assert user["belt"]["motors"] == list(last["belt"].motors)
    assert user["status"]["state"] == str(last["status"].state)
    assert user["map"]["seq"] == last["map_delta"].seq
