"""The mapper as a zenoh node: frames in, ``MapDelta`` and ``Proximity`` out for one user.

It plays the map producer's side of the daemon's contract as ``sim/node.py`` does: deltas
numbered from 0 on ``MAP_DELTA`` (delta 0 carries the map it starts from, the known
obstacles, so the daemon learns the map's shape), never more than ``MAX_DELTA_CELLS`` cells
each, and a ``MAP_SOURCE`` queryable that answers a snapshot of everything published so
far when the daemon has lost the sequence. Per frame it also publishes the frame's nearest
obstacles on ``PROXIMITY``, which the daemon turns into STOP before contact.

A refused frame is counted by reason and logged (rate limited); nothing is published for
it and the map is untouched.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from typing import Any

import numpy as np
import zenoh
from zenoh.handlers import Callback

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import MAX_DELTA_CELLS, MapSnapshot

from .frame import DepthFrame, FrameRejected
from .occupancy_mapper import OCCUPIED, FrameResult, OccupancyMapper

log = logging.getLogger("guidebelt.mapper")


class MapperNode:
    def __init__(self, session: zenoh.Session, user: str, mapper: OccupancyMapper) -> None:
        self.session = session
        self.user = T.check_user(user)
        self.mapper = mapper
        self.seq = -1
        self.published = 0
        self.refused: Counter[str] = Counter()
        self.last: FrameResult | None = None
        self._lock = threading.Lock()
        """The map changes on the feeding thread; the snapshot queryable reads it on zenoh's."""
        self._delta = wire.declare_publisher(session, T.MAP_DELTA, user)
        self._prox = wire.declare_publisher(session, T.PROXIMITY, user)
        self._source = wire.declare_queryable(
            session, T.MAP_SOURCE, Callback(self._on_source, indirect=False), user
        )
        self._logged_at = 0.0

    def start(self, stamp: float | None = None) -> int:
        """Delta 0: the map the mapper starts from (its occupied cells), so the daemon has
        the map's shape at once; a start map too big for one delta is left to a snapshot."""
        stamp = time.time() if stamp is None else stamp
        with self._lock:
            occupied = np.flatnonzero(self.mapper.occupancy == OCCUPIED)
            values = np.full(occupied.size, OCCUPIED, np.uint8)
            if occupied.size <= MAX_DELTA_CELLS:
                deltas = self._deltas(occupied, values, stamp, at_least_one=True)
            else:
                deltas, self.seq = [], 0  # delta 1 comes first: the daemon asks MAP_SOURCE
        for delta in deltas:
            self._delta.put(delta)
        self.published += len(deltas)
        return self.seq

    def feed(self, frame: DepthFrame) -> FrameResult | None:
        """Map one frame and publish what it changed; None (counted) if it was refused."""
        result = self._map_and_publish(frame)
        if result is None:
            return None
        p = result.proximity
        # Packed without the model, as the deltas: the daemon checks it on arrival.
        self._prox.put(codec.proximity_bytes(p.ahead_m, p.nearest_m, p.bearing, frame.stamp,
                                             time.time()))  # fmt: skip
        self.last = result
        # The frame is out: a floor fit it left due runs now, off its path (floor_async).
        self.mapper.fit_pending_floor()
        return result

    def _map_and_publish(self, frame: DepthFrame) -> Any:  # the mapper's own result type
        """The mapper's result for ``frame`` once its map deltas are out; None (counted) if
        the frame was refused, the map then unchanged."""
        try:
            with self._lock:  # the map and its sequence number change together
                result = self.mapper.process(frame)
                deltas = self._deltas(result.cells, result.values, frame.stamp)
        except FrameRejected as exc:
            self.refuse(exc)
            return None
        # Published outside the lock: zenoh's thread may be waiting on it for a snapshot.
        for delta in deltas:
            self._delta.put(delta)
        self.published += len(deltas)
        return result

    def refuse(self, exc: FrameRejected) -> None:
        self.refused[exc.refusal] += 1
        now = time.monotonic()
        if now - self._logged_at > 1.0:
            self._logged_at = now
            log.warning("frame refused", extra={"fields": {"user": self.user,
                        "code": str(exc.refusal), "reason": exc.reason}})  # fmt: skip

    def _deltas(self, cells: np.ndarray, values: np.ndarray, stamp: float,
                at_least_one: bool = False) -> list[bytes]:  # fmt: skip
        """The change as numbered deltas of at most ``MAX_DELTA_CELLS`` cells each, encoded.

        Packed straight from the arrays, not through the ``MapDelta`` model: its checks (the
        cells inside the map, the values known) hold by construction here, the mapper's own
        window cells and occupancy values, and on an H100 host at 30 fps the model with its
        checks was the largest piece of the frame's host Python. The daemon decodes and
        checks every delta as it arrives."""
        h, w = self.mapper.settings.shape
        cells = np.asarray(cells, dtype="<u4")
        values = np.asarray(values, dtype=np.uint8)
        out = []
        for at in range(0, max(cells.size, int(at_least_one)), MAX_DELTA_CELLS):
            self.seq += 1
            part = slice(at, at + MAX_DELTA_CELLS)
            out.append(codec.delta_bytes(self.seq, h, w, stamp, cells[part].tobytes(),
                                         values[part].tobytes()))  # fmt: skip
        return out

    def _on_source(self, query: zenoh.Query) -> None:
        with self._lock:
            snap = MapSnapshot.from_array(max(self.seq, 0), self.mapper.occupancy, time.time())
        wire.reply(query, T.MAP_SOURCE, self.user, codec.encode(snap))
        query.drop()

    def close(self) -> None:
        for ent in (self._delta, self._prox, self._source):
            ent.undeclare()
        if isinstance(self.mapper, OccupancyMapper):  # a bird's-eye mapper has no floor fit
            self.mapper.close()
