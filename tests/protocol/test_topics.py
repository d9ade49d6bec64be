"""The topic table: keys, QoS policy, the schema derived from it, and that nothing else
spells a key or opens a zenoh session."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from protocol import topics as T
from protocol.messages import MAX_DELTA_CELLS, BeltHealth, NavStatus, RfidStats, StatusCode
from protocol.schema import MESSAGES
from protocol.topics import Congestion, Kind, Priority

ROOT = Path(__file__).resolve().parents[2]
PRODUCT = ("protocol", "daemon", "drivers", "sim", "cli", "scripts", "viewer", "recording")


def test_keys_stay_under_the_user_or_the_daemon():
    assert T.MAP_SOURCE.key("ann") == "guidebelt/ann/map/source"
    assert T.HEALTH.key() == "guidebelt/@daemon/health"
    assert T.ALIVE.key() == "guidebelt/@daemon/alive"
    assert T.POSE.any_user() == "guidebelt/*/pose"
    assert T.STATUS.selector(None) == T.STATUS.selector("*") == "guidebelt/*/status"
    assert T.user_of(T.STATUS.key("bo-1")) == "bo-1"
    assert T.STATUS.user_of("guidebelt/bo-1/status") == "bo-1"
    with pytest.raises(ValueError):
        T.STATUS.user_of("guidebelt/bo-1/pose")
    for bad in ("", "Ann", "-x", "a/b", "a" * 33, "@daemon"):
        with pytest.raises(ValueError):
            T.check_user(bad)
    with pytest.raises(ValueError):
        T.HEALTH.key("ann")  # daemon-wide: no user
    with pytest.raises(ValueError):
        T.POSE.key()  # per user: a user is needed


def test_every_key_is_in_one_row_and_found_again_from_its_key():
    seen = {(t.per_user, t.leaf, t.kind) for t in T.TOPICS}
    assert len(seen) == len(T.TOPICS)
    assert len({t.name for t in T.TOPICS}) == len(T.TOPICS)
    for topic in T.TOPICS:
        key = topic.key("ann") if topic.per_user else topic.key()
        assert topic.matches(key)
        if topic.kind is not Kind.LIVELINESS:
            assert T.topic_of(key, topic.kind) is topic
    assert not T.POSE.matches("guidebelt/@daemon/pose")
    assert not T.HEALTH.matches("guidebelt/ann/health")
    with pytest.raises(ValueError):
        T.topic_of("guidebelt/ann/nothing")


def test_qos_never_drops_what_steers_or_stops_the_user():
    for topic in (T.BELT, T.STATUS, T.GOAL, T.VOICE, T.MAP_DELTA):
        assert topic.qos.congestion is Congestion.BLOCK, topic.name
        assert topic.qos.express, topic.name
    assert T.BELT.qos.priority is Priority.REAL_TIME
    order = list(Priority)  # highest first
    for topic in T.TOPICS:
        if topic is not T.BELT:
            assert order.index(topic.qos.priority) > order.index(T.BELT.qos.priority)
    # Latest-wins data may be dropped on a full queue.
    for topic in (T.POSE, T.PATH, T.BELT_HEALTH, T.RFID_STATS):
        assert topic.qos.congestion is Congestion.DROP, topic.name
    # A pose never waits in (or is dropped from) a queue of messages that must arrive: zenoh
    # drops a DROP sample that finds its priority's queue full (the lost-pose bug).
    sharing = [
        t.name for t in T.TOPICS if t.qos.priority is T.POSE.qos.priority and t is not T.POSE
    ]
    assert not sharing, sharing
    assert order.index(T.POSE.qos.priority) > order.index(T.GOAL.qos.priority)


def test_status_codes_are_an_enum_and_the_wire_is_unchanged():
    status = NavStatus(state="stale", code="stale_pose", stamp=1.0)
    assert status.code is StatusCode.STALE_POSE
    assert json.loads(status.model_dump_json())["code"] == "stale_pose"
    assert NavStatus(state="idle", stamp=1.0).code == "" == StatusCode.OK
    with pytest.raises(ValueError):
        NavStatus(state="idle", stamp=1.0, code="not_a_code")


def test_every_status_code_has_an_outcome_for_the_user():
    from daemon.navigation import OUTCOMES

    assert set(OUTCOMES) == {c.value for c in StatusCode} - {StatusCode.OK.value}


def test_the_schema_list_comes_from_the_table():
    models = {t.model for t in T.TOPICS if t.model is not None}
    assert set(MESSAGES) == models
    assert BeltHealth in MESSAGES and RfidStats in MESSAGES


@pytest.mark.timeout(60)
def test_schema_command_writes_one_schema_per_topic_message(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "cli.app", "schema", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=50,
    )
    assert out.returncode == 0, out.stderr
    files = sorted(p.name for p in tmp_path.glob("*.schema.json"))
    wanted = {t.model.__name__ for t in T.TOPICS if t.model is not None}
    assert files == sorted(f"{name}.schema.json" for name in wanted)
    delta = json.loads((tmp_path / "MapDelta.schema.json").read_text())
    assert delta["additionalProperties"] is False
    assert delta["x-wire"]["max_count"] == MAX_DELTA_CELLS
    assert delta["x-topics"] == [
        {"key": "guidebelt/*/map/delta", "kind": "publish/subscribe", "from": "mapper / sim",
         "to": "daemon", "may_send": ["mapper", "sim"], "may_receive": ["daemon"]}
    ]  # fmt: skip
    pose = json.loads((tmp_path / "Pose.schema.json").read_text())
    assert set(pose["required"]) == {"x", "y", "heading", "stamp"}
    status = json.loads((tmp_path / "NavStatus.schema.json").read_text())
    assert "stale_pose" in json.dumps(status)  # the enum of codes is in the schema
    table = (tmp_path / "topics.md").read_text().splitlines()
    assert len(table) == 2 + len(T.TOPICS)
    belt = table[2 + T.TOPICS.index(T.BELT)]
    assert belt.startswith("| `guidebelt/*/belt` | BeltPattern | publish/subscribe |")


def _sources(*folders: str) -> list[Path]:
    return [p for f in folders for p in (ROOT / f).rglob("*.py")]


def test_no_key_is_spelled_and_no_session_opened_outside_protocol():
    """Keys come from the table and sessions from ``open_session``, in product and tests."""
    leaves = "|".join(re.escape(t.leaf) for t in T.TOPICS if "/" in t.leaf)
    spelled = re.compile(rf"[\"'](guidebelt/|{leaves})")
    offenders = []
    for path in _sources(*PRODUCT, "tests"):
        rel = path.relative_to(ROOT)
        if rel.parts[0] == "protocol" or rel.parts[:2] == ("tests", "protocol"):
            continue  # the table and its own tests
        text = path.read_text()
        # The intruder with no certificate cannot be written as ZenohSettings (they always
        # present one): these tests open zenoh on a config of their own.
        raw_open_allowed = rel.as_posix() in (
            "tests/daemon/service/test_tls_access.py",
            "tests/daemon/service/test_workers_tls_walk.py",
        )
        if spelled.search(text) or ("zenoh.open(" in text and not raw_open_allowed):
            offenders.append(str(rel))
    assert offenders == []
    opens = [p for p in _sources("protocol") if "zenoh.open(" in p.read_text()]
    assert [p.name for p in opens] == ["session.py"]


def test_the_belt_buttons_and_settings_are_in_the_table_and_the_schema():
    """Issue 26: what the belt's buttons and the user's settings travel on is in the one table,
    so ``guidebelt schema`` documents it with no list of its own."""
    from protocol.schema import schemas

    assert T.topic_of("guidebelt/ann/belt/button") is T.BELT_BUTTON
    assert T.topic_of("guidebelt/ann/settings/set") is T.SETTINGS_SET
    assert T.topic_of("guidebelt/ann/settings", T.Kind.QUERYABLE) is T.SETTINGS_QUERY
    assert T.SETTINGS_SET.user_of("guidebelt/ann/settings/set") == "ann"
    out = schemas()
    assert {"BeltButton", "UserSettings"} <= set(out)
    props = out["UserSettings"]["properties"]
    assert props["intensity"]["anyOf"][0]["maximum"] == 100  # or null: left as it is
    assert props["wording"]["anyOf"][0]["enum"] == ["clock", "sides"]
    assert "paused" in out["NavStatus"]["properties"]
    assert "battery_v" in out["BeltHealth"]["properties"]
