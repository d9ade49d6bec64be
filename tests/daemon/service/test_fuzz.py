"""A bounded fuzz campaign on every key the daemon subscribes to: random bytes, mutated valid
messages and hypothesis-made JSON, 20,000+ inputs. The daemon must refuse what is bad (and count
it), never raise out of a callback, keep every user's session alive and answering, and stay
within its memory."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daemon.service.bridge import INPUTS
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import (
    BeltButton,
    BeltHealth,
    Goal,
    GoalCell,
    Health,
    MapDelta,
    NavStatus,
    Pose,
    Proximity,
    UserSettings,
)

pytestmark = pytest.mark.timeout(180)
USERS = ("f0", "f1", "f2")


def valid_examples(now: float) -> dict:
    """One well-formed message per input topic, encoded, to mutate."""
    belt = BeltHealth.model_json_schema()  # its required fields, filled with zeros
    health = {k: 0 for k in belt.get("required", [])}
    health.update(state="active", connected=True, stamp=now)
    examples = {
        T.MAP_DELTA: codec.encode(
            MapDelta.from_arrays(0, (40, 40), np.arange(20), np.ones(20, np.uint8), now)
        ),
        T.POSE: codec.encode(Pose(x=1.0, y=1.0, heading=0.5, stamp=now)),
        T.GOAL: codec.encode(Goal(target=GoalCell(row=5, col=5), stamp=now)),
        T.BELT_BUTTON: codec.encode(BeltButton(press=1, button=0, kind="short", stamp=now)),
        T.SETTINGS_SET: codec.encode(UserSettings(intensity=50, stamp=now)),
        T.BELT_HEALTH: json.dumps(health).encode(),
        T.PROXIMITY: codec.encode(
            Proximity(ahead_m=2.0, nearest_m=1.0, bearing=0.1, frame_stamp=now, stamp=now)
        ),
    }
    assert set(examples) == set(INPUTS)  # a new input topic needs its example here
    return examples


def mutate(rng: np.random.Generator, data: bytes) -> bytes:
    b = bytearray(data)
    kind = rng.integers(5)
    if kind == 0 and b:  # flip bytes
        for i in rng.integers(0, len(b), size=int(rng.integers(1, 8))):
            b[i] = int(rng.integers(256))
    elif kind == 1:  # truncate
        b = b[: int(rng.integers(0, len(b) + 1))]
    elif kind == 2:  # extend
        b += rng.bytes(int(rng.integers(1, 64)))
    elif kind == 3:  # splice two halves
        cut = int(rng.integers(0, len(b) + 1))
        b = b[cut:] + b[:cut]
    else:  # random bytes of about the same length
        b = bytearray(rng.bytes(int(rng.integers(0, 2 * len(b) + 2))))
    return bytes(b)


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def feed(daemon, batch: list[tuple]) -> None:
    """Deliver samples as the bridge does: on the daemon's loop, one after another."""

    def deliver() -> int:
        for topic, key, payload in batch:
            daemon.daemon._on_sample(topic, key, payload, time.time())
        return len(batch)

    assert daemon.call(deliver) == len(batch)  # an exception here would be the daemon's


def sessions_alive_and_answering(daemon, peer) -> None:
    for user in USERS:
        runner = daemon.call(lambda u=user: daemon.daemon.runners.get(u))
        assert runner is not None, user
        assert runner.serving, f"{user}'s session ended"
        replies = [r.ok for r in wire.get(peer, T.STATUS_QUERY, user) if r.ok is not None]
        assert replies, f"{user}'s session is silent"
        codec.decode(NavStatus, replies[0].payload.to_bytes())


def test_twenty_thousand_bad_inputs_leave_every_session_alive_and_counted(daemon, peer):
    rng = np.random.default_rng(0)
    now = time.time()
    examples = valid_examples(now)
    # Start each user's session with a valid map and goal.
    feed(daemon, [(t, t.key(u), examples[t]) for u in USERS for t in (T.MAP_DELTA, T.GOAL)])
    before_rss, invalid, total = rss_mb(), 0, 0
    good = T.POSE.key("f0")  # keys are the table's; a hostile peer's are made from one
    bad_keys = [
        good.replace("/f0/", "//"),
        good.replace("f0", "x" * 300),
        good.replace("f0", "Ann!"),
    ]
    t0 = time.monotonic()
    while total < 20_000:
        batch = []
        for _ in range(1000):
            topic = INPUTS[int(rng.integers(len(INPUTS)))]
            if rng.random() < 0.02:
                key = bad_keys[int(rng.integers(len(bad_keys)))]
                invalid += 1
            else:
                key = topic.key(USERS[int(rng.integers(len(USERS)))])
            payload = mutate(rng, examples[topic])
            if key not in bad_keys:
                try:
                    codec.decode(topic.model, payload)
                except codec.DecodeError:
                    invalid += 1
            batch.append((topic, key, payload))
        feed(daemon, batch)
        total += len(batch)
    took = time.monotonic() - t0
    sessions_alive_and_answering(daemon, peer)
    # Refusals are counted by the step that takes them from the inbox: on a slow machine
    # the last batch's step may still run, so wait (bounded) for the count to settle.
    deadline = time.monotonic() + 30.0
    while True:
        health = [r.ok for r in wire.get(peer, T.HEALTH) if r.ok is not None]
        h = codec.decode(Health, health[0].payload.to_bytes())
        if h.rejected >= invalid or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    assert h.rejected >= invalid > 5_000, (h.rejected, invalid)
    assert sum(h.rejected_by_code.values()) == h.rejected
    assert h.log_lines_suppressed > 0  # the flood was not written out line by line
    assert rss_mb() - before_rss < 200
    print(f"{total} inputs in {took:.1f} s, {invalid} invalid, health {h.rejected_by_code}")


@settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    topic=st.sampled_from([t for t in INPUTS if t is not T.MAP_DELTA]),
    body=st.recursive(
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
        lambda inner: (
            st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner, max_size=6)
        ),
        max_leaves=20,
    ),
)
def test_any_json_on_any_key_is_refused_or_taken_never_fatal(daemon, peer, topic, body):
    payload = json.dumps(body, allow_nan=True).encode()
    feed(daemon, [(topic, topic.key(USERS[0]), payload)])
    runner = daemon.call(lambda: daemon.daemon.runners.get(USERS[0]))
    assert runner is not None and runner.serving
