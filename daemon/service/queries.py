"""The daemon's answers to queries on the loop thread: health, users' statuses and settings,
and map snapshots (those are read by the user's worker between steps and answered from there).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable

import zenoh

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Health
from protocol.settings import ZenohSettings
from protocol.topics import Topic

from .admission import Admission
from .config import DaemonConfig
from .runner import UserRunner

log = logging.getLogger("guidebelt.daemon")


class QueryAnswers:
    def __init__(self, runners: dict[str, UserRunner], health: Callable[[], Health]) -> None:
        self.runners = runners
        self.health = health

    def on_query(self, topic: Topic, query: zenoh.Query) -> None:
        try:
            if topic is T.HEALTH:
                wire.reply(query, T.HEALTH, None, codec.encode(self.health()))
            elif topic is T.STATUS_QUERY:
                self._reply_statuses(query)
            elif topic is T.SETTINGS_QUERY:
                self._reply_settings(query)
            else:
                self._reply_snapshots(query)
                return  # those replies come later, from the workers
        except zenoh.ZError as exc:
            log.warning(
                "query reply failed", extra={"fields": {"topic": topic.name, "err": str(exc)}}
            )
        query.drop()

    def _matching_users(self, query: zenoh.Query, topic: Topic) -> list[str]:
        asked = query.key_expr
        return [u for u in self.runners if asked.intersects(zenoh.KeyExpr(topic.key(u)))]

    def _reply_statuses(self, query: zenoh.Query) -> None:
        for user in self._matching_users(query, T.STATUS_QUERY):
            runner = self.runners[user]
            payload = runner.last_status or codec.encode(runner.navigator.status(time.time()))
            wire.reply(query, T.STATUS_QUERY, user, payload)

    def _reply_settings(self, query: zenoh.Query) -> None:
        for user in self._matching_users(query, T.SETTINGS_QUERY):
            settings = self.runners[user].settings(time.time())
            wire.reply(query, T.SETTINGS_QUERY, user, codec.encode(settings))

    def _reply_snapshots(self, query: zenoh.Query) -> None:
        users = self._matching_users(query, T.MAP_SNAPSHOT)
        if not users:
            query.drop()
            return
        # One query, one user: wildcard snapshot queries are answered for the first match.
        runner = self.runners[users[0]]
        task = asyncio.get_running_loop().create_task(
            runner.reply_snapshot(query, T.MAP_SNAPSHOT.key(users[0]))
        )
        task.add_done_callback(lambda t: t.exception() if not t.cancelled() else None)


def daemon_health(
    config: DaemonConfig,
    started: float,
    runners: dict[str, UserRunner],
    admission: Admission,
    unrouted: int,
    suppressed: int,
) -> Health:
    """The daemon's answer on ``health``; ``unrouted``: messages refused before reaching a
    user, ``suppressed``: log lines the daemon itself held back."""
    return Health(
        daemon_id=config.daemon_id,
        uptime_s=time.time() - started,
        users=sorted(runners),
        backend=config.backend,
        rejected=unrouted + sum(r.navigator.rejected for r in runners.values()),
        rejected_by_code=rejections_by_code(unrouted, runners),
        log_lines_suppressed=suppressed
        + sum(r.navigator.log_limit.suppressed_total for r in runners.values()),
        overloaded=admission.shed,
        lag_p95_ms=round(admission.last_p95_ms, 3),
        stamp=time.time(),
    )


def rejections_by_code(unrouted: int, runners: dict[str, UserRunner]) -> dict[str, int]:
    """Health's count of refused messages by status code, every user's together; ``unrouted``:
    those whose key named no user the daemon could route to."""
    totals: dict[str, int] = {"unrouted": unrouted} if unrouted else {}
    for runner in runners.values():
        for code, n in runner.navigator.rejected_by_code.items():
            totals[str(code)] = totals.get(str(code), 0) + n
    return totals


def say_who_may_connect(z: ZenohSettings) -> None:
    """One line at start on who can reach the daemon: the first thing to read when a phone
    cannot connect, or when the daemon is exposed more than meant."""
    where = {"listen": ",".join(z.listen) or "-", "connect": ",".join(z.connect) or "-"}
    if z.tls is None and z.loopback_only():
        log.info("no TLS: loopback only", extra={"fields": where})
    elif z.tls is None:
        log.warning(
            "no TLS and endpoints beyond this host: whoever reaches them can steer any user",
            extra={"fields": where},
        )
    elif z.access is None:
        log.warning(
            "mutual TLS without access control: any certified node may steer any user",
            extra={"fields": where},
        )
    else:
        fields = {**where, "users": len(z.access.users), "services": len(z.access.services)}
        log.info("mutual TLS, access control by certificate name", extra={"fields": fields})
