"""Each user's settings survive a daemon restart, and a broken row costs only the defaults."""

from __future__ import annotations

import time

from daemon.service.config import DaemonConfig
from daemon.service.persistence import Persistence
from daemon.service.user_settings import SettingsStore
from protocol.messages import UserSettings


def store_in(state: Persistence) -> SettingsStore:
    return SettingsStore(80, state.stored_settings, state.save_settings)


def test_settings_are_stored_per_user_and_read_back(tmp_path):
    state = Persistence(DaemonConfig(state_dir=tmp_path))
    store = store_in(state)
    assert store.load("ann").intensity == 80  # nothing stored: the config's default
    store.save("ann", UserSettings(intensity=25, stamp=time.time()))
    state.close()
    again = Persistence(DaemonConfig(state_dir=tmp_path))  # a restarted daemon
    assert store_in(again).load("ann").intensity == 25
    assert store_in(again).load("bob").intensity == 80
    assert sorted(again.stored.settings) == ["ann"]
    again.close()


def test_a_broken_row_gives_the_defaults_and_no_store_keeps_them_in_memory(tmp_path):
    state = Persistence(DaemonConfig(state_dir=tmp_path))
    assert state.db is not None
    state.db.put_settings("ann", '{"intensity": 900, "stamp": 1}')
    state.close()
    again = Persistence(DaemonConfig(state_dir=tmp_path))
    assert store_in(again).load("ann").intensity == 80
    again.close()
    memory = SettingsStore(60)
    memory.save("ann", UserSettings(intensity=10, stamp=time.time()))
    assert memory.load("ann").intensity == 10


def test_the_old_settings_dir_is_imported_once(tmp_path, caplog):
    old = tmp_path / "settings"
    old.mkdir()
    (old / "ann.json").write_text('{"intensity": 45, "stamp": 1}')
    (old / "bob.json").write_text('{"intensity": 900, "stamp": 1}')  # refused, said
    state = Persistence(DaemonConfig(state_dir=tmp_path / "state", settings_dir=old))
    assert store_in(state).load("ann").intensity == 45
    assert store_in(state).load("bob").intensity == 80
    state.close()
    assert "settings_dir is no longer used" in caplog.text
    again = Persistence(DaemonConfig(state_dir=tmp_path / "state"))
    assert sorted(again.stored.settings) == ["ann"]  # in the database now
    again.close()
