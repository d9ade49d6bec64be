"""Where each user's run-time settings (``UserSettings``) are kept between sessions.

One JSON file per user, ``<settings_dir>/<user>.json``, written whole and renamed into
place, so a crash mid-write leaves the old file. Without a ``settings_dir`` the settings
live as long as the daemon. A file that no longer validates is ignored (and said so): the
user gets the configured defaults rather than no belt.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path

from pydantic import ValidationError

from protocol.messages import UserSettings
from protocol.topics import check_user

log = logging.getLogger("guidebelt.settings")


class SettingsStore:
    def __init__(self, folder: Path | None, intensity: int = 100) -> None:
        self.folder = folder
        self.intensity = intensity
        self._memory: dict[str, UserSettings] = {}
        self._lock = threading.Lock()

    def default(self) -> UserSettings:
        return UserSettings(intensity=self.intensity, stamp=time.time())

    def _path(self, user: str) -> Path:
        assert self.folder is not None
        return self.folder / f"{check_user(user)}.json"

    def load(self, user: str) -> UserSettings:
        with self._lock:
            if user in self._memory:
                return self._memory[user]
        if self.folder is None or not self._path(user).is_file():
            return self.default()
        try:
            return UserSettings.model_validate_json(self._path(user).read_text())
        except (OSError, ValidationError) as exc:
            log.warning(
                "stored settings ignored", extra={"fields": {"user": user, "err": str(exc)}}
            )
            return self.default()

    def save(self, user: str, settings: UserSettings) -> None:
        """Any thread: the users' workers store their own settings."""
        with self._lock:
            self._memory[user] = settings
        if self.folder is None:
            return
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            path = self._path(user)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(settings.model_dump_json())
            os.replace(tmp, path)
        except OSError as exc:  # a full disk must not stop the guidance
            log.warning("settings not stored", extra={"fields": {"user": user, "err": str(exc)}})
