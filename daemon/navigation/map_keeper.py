"""One user's map as the deltas and snapshots describe it, in sequence, inflated.

Deltas are applied only in sequence. A gap (or a delta of another shape) means the map is out of
date: the keeper asks for a snapshot, buffers what comes meanwhile and replays it on top of the
snapshot.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.grid import UNKNOWN
from daemon.planning.inflation import InflatedMap
from protocol.messages import MapDelta, MapSnapshot, StatusCode

from .outcomes import Rejection

log = logging.getLogger("guidebelt.navigation")

MAX_BUFFERED_DELTAS = 256
"""Deltas kept while a snapshot is on its way; more means the snapshot is hopeless."""


@dataclass
class MapUpdate:
    """What taking one step's map messages did."""

    rejections: list[Rejection] = field(default_factory=list)
    want_snapshot: bool = False
    new_map: bool = False
    """The map was replaced (first delta or a snapshot): plan from scratch."""
    flipped: np.ndarray | None = None
    """Flat cells whose blocked state flipped, and their new state (``blocked_now``)."""
    blocked_now: np.ndarray | None = None


class MapKeeper:
    def __init__(self, radius_cells: int) -> None:
        self.radius_cells = radius_cells
        self.map: InflatedMap | None = None
        self.seq = -1
        self.resyncing = False
        """A snapshot has been asked for and the deltas that come meanwhile are buffered."""
        self.stale = False
        """Deltas are known to be missing: from a gap or a refused delta until a snapshot is
        applied (a failed snapshot leaves the map stale; the next delta asks again)."""
        self._buffered: dict[int, MapDelta] = {}

    def snapshot_failed(self) -> None:
        """No snapshot came: let the next delta notice the gap again and ask once more."""
        self.resyncing = False
        self._buffered.clear()

    def take_snapshot(self, snap: MapSnapshot, user: str) -> MapUpdate:
        self.map = InflatedMap(snap.array(), self.radius_cells)
        self.seq = snap.seq
        self.resyncing = self.stale = False
        buffered = sorted(self._buffered.values(), key=lambda d: d.seq)
        self._buffered.clear()
        log.info(
            "map resynchronised",
            extra={"fields": {"user": user, "seq": snap.seq, "replay": len(buffered)}},
        )
        update = self.take_deltas(buffered) if buffered else MapUpdate()
        update.new_map = True
        return update

    def take_deltas(self, deltas: list[MapDelta]) -> MapUpdate:
        update = MapUpdate()
        cells: list[np.ndarray] = []
        values: list[np.ndarray] = []
        for d in deltas:
            shape = (d.height, d.width)
            if self.map is None and d.seq == 0 and not self.resyncing:
                self.map = InflatedMap(np.full(shape, UNKNOWN, np.uint8), self.radius_cells)
                update.new_map = True
            elif self.map is None:
                self._gap(f"first delta seen is {d.seq}, not 0", d, update)
                continue
            if shape != self.map.shape:
                why = f"delta for {shape}, map is {self.map.shape}"
                update.rejections.append(Rejection(StatusCode.SHAPE_MISMATCH, why))
                update.want_snapshot = self.resyncing = self.stale = True
                continue
            if self.resyncing:
                self._buffer(d)
            elif d.seq <= self.seq:
                continue  # already in the map (replayed, or older than a snapshot)
            elif d.seq != self.seq + 1:
                self._gap(f"expected delta {self.seq + 1}, got {d.seq}", d, update)
            else:
                cells.append(d.cell_array())
                values.append(d.value_array())
                self.seq = d.seq
        if cells:
            update.flipped, update.blocked_now = self.map.apply(
                np.concatenate(cells), np.concatenate(values)
            )
        return update

    def snapshot(self, stamp: float) -> MapSnapshot | None:
        if self.map is None:
            return None
        return MapSnapshot.from_array(max(self.seq, 0), self.map.occupancy, stamp)

    def _gap(self, reason: str, d: MapDelta, update: MapUpdate) -> None:
        if not self.resyncing:
            why = reason + "; asking for a snapshot"
            update.rejections.append(Rejection(StatusCode.SEQUENCE_GAP, why))
        self.resyncing = self.stale = True
        update.want_snapshot = True
        self._buffer(d)

    def _buffer(self, d: MapDelta) -> None:
        if len(self._buffered) < MAX_BUFFERED_DELTAS:
            self._buffered[d.seq] = d
