"""Simulated users walking through a running daemon, for whoever watches or records them.

The daemon's peers do not route between other peers (gossip is off on loopback), so a
watcher that wants the world's own messages (poses, map deltas, goals) as well as the
daemon's listens on its own port and the world connects to it as well as to the daemon,
as it would to a router in a deployment: ``observers`` names those ports.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import zenoh

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell
from protocol.session import ZenohSettings, open_session

from .courtyard import make_courtyard
from .node import SimNode, SimResult


def endpoints(*ports: int) -> list[str]:
    return [f"tcp/127.0.0.1:{p}" for p in ports]


@dataclass
class LiveWalks:
    """``users`` walking the courtyard at ``pace_s`` a step, each on its own session and
    thread; ``rounds`` walks each (0: until ``stop()``)."""

    daemon_port: int
    users: list[str]
    observers: list[int] = field(default_factory=list)
    grid: int = 100
    unknown: float = 0.4
    seed: int = 0
    pace_s: float = 0.1
    walker: str = "belt"
    rounds: int = 1
    timeout_s: float = 120.0
    results: dict[str, list[SimResult]] = field(default_factory=dict)
    _stop: threading.Event = field(default_factory=threading.Event)
    _threads: list[threading.Thread] = field(default_factory=list)

    def start(self) -> LiveWalks:
        for i, user in enumerate(self.users):
            self.results[user] = []
            th = threading.Thread(target=self._walk, args=(user, i), name=f"walk-{user}")
            th.start()
            self._threads.append(th)
        return self

    def _walk(self, user: str, index: int) -> None:
        settings = ZenohSettings(connect=endpoints(self.daemon_port, *self.observers))
        session = open_session(settings)
        try:
            done = 0
            while not self._stop.is_set() and (self.rounds == 0 or done < self.rounds):
                self.results[user].append(self._one_walk(session, user, index))
                done += 1
        finally:
            session.close()

    def _one_walk(self, session: zenoh.Session, user: str, index: int) -> SimResult:
        # Each user its own courtyard (seed + index), so four users are four different walks.
        scenario = make_courtyard(grid=self.grid, unknown=self.unknown, seed=self.seed + index)
        node = SimNode(session, user, scenario, walker=self.walker, step_period_s=self.pace_s)
        box: dict[str, SimResult] = {}
        th = threading.Thread(
            target=lambda: box.setdefault("r", node.run(self._stop, timeout_s=self.timeout_s))
        )
        th.start()
        time.sleep(0.3)  # the node's first map and pose reach the daemon before the goal
        goal = Goal(target=GoalCell(row=scenario.goal[0], col=scenario.goal[1]), stamp=time.time())
        wire.put(session, T.GOAL, user, codec.encode(goal))
        th.join()
        return box["r"]

    def stop(self) -> None:
        self._stop.set()

    def join(self, timeout_s: float | None = None) -> bool:
        """Wait for every walk; True when all ended in time."""
        end = None if timeout_s is None else time.monotonic() + timeout_s
        for th in self._threads:
            th.join(None if end is None else max(0.0, end - time.monotonic()))
        return not any(th.is_alive() for th in self._threads)

    def __enter__(self) -> LiveWalks:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
        self.join(10.0)
