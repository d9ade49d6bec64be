"""The log-distance path-loss model: RSSI from distance (simulation) and back (ranging).

Chen et al. range a UHF tag from its RSSI with ``d = 10^((|RSSI| − A)/(10 n))``, A = 45.8 dB
(−45.8 dBm at 1 m) and n = 3. The simulation draws reads from the same model plus
log-normal shadowing — a fixed offset per tag (mounting, orientation) and a fresh one per
read (multipath, the body) — and read dropouts, so the median of n reads removes only
the fast part, as on a real reader.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .protocol import RSSI_MAX_DBM, RSSI_MIN_DBM, Read

A_DB = 45.8
"""|RSSI| at 1 m, dB."""
N_PATH = 3.0
"""Path-loss exponent."""
NEAR_FIELD_M = 0.1
"""Closer than this the log-distance law no longer holds; the RSSI saturates."""


def rssi_at(d_m: np.ndarray | float, a: float = A_DB, n: float = N_PATH) -> np.ndarray:
    """Mean RSSI (dBm, negative) at distance ``d_m``."""
    d = np.maximum(np.asarray(d_m, dtype=float), NEAR_FIELD_M)
    return -(a + 10.0 * n * np.log10(d))


def distance_from_rssi(rssi: np.ndarray | float, a: float = A_DB, n: float = N_PATH) -> np.ndarray:
    """The paper's inverse: ``d = 10^((|RSSI| − A)/(10 n))`` metres."""
    return 10.0 ** ((np.abs(np.asarray(rssi, dtype=float)) - a) / (10.0 * n))


@dataclass
class ReadModel:
    """Draws what the reader reports at a position: UHF reads with noise, LF reads in range.

    ``uhf_xy``/``lf_xy`` are (k, 2) tag positions in metres, ``uhf_ids``/``lf_ids`` their ids.
    """

    uhf_ids: list[str]
    uhf_xy: np.ndarray
    lf_ids: list[str]
    lf_xy: np.ndarray
    sigma_read_db: float = 3.0
    """Fast shadowing, fresh on every read."""
    sigma_tag_db: float = 1.0
    """Slow shadowing, one fixed offset per tag (its mounting): the median cannot remove it."""
    dropout: float = 0.2
    """Chance that a tag in range is missed in one inventory round."""
    uhf_range_m: float = 5.0
    lf_range_m: float = 0.10
    lf_rssi_dbm: float = -40.0
    seed: int = 0
    rng: np.random.Generator = field(init=False, repr=False)
    tag_offset_db: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.uhf_xy = np.asarray(self.uhf_xy, dtype=float).reshape(-1, 2)
        self.lf_xy = np.asarray(self.lf_xy, dtype=float).reshape(-1, 2)
        self.rng = np.random.default_rng(self.seed)
        self.tag_offset_db = self.rng.normal(0.0, self.sigma_tag_db, len(self.uhf_ids))

    @classmethod
    def for_tags(cls, tag_map, **kw) -> ReadModel:  # tag_map: tags.TagMap
        return cls(
            uhf_ids=list(tag_map.uhf_ids),
            uhf_xy=tag_map.uhf_xy,
            lf_ids=list(tag_map.lf_ids),
            lf_xy=tag_map.lf_xy,
            lf_range_m=tag_map.lf_range_m,
            **kw,
        )

    def round(
        self, x: float, y: float, t: float, reader_ms: int = 0, uhf: bool = True
    ) -> list[Read]:
        """One inventory round with the antenna at (x, y): every read the reader reports.

        ``uhf=False``: the LF floor antenna only (it polls faster than a UHF inventory).
        """
        reads: list[Read] = []
        p = np.array([x, y])
        if uhf and len(self.uhf_ids):
            d = np.hypot(*(self.uhf_xy - p).T)
            seen = (d <= self.uhf_range_m) & (self.rng.random(len(d)) >= self.dropout)
            idx = np.flatnonzero(seen)
            noise = self.rng.normal(0.0, self.sigma_read_db, idx.size)
            rssi = rssi_at(d[idx]) + self.tag_offset_db[idx] + noise
            for i, r in zip(idx, rssi, strict=True):
                r = round(float(r), 1)  # the line protocol carries one decimal
                if RSSI_MIN_DBM <= r <= RSSI_MAX_DBM:  # else the reader cannot report it
                    reads.append(Read(self.uhf_ids[i], r, t, reader_ms))
        if len(self.lf_ids):
            d = np.hypot(*(self.lf_xy - p).T)
            for i in np.flatnonzero(d <= self.lf_range_m):
                reads.append(Read(self.lf_ids[i], self.lf_rssi_dbm, t, reader_ms))
        return reads
