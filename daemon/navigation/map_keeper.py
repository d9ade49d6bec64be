"""One user's map as the deltas and snapshots describe it, in sequence, inflated.

Deltas are applied only in sequence. A gap (or a delta of another shape) means the map is out of
date: the keeper asks for a snapshot, buffers what comes meanwhile and replays it on top of the
snapshot.

Sequences are per epoch: a map source picks a new epoch each time it starts and counts from 0
again. A delta (or snapshot) of an epoch the keeper has not seen means the source restarted: the
map is out of date as for a gap (the user waits) until the new epoch's snapshot replaces it,
instead of every delta up to the old sequence being taken for one already applied. The epochs
left behind are remembered (the last ``RETIRED_EPOCHS``), and what still comes from them is
refused with ``old_epoch``: a source that did not really stop must not overwrite the new one.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.grid import UNKNOWN
from daemon.planning.inflation import InflatedMap
from protocol.messages import MapDelta, MapSnapshot, StatusCode

from .outcomes import Rejection

log = logging.getLogger("guidebelt.navigation")

MAX_BUFFERED_DELTAS = 256
"""Deltas kept while a snapshot is on its way; more means the snapshot is hopeless."""
RETIRED_EPOCHS = 16
"""Epochs left behind that are still refused by name; an older one would count as new again."""


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
    def __init__(self, radius_cells: int, on_cells: Callable[[int], None] | None = None) -> None:
        """``on_cells(cells)``: told the new map's cell count whenever a map replaces the last
        (the daemon's memory budget keeps every user's count so, not by a pass over them)."""
        self.radius_cells = radius_cells
        self.map: InflatedMap | None = None
        self._on_cells = on_cells
        self.seq = -1
        self.resyncing = False
        """A snapshot has been asked for and the deltas that come meanwhile are buffered."""
        self.stale = False
        """Deltas are known to be missing: from a gap or a refused delta until a snapshot is
        applied (a failed snapshot leaves the map stale; the next delta asks again)."""
        self.epoch: int | None = None
        """The map source's epoch that ``seq`` counts in (None: a source without epochs)."""
        self.restored = False
        """The map came from the daemon's own store after a restart and the source has not
        confirmed it yet (``restore``)."""
        self._restore_attempts = 0
        self._retired: deque[int | None] = deque(maxlen=RETIRED_EPOCHS)
        self._buffered: dict[int, MapDelta] = {}

    def restore(
        self, occupancy: np.ndarray, seq: int, epoch: int | None, attempts: int = 1
    ) -> None:
        """Start from the map the daemon stored before it stopped. It may lag what the source
        published (the store writes at a bounded rate, and the source went on while the
        daemon was down), so it stays stale (the user waits) until the source's snapshot
        arrives; after ``attempts`` snapshots that did not come the stored map is taken as it
        is, and the next delta out of sequence asks again, as for any gap."""
        self._new_map(occupancy)
        self.seq, self.epoch = seq, epoch
        self.stale = self.restored = True
        self.resyncing = False
        self._restore_attempts = max(1, attempts)
        self._buffered.clear()

    def snapshot_failed(self) -> None:
        """No snapshot came: let the next delta notice the gap again and ask once more."""
        self.resyncing = False
        self._buffered.clear()
        if self.restored:
            self._restore_attempts -= 1
            if self._restore_attempts <= 0:  # the source is silent: the stored map it is
                self.restored = self.stale = False
                log.warning("stored map used unconfirmed: the map source did not answer")

    def take_snapshot(self, snap: MapSnapshot, user: str) -> MapUpdate:
        update = MapUpdate()
        if not self._same_epoch(snap.epoch, "snapshot", update):
            self.snapshot_failed()  # the next delta asks again
            return update
        self._new_map(snap.array())
        self.seq = snap.seq
        self.resyncing = self.stale = self.restored = False
        buffered = sorted(
            (d for d in self._buffered.values() if d.epoch == self.epoch), key=lambda d: d.seq
        )
        self._buffered.clear()
        log.info(
            "map resynchronised",
            extra={
                "fields": {"user": user, "seq": snap.seq, "epoch": snap.epoch,
                           "replay": len(buffered)}
            },
        )  # fmt: skip
        if buffered:
            replayed = self.take_deltas(buffered)
            replayed.rejections[:0] = update.rejections
            update = replayed
        update.new_map = True
        return update

    def _new_map(self, occupancy: np.ndarray) -> None:
        self.map = InflatedMap(occupancy, self.radius_cells)
        if self._on_cells is not None:
            self._on_cells(occupancy.size)

    def take_deltas(self, deltas: list[MapDelta]) -> MapUpdate:
        update = MapUpdate()
        cells: list[np.ndarray] = []
        values: list[np.ndarray] = []
        for d in deltas:
            if not self._same_epoch(d.epoch, "delta", update):
                continue
            shape = (d.height, d.width)
            if self.map is None and d.seq == 0 and not self.resyncing:
                self._new_map(np.full(shape, UNKNOWN, np.uint8))
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
            elif self.stale:  # the last snapshot never came: ask again
                self._gap("the map is out of date", d, update)
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
        return MapSnapshot.from_array(max(self.seq, 0), self.map.occupancy, stamp, self.epoch)

    def _same_epoch(self, epoch: int | None, what: str, update: MapUpdate) -> bool:
        """Whether a message of ``epoch`` may be taken; a new epoch starts a resync first."""
        if epoch == self.epoch:
            return True
        if epoch in self._retired:
            why = f"{what} of epoch {epoch}, which the map source has left for {self.epoch}"
            update.rejections.append(Rejection(StatusCode.OLD_EPOCH, why))
            return False
        if self.map is None and self.seq < 0 and not self.resyncing:
            self.epoch = epoch  # the first message ever: nothing to resynchronise
            return True
        self._retired.append(self.epoch)
        if epoch in self._retired:  # back to an epoch retired RETIRED_EPOCHS ago
            self._retired.remove(epoch)
        self.epoch, self.seq = epoch, -1
        self._buffered.clear()  # the old epoch's: they never apply now
        if what == "delta":
            why = f"the map source restarted (epoch {epoch}); asking for a snapshot"
            update.rejections.append(Rejection(StatusCode.NEW_EPOCH, why, counted=False))
            self.resyncing = self.stale = True
            update.want_snapshot = True
        return True

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
