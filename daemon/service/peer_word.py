"""What one worker's admission hears of the other workers' (``admission.py``): the worst lag,
the latest readmission and lag-driven shedding, and how long the longest-waiting of them has
waited for its turn, relayed by the parent (``workers.peer_view``) as seconds before the
relay and turned here into times on the hearing worker's clock."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class PeerWord:
    heard: float
    lag_ms: float
    """The worst lag p95 among the other workers."""
    back_at: float
    """The latest readmission among them (-inf: none)."""
    shed_at: float
    """The latest lag-driven shedding among them (-inf: none)."""
    waiting_since: float | None
    """Since when the longest-waiting of them with users waiting has waited for its turn (its
    last readmission, or its oldest shedding if it never readmitted); None: nobody waits."""

    @classmethod
    def heard_now(cls, view: Mapping[str, float | None], now: float) -> PeerWord:
        def at(key: str) -> float:
            ago = view.get(key)
            return -math.inf if ago is None else now - float(ago)

        waited = view.get("waiting_s")
        since = None if waited is None else now - float(waited)
        lag = float(view.get("lag_p95_ms") or 0.0)
        return cls(now, lag, at("readmitted_s_ago"), at("shed_s_ago"), since)


def said_to_peers(
    lag_ms: float, back_at: float, shed_at: float, waiting_since: float | None, now: float
) -> dict[str, float | None]:
    """A worker's word for the others (``PeerWord``'s fields as seconds before ``now``)."""

    def ago(t: float | None) -> float | None:
        return None if t is None or t == -math.inf else round(now - t, 3)

    return {
        "lag_p95_ms": round(lag_ms, 1), "readmitted_s_ago": ago(back_at),
        "shed_s_ago": ago(shed_at), "waiting_s": ago(waiting_since),
    }  # fmt: skip
