"""Each user's settings survive a daemon restart, and a broken file costs only the defaults."""

from __future__ import annotations

import time

from daemon.service.user_settings import SettingsStore
from protocol.messages import UserSettings


def test_settings_are_stored_per_user_and_read_back(tmp_path):
    store = SettingsStore(tmp_path / "settings", intensity=80)
    assert store.load("ann").intensity == 80  # nothing stored: the config's default
    store.save("ann", UserSettings(intensity=25, stamp=time.time()))
    again = SettingsStore(tmp_path / "settings", intensity=80)  # a restarted daemon
    assert again.load("ann").intensity == 25
    assert again.load("bob").intensity == 80
    assert sorted(p.name for p in (tmp_path / "settings").iterdir()) == ["ann.json"]


def test_a_broken_file_gives_the_defaults_and_no_folder_keeps_them_in_memory(tmp_path):
    (tmp_path / "ann.json").write_text('{"intensity": 900, "stamp": 1}')
    assert SettingsStore(tmp_path, intensity=60).load("ann").intensity == 60
    memory = SettingsStore(None, intensity=60)
    memory.save("ann", UserSettings(intensity=10, stamp=time.time()))
    assert memory.load("ann").intensity == 10
