"""What of each session outlives the daemon, and how a restarted daemon picks it up again.

Kept (``state_db.StateDB``): the goal, the navigation state and the pause, each user's settings,
and the latest map with its source's epoch and sequence. Not kept: the pose. A restored session
has its map, goal and settings back before the daemon's liveliness token appears; one that had
a goal says ``restored`` (WAIT) once a second until a fresh pose comes (the belt and the client
reconnect after the daemon does and would miss a single word), and no guidance is ever given on
a pre-crash pose. Clients learn of the restart from the token and resend what the daemon may
have missed while it was down (the sim node its goal); the map source is asked for a snapshot.

The map is written whole (compressed) at most every ``persist_map_s`` per user rather than as a
log of deltas: the map source holds the truth and is asked for a snapshot on restore (the stored
map stays stale, so the user waits, until it answers), so a log would buy back only what the
source re-sends anyway, at the cost of a write per delta. If the source is silent the stored map
is used as it is, and a later delta out of sequence asks again.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path

from pydantic import ValidationError

from daemon.navigation import Navigator
from protocol import codec
from protocol import topics as T
from protocol.messages import Goal, StatusCode, UserSettings

from .config import DaemonConfig
from .runner import UserRunner
from .state_db import StateDB, Stored, StoredSession

log = logging.getLogger("guidebelt.state")

RESTORE_RETRY_S = 1.0
"""How often a restored map's source is asked again: it may not have reconnected yet."""
RESTORE_WAIT_S = 10.0
"""How long a restored map waits for its source before it is used unconfirmed."""
ANNOUNCE_S = 60.0
"""How long a restored user without a fresh pose keeps hearing ``restored`` (WAIT), once a
``RESTORE_RETRY_S``: the belt and the client reconnect after the daemon is back and would
miss a single announcement."""


class SessionSaver:
    """One user's link to the store: hands it what changed since the last step (worker)."""

    def __init__(self, db: StateDB, user: str) -> None:
        self.db = db
        self.user = user
        self._goal: Goal | None = None
        self._goal_json: str | None = None
        self._session: StoredSession | None = None
        self._map_key: tuple | None = None
        self._map_at = -1e9

    def __call__(self, nav: Navigator) -> None:
        if nav.goal is not self._goal:
            self._goal = nav.goal
            self._goal_json = None if nav.goal is None else codec.encode(nav.goal).decode()
        session = StoredSession(self._goal_json, str(nav.state), nav.controls.paused)
        if session != self._session:
            self._session = session
            self.db.put_session(self.user, session)
        maps = nav.maps
        if maps.map is None or maps.stale:
            return  # a stale map is not worth keeping: the source's snapshot replaces it
        key = (id(maps.map), maps.epoch, maps.seq)
        now = time.monotonic()
        # The copy is the worker's only cost (0.6 ms at 2000², after the step's belt pattern
        # is out), so it is made at most once a period; a change left over is taken by the
        # user's next step (every pose steps), and the source's snapshot covers the rest.
        if key != self._map_key and now - self._map_at >= self.db.map_period_s:
            self._map_key, self._map_at = key, now
            occupancy = maps.map.occupancy.copy()
            self.db.put_map(self.user, occupancy, maps.seq, maps.epoch, time.time())


class Persistence:
    """The daemon's store, or none (``state_dir`` unset or unusable: said once at start)."""

    def __init__(self, config: DaemonConfig) -> None:
        self.db: StateDB | None = None
        self.stored = Stored()
        self._retry_at: dict[str, float] = {}
        """Users whose restored map waits for its source: when to ask again (monotonic)."""
        self._announce: dict[str, tuple[float, float]] = {}
        """Restored users not yet heard from with a pose: when to say so again, and until."""
        if config.state_dir is None:
            log.warning("state not kept: no state_dir; a restart loses every session")
            return
        opened = StateDB.open(config.state_dir, map_period_s=config.persist_map_s)
        if opened is not None:
            self.db, self.stored = opened
            if config.settings_dir is not None:
                self._import_settings(config.settings_dir)
            log.info(
                "state database open",
                extra={"fields": {"path": str(self.db.path), "sessions": len(self.stored.sessions),
                                  "maps": len(self.stored.maps)}},
            )  # fmt: skip

    def _import_settings(self, folder: Path) -> None:
        """The JSON files of the old ``settings_dir`` (one per user), for users the database
        has no settings of; a file that does not validate is left out, said."""
        assert self.db is not None
        taken = 0
        for path in sorted(folder.glob("*.json"))[:10_000]:
            user = path.stem
            if user in self.stored.settings or not T.USER_RE.match(user):
                continue
            try:
                text = UserSettings.model_validate_json(path.read_text()).model_dump_json()
            except (OSError, ValidationError) as exc:
                fields = {"path": str(path), "err": str(exc)[:200]}
                log.warning("old settings file not imported", extra={"fields": fields})
                continue
            self.stored.settings[user] = text
            self.db.put_settings(user, text)
            taken += 1
        log.warning(
            "settings_dir is no longer used: settings live in state_dir; remove it from the config",
            extra={"fields": {"settings_dir": str(folder), "imported": taken}},
        )

    def saver(self, user: str) -> Callable[[Navigator], None] | None:
        return None if self.db is None else SessionSaver(self.db, user)

    def save_settings(self, user: str, settings: UserSettings) -> None:
        if self.db is not None:
            self.db.put_settings(user, settings.model_dump_json())

    def stored_settings(self, user: str) -> UserSettings | None:
        text = self.stored.settings.get(user)
        if text is None:
            return None
        try:
            return UserSettings.model_validate_json(text)
        except ValidationError as exc:
            fields = {"user": user, "err": str(exc)}
            log.warning("stored settings ignored", extra={"fields": fields})
            return None

    def forget(self, user: str) -> None:
        if self.db is not None:
            self.db.forget(user)

    def users(self) -> list[str]:
        """Users with a session or a map to restore, in name order."""
        return sorted(set(self.stored.sessions) | set(self.stored.maps))

    def restore(self, runner: UserRunner, too_big: Callable[[int], str | None]) -> None:
        """Give ``runner``'s navigator its stored map, goal and pause (on the loop thread,
        before the runner's first step), tell the user to wait, and ask for the source's map."""
        user, nav = runner.user, runner.navigator
        stored_map = self.stored.maps.pop(user, None)
        session = self.stored.sessions.pop(user, None)
        fields: dict[str, object] = {"user": user}
        if stored_map is not None:
            snap = stored_map.snapshot
            why = too_big(snap.height * snap.width)
            if why is None:
                attempts = round(RESTORE_WAIT_S / RESTORE_RETRY_S)
                nav.maps.restore(snap.array(), stored_map.seq, stored_map.epoch, attempts)
                fields.update(seq=stored_map.seq, epoch=stored_map.epoch)
            else:
                log.warning("stored map skipped", extra={"fields": {"user": user, "err": why}})
        if session is not None:
            fields["was"] = session.state
            nav.controls.paused = session.paused
            if session.goal is not None:
                try:
                    nav.goal = codec.decode(Goal, session.goal.encode())
                    fields["goal"] = session.goal
                except codec.DecodeError as exc:
                    log.warning(
                        "stored goal skipped", extra={"fields": {"user": user, "err": exc.reason}}
                    )
        now = time.monotonic()
        if nav.goal is not None:  # one being guided waits; one who was not stays quiet
            _announce(runner)
            self._announce[user] = (now + RESTORE_RETRY_S, now + ANNOUNCE_S)
        if nav.maps.restored:
            runner.resync()
            self._retry_at[user] = now + RESTORE_RETRY_S
        log.info("session restored", extra={"fields": fields})

    def tick(self, runners: dict[str, UserRunner]) -> None:
        """On the loop's tick: ask again for the maps restored and not yet confirmed (once a
        ``RESTORE_RETRY_S``; the runner sends no second query while one is out), and say
        ``restored`` again to those still without a fresh pose."""
        now = time.monotonic()
        for user, (at, until) in list(self._announce.items()):
            runner = runners.get(user)
            if runner is None or runner.navigator.pose is not None or now > until:
                del self._announce[user]
            elif now >= at:
                _announce(runner)
                self._announce[user] = (now + RESTORE_RETRY_S, until)
        for user, at in list(self._retry_at.items()):
            runner = runners.get(user)
            if runner is None or not runner.navigator.maps.restored:
                del self._retry_at[user]  # confirmed, given up on, or forgotten
            elif now >= at:
                runner.resync()
                self._retry_at[user] = now + RESTORE_RETRY_S

    def close(self) -> None:
        if self.db is not None:
            self.db.close()


def _announce(runner: UserRunner) -> None:
    """WAIT and a ``restored`` status: not a refused message, so not counted."""
    why = "the daemon restarted; waiting for a fresh pose"
    runner.reject(StatusCode.RESTORED, why, counted=False)
