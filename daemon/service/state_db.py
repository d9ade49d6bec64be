"""The daemon's state on disk: one SQLite database (standard library), written off the hot path.

``<state_dir>/state.db`` holds, per user, the settings (``settings``), the session (``sessions``:
goal, navigation state, paused) and the latest map (``maps``: zlib-compressed occupancy with the
source's epoch and sequence). Write-ahead log on and ``synchronous=NORMAL``: a killed process
loses nothing committed, a power cut at most the last commits, and the file stays consistent.

Nothing that steps a user waits for the disk. Callers hand rows to ``put_*``, which only store
them in a coalescing table under a lock (the latest row per user and kind wins, so the queue is
bounded by users × kinds and a put never blocks); one writer thread commits what is pending as
one transaction at most every ``commit_s`` (woken only when it would otherwise sleep past a new
row's turn, not by every row) and each user's map at most every ``map_period_s``
(compressing it there, not on the user's worker). ``close`` writes whatever is pending.

A file that is not ours (another application id or schema version) or that SQLite finds corrupt
is moved aside with one log line, and the daemon starts from an empty database: a broken state
file costs the restore, never the service. Rows that no longer validate are skipped, each said.
"""

from __future__ import annotations

import logging
import sqlite3
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from protocol.messages import MapSnapshot

log = logging.getLogger("guidebelt.state")

FILE_NAME = "state.db"
APPLICATION_ID = 0x4742_4C54
"""``PRAGMA application_id``: "GBLT", so a foreign SQLite file is told from ours."""
SCHEMA_VERSION = 1
"""``PRAGMA user_version``; another one is moved aside like a foreign file (no migrations yet)."""
MAX_PENDING = 65_536
"""Rows waiting for the writer, all kinds: past it a row is dropped (and counted), never waited
for. Coalescing keeps it at users × 3, so only a flood of users reaches it."""

SCHEMA = """
CREATE TABLE settings (user TEXT PRIMARY KEY, json TEXT NOT NULL);
CREATE TABLE sessions (
    user TEXT PRIMARY KEY, goal TEXT, state TEXT NOT NULL, paused INTEGER NOT NULL,
    stamp REAL NOT NULL
);
CREATE TABLE maps (
    user TEXT PRIMARY KEY, epoch TEXT, seq INTEGER NOT NULL, height INTEGER NOT NULL,
    width INTEGER NOT NULL, occupancy BLOB NOT NULL, stamp REAL NOT NULL
);
"""


class ForeignDatabase(Exception):
    """The file is a database, but not guidebelt's (or not this schema's)."""


@dataclass(frozen=True)
class StoredSession:
    goal: str | None
    """The goal's JSON as it came on the wire, or None."""
    state: str
    paused: bool


@dataclass(frozen=True)
class StoredMap:
    epoch: int | None
    seq: int
    snapshot: MapSnapshot
    """Validated (shape, size, values) when read: ``snapshot.array()`` gives the occupancy."""


@dataclass
class Stored:
    """Everything the database held at start."""

    settings: dict[str, str] = field(default_factory=dict)
    sessions: dict[str, StoredSession] = field(default_factory=dict)
    maps: dict[str, StoredMap] = field(default_factory=dict)


@dataclass(frozen=True)
class _Map:
    occupancy: np.ndarray  # the worker's copy; compressed on the writer thread
    seq: int
    epoch: int | None
    stamp: float


class StateDB:
    def __init__(
        self, path: Path, conn: sqlite3.Connection, map_period_s: float, commit_s: float
    ) -> None:
        self.path = path
        self.map_period_s = map_period_s
        self.commit_s = commit_s
        self._conn = conn
        self._cond = threading.Condition()
        self._pending: dict[tuple[str, str], object] = {}
        self._map_written: dict[str, float] = {}
        self._last_commit = 0.0
        self._sleep_until = float("inf")
        """When the writer wakes by itself (monotonic); inf: not until a put wakes it."""
        self._closing = False
        self.commits = 0
        self.rows = 0
        self.dropped = 0
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name="guidebelt-state", daemon=True)

    # -- opening --------------------------------------------------------------------------

    @classmethod
    def open(
        cls, folder: Path, map_period_s: float = 2.0, commit_s: float = 0.25
    ) -> tuple[StateDB, Stored] | None:
        """The database in ``folder`` and what it holds, its writer started; None (said in one
        line) when the folder cannot be used at all, and the daemon runs without a store."""
        path = folder / FILE_NAME
        try:
            folder.mkdir(parents=True, exist_ok=True)
            try:
                conn, stored = _connect(path)
            except (sqlite3.DatabaseError, ForeignDatabase) as exc:
                aside = path.with_name(f"{FILE_NAME}.bad-{time.strftime('%Y%m%dT%H%M%S')}")
                log.error(
                    "state database unusable, moved aside; starting with no saved state",
                    extra={"fields": {"path": str(path), "moved_to": str(aside), "err": str(exc)}},
                )
                for suffix in ("", "-wal", "-shm"):
                    src = path.with_name(FILE_NAME + suffix)
                    if src.exists():
                        src.replace(aside.with_name(aside.name + suffix))
                conn, stored = _connect(path)
        except (OSError, sqlite3.Error, ForeignDatabase) as exc:
            log.error(
                "state not kept: cannot use the state directory",
                extra={"fields": {"path": str(path), "err": str(exc)}},
            )
            return None
        db = cls(path, conn, map_period_s, commit_s)
        db._thread.start()
        return db, stored

    # -- puts (any thread, never blocking) ------------------------------------------------

    def put_settings(self, user: str, settings_json: str) -> None:
        self._put(("settings", user), settings_json)

    def put_session(self, user: str, session: StoredSession) -> None:
        self._put(("session", user), session)

    def put_map(
        self, user: str, occupancy: np.ndarray, seq: int, epoch: int | None, stamp: float
    ) -> None:
        """``occupancy`` must be the caller's own copy: it is read later, on the writer."""
        self._put(("map", user), _Map(occupancy, seq, epoch, stamp))

    def forget(self, user: str) -> None:
        """The user's session and map go (an idle user's); the settings stay."""
        self._put(("session", user), None)
        self._put(("map", user), None)

    def _put(self, key: tuple[str, str], row: object) -> None:
        with self._cond:
            if self._closing:
                return
            if key not in self._pending and len(self._pending) >= MAX_PENDING:
                self.dropped += 1
                return
            self._pending[key] = row
            # Woken only when it would sleep past this row's turn: a wake per put (one a step
            # per user) would only send it back to sleep, at the cost of a GIL hand-off.
            if self._sleep_until > time.monotonic() + self.commit_s:
                self._cond.notify()

    # -- the writer -----------------------------------------------------------------------

    def _due(self, now: float) -> tuple[dict[tuple[str, str], object], float | None]:
        """The rows to write now, and how long until the next one is due (None: nothing)."""
        if not self._pending:
            return {}, None
        if not self._closing and now - self._last_commit < self.commit_s:
            return {}, self.commit_s - (now - self._last_commit)
        ready: dict[tuple[str, str], object] = {}
        wait: float | None = None
        for key, row in list(self._pending.items()):
            kind, user = key
            if kind == "map" and row is not None and not self._closing:
                left = self._map_written.get(user, -1e9) + self.map_period_s - now
                if left > 0:
                    wait = left if wait is None else min(wait, left)
                    continue
            ready[key] = self._pending.pop(key)
        return ready, wait

    def _run(self) -> None:
        while True:
            with self._cond:
                while True:
                    now = time.monotonic()
                    ready, wait = self._due(now)
                    if ready or (self._closing and not self._pending):
                        break
                    self._sleep_until = float("inf") if wait is None else now + wait
                    self._cond.wait(wait)
                self._sleep_until = 0.0  # busy: rows put now are taken on its next look
                closing = self._closing and not self._pending
            if ready:
                self._write(ready)
            if closing:
                return

    def _write(self, rows: dict[tuple[str, str], object]) -> None:
        now = time.monotonic()
        try:
            with self._conn:  # one transaction
                for (kind, user), row in rows.items():
                    self._write_row(kind, user, row)
                    if kind == "map" and row is not None:
                        self._map_written[user] = now
        except sqlite3.Error as exc:  # a full disk must not stop the guidance
            self.errors += 1
            log.warning("state not written", extra={"fields": {"rows": len(rows), "err": str(exc)}})
        else:
            self.commits += 1
            self.rows += len(rows)
        self._last_commit = time.monotonic()

    def _write_row(self, kind: str, user: str, row: object) -> None:
        c = self._conn
        if kind == "settings":
            c.execute("INSERT OR REPLACE INTO settings VALUES (?, ?)", (user, row))
        elif kind == "session" and row is None:
            c.execute("DELETE FROM sessions WHERE user = ?", (user,))
        elif kind == "session":
            assert isinstance(row, StoredSession)
            c.execute(
                "INSERT OR REPLACE INTO sessions VALUES (?, ?, ?, ?, ?)",
                (user, row.goal, row.state, int(row.paused), time.time()),
            )
        elif kind == "map" and row is None:
            c.execute("DELETE FROM maps WHERE user = ?", (user,))
        else:
            assert isinstance(row, _Map)
            h, w = row.occupancy.shape
            body = zlib.compress(row.occupancy.tobytes(), level=1)  # releases the GIL
            epoch = None if row.epoch is None else str(row.epoch)  # u64: past SQLite's INTEGER
            c.execute(
                "INSERT OR REPLACE INTO maps VALUES (?, ?, ?, ?, ?, ?, ?)",
                (user, epoch, row.seq, h, w, body, row.stamp),
            )

    def close(self) -> None:
        """Write what is pending (maps too, due or not), then stop the writer."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(10.0)
        try:
            self._conn.close()
        except sqlite3.Error as exc:
            log.warning("state database not closed cleanly", extra={"fields": {"err": str(exc)}})


def _connect(path: Path) -> tuple[sqlite3.Connection, Stored]:
    """Open (or create) ``path``, check it is ours and sound, and read everything in it."""
    conn = sqlite3.connect(path, check_same_thread=False, timeout=1.0)
    try:
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        if (app_id, version, tables) == (0, 0, 0):  # a new file
            conn.executescript(SCHEMA)
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
        elif (app_id, version) != (APPLICATION_ID, SCHEMA_VERSION):
            raise ForeignDatabase(f"application_id {app_id:#x}, user_version {version}")
        check = conn.execute("PRAGMA quick_check").fetchone()[0]
        if check != "ok":
            raise sqlite3.DatabaseError(f"quick_check: {check}")
        if conn.execute("PRAGMA journal_mode = WAL").fetchone()[0].lower() != "wal":
            raise sqlite3.DatabaseError("write-ahead log not available")
        conn.execute("PRAGMA synchronous = NORMAL")
        return conn, _read(conn)
    except BaseException:
        conn.close()
        raise


def _read(conn: sqlite3.Connection) -> Stored:
    stored = Stored()
    for user, text in conn.execute("SELECT user, json FROM settings"):
        stored.settings[str(user)] = str(text)
    for user, goal, state, paused, _stamp in conn.execute("SELECT * FROM sessions"):
        stored.sessions[str(user)] = StoredSession(goal, str(state), bool(paused))
    for user, epoch, seq, h, w, body, stamp in conn.execute("SELECT * FROM maps"):
        try:
            snap = MapSnapshot(
                seq=max(int(seq), 0), height=h, width=w, stamp=stamp, occupancy=bytes(body),
                epoch=None if epoch is None else int(epoch),
            )  # fmt: skip
            snap.array()  # the size and values checked once, here
        except (ValueError, TypeError) as exc:
            log.warning("stored map skipped", extra={"fields": {"user": user, "err": str(exc)}})
            continue
        stored.maps[str(user)] = StoredMap(snap.epoch, int(seq), snap)
    return stored
