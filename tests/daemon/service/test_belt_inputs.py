"""The daemon's side of the belt's inputs over zenoh: settings on the user's own key, stored
and published; a belt's health alone starts no session."""

from __future__ import annotations

import json
import sqlite3
import time

import pytest

from daemon.service.embedded import DaemonThread
from drivers.belt.recorder import Recorder
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltHealth, Goal, GoalCell, Health, UserSettings


def health(peer) -> Health:
    reply = next(r.ok for r in wire.get(peer, T.HEALTH) if r.ok is not None)
    return codec.decode(Health, reply.payload.to_bytes())


@pytest.mark.timeout(90)
def test_settings_set_is_applied_stored_and_survives_a_restart(tmp_path):
    folder = tmp_path / "state"
    with DaemonThread(backend="cpu", state_dir=folder, intensity=70) as daemon:
        peer = daemon.peer()
        applied: Recorder[UserSettings] = Recorder(peer, T.SETTINGS, "ann")
        time.sleep(0.2)
        goal = Goal(target=GoalCell(row=1, col=1), stamp=time.time())
        wire.put(peer, T.GOAL, "ann", codec.encode(goal))  # ann's session starts
        first = applied.wait_for(lambda r: True, 3.0)
        assert first is not None and first.msg.intensity == 70  # the config's, for a new user
        wire.put(peer, T.SETTINGS_SET, "ann", codec.encode(UserSettings(intensity=35, stamp=1.0)))
        assert applied.wait_for(lambda r: r.msg.intensity == 35, 3.0) is not None
        # A belt that is only switched on starts no session for its user.
        idle = BeltHealth(port="/dev/x", connected=True, belt_state="idle", frames_sent=0,
                          acks=0, refused=0, dropped=0, reconnects=0, rx_errors=0,
                          belt_crc_errors=0, belt_oversized=0, belt_truncated=0,
                          belt_malformed=0, watchdog_trips=0, battery_v=3.9,
                          stamp=time.time())  # fmt: skip
        wire.put(peer, T.BELT_HEALTH, "bob", codec.encode(idle))
        time.sleep(0.5)
        assert health(peer).users == ["ann"]
        applied.close()
        peer.close()
    with sqlite3.connect(folder / "state.db") as db:
        (stored,) = db.execute("SELECT json FROM settings WHERE user = 'ann'").fetchone()
    assert json.loads(stored)["intensity"] == 35
    with DaemonThread(backend="cpu", state_dir=folder, intensity=70) as daemon:
        peer = daemon.peer()
        wire.put(peer, T.GOAL, "ann", codec.encode(goal))
        deadline = time.monotonic() + 3.0
        replies: list[UserSettings] = []
        while not replies and time.monotonic() < deadline:
            for reply in wire.get(peer, T.SETTINGS_QUERY, "ann", timeout=1.0):
                if reply.ok is not None:
                    replies.append(codec.decode(UserSettings, reply.ok.payload.to_bytes()))
        assert [s.intensity for s in replies] == [35]  # read back after the restart
        peer.close()
