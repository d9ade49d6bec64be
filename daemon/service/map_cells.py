"""Every user's map size, kept as maps come and go, for the memory budget (``map_too_big``).

The budget is asked about each map delta before it is decoded (a delta may declare a new, larger
map). Summing every other user's map there was a pass over all the runners per delta: 7.2 µs a
delta at 25 users in-process against 0.9 µs for the total (dev VM, 2026-11-27), at 250 deltas a
second a worker. Each user's navigator now says the size of every map it takes (``MapKeeper``'s
``on_cells``, on the user's step thread), and the budget reads a running total.
"""

from __future__ import annotations

import functools
import itertools
import threading
from collections.abc import Callable


class MapCells:
    """Cells of each session's current map, and their total. Counted per session, not per
    user name: a forgotten session's last step may still take a map after the user's next
    session has begun."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._cells: dict[tuple[str, int], int] = {}
        self._total = 0
        self._current: dict[str, tuple[str, int]] = {}
        self._serial = itertools.count()

    def open(self, user: str) -> Callable[[int], None]:
        """A new session of ``user``'s: what its map keeper tells each new map's size."""
        session = self._current[user] = (user, next(self._serial))
        return functools.partial(self._set, session)

    def close(self, user: str) -> Callable[[], None]:
        """``user``'s session is gone: its map no longer counts. Returns what clears it again
        once the session's last step is over (a step still running may take a map)."""
        clear = functools.partial(self._set, self._current.pop(user, ("", -1)), 0)
        clear()
        return clear

    def others(self, user: str) -> int:
        """The cells of every map but that of ``user``'s current session."""
        with self._lock:
            return self._total - self._cells.get(self._current.get(user, ("", -1)), 0)

    def total(self) -> int:
        with self._lock:
            return self._total

    def _set(self, session: tuple[str, int], cells: int) -> None:
        with self._lock:
            self._total += cells - self._cells.pop(session, 0)
            if cells:
                self._cells[session] = cells
