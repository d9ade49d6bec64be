"""The load generator's side of ``guidebelt load``: the wearers it plays and what it hears back.

It shares the dev VM's two cores with the daemon it measures, so its own CPU is taken from the
daemon's: at 50 users it took ~0.31 of a core (its Python ~0.15) while polling every user each
millisecond and building every pose and delta through pydantic. Now one heap of due sends wakes
it for the next send only, a pose is the bytes of one encoded pose around its stamp, and a delta
is ``codec.delta_bytes`` of cells it made itself (the daemon checks both on arrival as any).
"""

from __future__ import annotations

import heapq
import json
import re
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import zenoh
from zenoh.handlers import Callback, RingChannel

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Goal, GoalCell, MapDelta, MapSnapshot, NavStatus, Pose

_MAP_SEQ = re.compile(rb'"map_seq":\s*(-?\d+)')
_POSE, _DELTA = 0, 1


@dataclass
class LoadSpec:
    users: int = 50
    grid: int = 200
    pose_hz: float = 20.0
    delta_hz: float = 10.0
    seconds: float = 30.0
    warmup_s: float = 5.0
    """Deltas sent before this are not measured: the daemon is still starting sessions."""
    blob: int = 3
    seed: int = 0
    join_hz: float = 20.0
    """Users who start walking per second: a venue's wearers do not all arrive at once."""


@dataclass
class UserTrace:
    sends: dict[int, int] = field(default_factory=dict)
    """delta seq → send time (perf_counter_ns)."""
    belts: list[tuple[int, int]] = field(default_factory=list)
    """(arrival ns, map_seq) of each belt pattern: the map version the pattern was decided on."""
    codes: Counter = field(default_factory=Counter)
    """Status codes heard after the warm-up."""
    first_measured: int = 1 << 62


def _blob(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """Flat cells of a size × size obstacle somewhere on the straight way up the middle, row
    by row (the order ``np.mgrid`` gave, which cost more than the rest of a delta)."""
    r = int(rng.integers(n // 5, 4 * n // 5))
    c = int(rng.integers(n // 2 - n // 10, n // 2 + n // 10))
    return np.array([(r + i) * n + c + j for i in range(size) for j in range(size)], np.int64)


def _pose_template(x: float, y: float) -> tuple[bytes, bytes]:
    """The bytes of an encoded pose at (x, y) before and after its stamp: a load user stands
    still, so only the stamp changes (the stamp's JSON goes between them)."""
    mark = 1234.5
    text = codec.encode(Pose(x=x, y=y, heading=1.57, stamp=mark))
    head, tail = text.split(json.dumps(mark).encode())
    return head, tail


class LoadGenerator:
    """Publishes the users' poses and deltas on ``session`` and records what comes back."""

    def __init__(self, session: zenoh.Session, spec: LoadSpec) -> None:
        self.session, self.spec = session, spec
        self.names = [f"load{i:03d}" for i in range(spec.users)]
        self.traces = {u: UserTrace() for u in self.names}
        self._lock = threading.Lock()
        self._measuring_from = 1 << 62
        self._measuring_until = 1 << 62
        self._subs = [
            wire.declare_subscriber(session, T.BELT, self._sink(self._on_belt)),
            wire.declare_subscriber(session, T.STATUS, self._sink(self._on_status)),
            # The path is not read (a pattern names its map now), but a path listener is what
            # makes the daemon put every step's pattern, not only those that differ from the
            # last (the runner's ``paired``), and build the path as a viewer would have it.
            # A ring of one in zenoh's own code: no path ever enters this process's Python.
            wire.declare_subscriber(session, T.PATH, RingChannel(1)),
        ]
        self._maps: dict[str, tuple[int, np.ndarray]] = {}
        """Each user's map as published (last seq, occupancy): the snapshot a daemon that
        skipped deltas (a user it shed) asks for when it guides the user again."""
        self._lock_maps = threading.Lock()
        self._subs.append(
            wire.declare_queryable(session, T.MAP_SOURCE, Callback(self._on_source, indirect=False))
        )
        self._pose_pubs = {u: wire.declare_publisher(session, T.POSE, u) for u in self.names}
        self._delta_pubs = {u: wire.declare_publisher(session, T.MAP_DELTA, u) for u in self.names}

    def _sink(self, handle: Callable[[str, int, bytes], None]) -> Callback:
        def on_sample(sample: zenoh.Sample) -> None:
            t = time.perf_counter_ns()
            key = str(sample.key_expr)
            user = key.split("/")[1]
            if user in self.traces:
                handle(user, t, sample.payload.to_bytes())

        return Callback(on_sample, indirect=False)

    def _on_belt(self, user: str, t: int, payload: bytes) -> None:
        m = _MAP_SEQ.search(payload)  # a full decode per pattern would load this process
        if m is not None:
            self.traces[user].belts.append((t, int(m.group(1))))

    def _on_status(self, user: str, t: int, payload: bytes) -> None:
        # Until shortly after the last pose: then poses stop and stale_pose is the truth.
        if self._measuring_from <= t <= self._measuring_until:
            status = codec.decode(NavStatus, payload)
            with self._lock:
                self.traces[user].codes[str(status.code) or status.state] += 1

    def _on_source(self, query: zenoh.Query) -> None:
        user = str(query.key_expr).split("/")[1]
        with self._lock_maps:
            seq, occ = self._maps.get(user, (-1, None))
            occ = None if occ is None else occ.copy()
        if occ is not None:
            snap = MapSnapshot.from_array(seq, occ, time.time())
            wire.reply(query, T.MAP_SOURCE, user, codec.encode(snap))
        query.drop()

    def _published(self, user: str, seq: int, cells: np.ndarray, values: np.ndarray) -> None:
        with self._lock_maps:
            occ = self._maps[user][1]
            occ.reshape(-1)[cells] = values
            self._maps[user] = (seq, occ)

    def schedule(self, start: float) -> list[tuple[float, int, int]]:
        """The first send of each kind for each user (due time, kind, user index), as a heap:
        users join ``join_hz`` apart, each one's sends offset within the period."""
        spec = self.spec
        due = []
        for i in range(spec.users):
            join, offset = start + i / spec.join_hz, i / spec.users
            due += [
                (join + offset / spec.pose_hz, _POSE, i),
                (join + offset / spec.delta_hz, _DELTA, i),
            ]
        heapq.heapify(due)
        return due

    def run(self) -> None:
        spec, n = self.spec, self.spec.grid
        cell_m = 10.0 / n
        walls = np.flatnonzero(np.pad(np.zeros((n - 2, n - 2), bool), 1, constant_values=True))
        x, y = (n // 2 + 0.5) * cell_m, (n // 10 + 0.5) * cell_m
        goal = codec.encode(Goal(target=GoalCell(row=n // 10, col=n // 2), stamp=time.time()))
        for u in self.names:
            first = MapDelta.from_arrays(0, (n, n), walls, np.ones(walls.size), time.time())
            self._maps[u] = (0, np.zeros((n, n), np.uint8))
            self._published(u, 0, walls, np.ones(walls.size, np.uint8))
            self._delta_pubs[u].put(codec.encode(first))
            wire.put(self.session, T.GOAL, u, goal)
        rngs = [np.random.default_rng([spec.seed, i]) for i in range(spec.users)]
        placed: list[np.ndarray | None] = [None] * spec.users
        seq = [0] * spec.users
        pose_head, pose_tail = _pose_template(x, y)
        area = spec.blob * spec.blob
        ones, zeros = np.ones(area, np.uint8), np.zeros(area, np.uint8)
        values_bytes = (ones.tobytes(), zeros.tobytes())
        pose_pubs = [self._pose_pubs[u] for u in self.names]
        delta_pubs = [self._delta_pubs[u] for u in self.names]
        traces = [self.traces[u] for u in self.names]
        periods = (1.0 / spec.pose_hz, 1.0 / spec.delta_hz)
        start = time.perf_counter()
        due = self.schedule(start)
        ramp_s = spec.users / spec.join_hz
        self._measuring_from = time.perf_counter_ns() + int((ramp_s + spec.warmup_s) * 1e9)
        end = start + ramp_s + spec.warmup_s + spec.seconds
        while (now := time.perf_counter()) < end:
            while due[0][0] <= now:
                when, kind, i = due[0]
                heapq.heapreplace(due, (when + periods[kind], kind, i))
                if kind == _POSE:
                    stamp = repr(time.time()).encode()
                    pose_pubs[i].put(b"".join((pose_head, stamp, pose_tail)))
                    continue
                seq[i] += 1
                blob = placed[i]
                if blob is None:  # every delta drops or lifts the obstacle: the path changes
                    blob = placed[i] = _blob(rngs[i], n, spec.blob)
                    values, raw = ones, values_bytes[0]
                else:
                    values, raw, placed[i] = zeros, values_bytes[1], None
                data = codec.delta_bytes(
                    seq[i], n, n, time.time(), blob.astype("<u4").tobytes(), raw
                )
                self._published(self.names[i], seq[i], blob, values)
                sent = time.perf_counter_ns()
                delta_pubs[i].put(data)
                trace = traces[i]
                trace.sends[seq[i]] = sent
                if sent >= self._measuring_from:
                    trace.first_measured = min(trace.first_measured, seq[i])
            time.sleep(max(0.0, min(due[0][0], end) - time.perf_counter()))
        self._measuring_until = time.perf_counter_ns() + int(0.5e9)
        time.sleep(1.0)  # the last answers

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub in (*self._pose_pubs.values(), *self._delta_pubs.values()):
            pub.undeclare()
