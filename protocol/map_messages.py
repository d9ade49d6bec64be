"""The map on the wire: deltas and whole snapshots of a user's occupancy grid.

Binary on the wire (see ``codec.py``): a 400 × 400 map update costs a ``memcpy``, not a JSON
list of numbers. A delta carries its source's epoch, so a restarted mapper is told apart.
"""

from __future__ import annotations

import zlib
from typing import Annotated, Self

import numpy as np
from pydantic import Field, model_validator

from .wire_types import MAX_SIDE, Message, Stamp

MAX_EPOCH = 2**64
"""Epochs are unsigned 64-bit: a random session id, or a start counter, chosen by the source."""

Epoch = Annotated[
    int | None,
    Field(
        default=None,
        ge=0,
        lt=MAX_EPOCH,
        description="the map source's epoch, new each time it starts (None: an older sender)",
    ),
]

MAX_DELTA_CELLS = 65536
"""A delta changing more cells than this is rejected whole; send a snapshot instead."""

OCCUPANCY_VALUES = (0, 1, 2)
"""FREE, OCCUPIED, UNKNOWN — as in ``daemon.planning.grid``."""
_OCCUPANCY_BYTES = bytes(OCCUPANCY_VALUES)


class MapDelta(Message):
    """Changed occupancy cells since delta ``seq - 1``; binary on the wire (``codec.py``).

    ``cells`` holds little-endian ``uint32`` flat indices (``row * width + col``),
    ``values`` one ``uint8`` occupancy per cell. A delta is applied whole or not at all.
    """

    seq: int = Field(ge=0, lt=2**32, description="consecutive per user and epoch, from 0")
    epoch: Epoch = None
    height: int = Field(ge=1, le=MAX_SIDE)
    width: int = Field(ge=1, le=MAX_SIDE)
    stamp: Stamp
    cells: bytes = Field(description="uint32 little-endian flat indices")
    values: bytes = Field(description="uint8 occupancy: 0 free, 1 occupied, 2 unknown")

    @model_validator(mode="after")
    def _check_cells(self) -> Self:
        n = len(self.values)
        if n > MAX_DELTA_CELLS:
            raise ValueError(f"delta of {n} cells exceeds the limit of {MAX_DELTA_CELLS}")
        if len(self.cells) != 4 * n:
            raise ValueError("cells must hold one uint32 per value")
        # The largest index read as stored (no int64 copy) and the values by deleting every
        # allowed byte: a daemon worker checks 250 deltas a second, most of 9 cells, where
        # the copies and the second reduction were a third of a delta's decode.
        if n and int(np.frombuffer(self.cells, "<u4").max()) >= self.height * self.width:
            raise ValueError("cell index outside the map")
        if self.values.translate(None, _OCCUPANCY_BYTES):
            raise ValueError("occupancy value not in {0, 1, 2}")
        return self

    def cell_array(self) -> np.ndarray:
        return np.frombuffer(self.cells, dtype="<u4").astype(np.int64)

    def value_array(self) -> np.ndarray:
        return np.frombuffer(self.values, dtype=np.uint8)

    @classmethod
    def from_arrays(
        cls,
        seq: int,
        shape: tuple[int, int],
        cells: np.ndarray,
        values: np.ndarray,
        stamp: float,
        epoch: int | None = None,
    ) -> MapDelta:
        return cls(
            seq=seq,
            epoch=epoch,
            height=shape[0],
            width=shape[1],
            stamp=stamp,
            cells=np.ascontiguousarray(cells, dtype="<u4").tobytes(),
            values=np.ascontiguousarray(values, dtype=np.uint8).tobytes(),
        )


class MapSnapshot(Message):
    """The whole occupancy map as of delta ``seq``, zlib-compressed ``uint8`` in C order."""

    seq: int = Field(ge=0, lt=2**32, description="the last delta this snapshot includes")
    epoch: Epoch = None
    height: int = Field(ge=1, le=MAX_SIDE)
    width: int = Field(ge=1, le=MAX_SIDE)
    stamp: Stamp
    occupancy: bytes = Field(description="zlib-compressed uint8 occupancy, height * width bytes")

    @classmethod
    def from_array(
        cls, seq: int, occupancy: np.ndarray, stamp: float, epoch: int | None = None
    ) -> MapSnapshot:
        occ = np.ascontiguousarray(occupancy, dtype=np.uint8)
        return cls(
            seq=seq,
            epoch=epoch,
            height=occ.shape[0],
            width=occ.shape[1],
            stamp=stamp,
            occupancy=zlib.compress(occ.tobytes(), level=1),
        )

    def array(self) -> np.ndarray:
        """The occupancy map; refuses anything but exactly height * width valid bytes."""
        n = self.height * self.width
        inflater = zlib.decompressobj()
        try:
            raw = inflater.decompress(self.occupancy, n + 1)  # + 1: detect an oversized body
        except zlib.error as exc:
            raise ValueError(f"snapshot occupancy is not zlib data: {exc}") from exc
        if len(raw) != n or inflater.unconsumed_tail or not inflater.eof:
            raise ValueError(f"snapshot occupancy must inflate to exactly {n} bytes")
        occ = np.frombuffer(raw, dtype=np.uint8).reshape(self.height, self.width)
        if n and int(occ.max()) > max(OCCUPANCY_VALUES):
            raise ValueError("occupancy value not in {0, 1, 2}")
        return occ.copy()
