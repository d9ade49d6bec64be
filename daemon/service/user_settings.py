"""Each user's run-time settings (``UserSettings``), kept between sessions and restarts.

Stored in the daemon's state database (``persistence.Persistence``) when there is one; in
memory either way. A stored row that no longer validates is ignored (and said so): the user
gets the configured defaults rather than no belt.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from protocol.messages import UserSettings


class SettingsStore:
    def __init__(
        self,
        intensity: int = 100,
        stored: Callable[[str], UserSettings | None] | None = None,
        write: Callable[[str, UserSettings], None] | None = None,
    ) -> None:
        """``stored(user)``: what the store held at start; ``write``: hand a change to it."""
        self.intensity = intensity
        self._stored = stored
        self._write = write
        self._memory: dict[str, UserSettings] = {}
        self._lock = threading.Lock()

    def default(self) -> UserSettings:
        return UserSettings(intensity=self.intensity, stamp=time.time())

    def load(self, user: str) -> UserSettings:
        with self._lock:
            if user in self._memory:
                return self._memory[user]
        found = self._stored(user) if self._stored is not None else None
        return found if found is not None else self.default()

    def save(self, user: str, settings: UserSettings) -> None:
        """Any thread: the users' workers store their own settings (never waiting on disk)."""
        with self._lock:
            self._memory[user] = settings
        if self._write is not None:
            self._write(user, settings)
