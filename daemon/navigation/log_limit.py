"""Bad input is logged at a bounded rate: a peer sending garbage a thousand times a second must
not fill the journal (or the disk) nor slow the daemon down, yet every refusal is counted.

A token bucket per key (a user's status code, or a topic): ``burst`` lines at once, then one
every ``1 / per_s`` seconds. A line let through after some were held back says how many
(``suppressed``), so the journal still tells how much bad input there was; the daemon's health
carries the totals.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field


@dataclass
class LogLimiter:
    burst: float = 5.0
    per_s: float = 1.0
    suppressed_total: int = 0
    """Lines held back since the start, all keys."""
    _tokens: dict[str, float] = field(default_factory=dict)
    _at: dict[str, float] = field(default_factory=dict)
    _held: dict[str, int] = field(default_factory=dict)

    def allow(self, key: str, now: float) -> int | None:
        """None: hold this line back. Else the number of lines of ``key`` held back since the
        last one let through (0 mostly), for the line to say."""
        tokens = min(self.burst, self._tokens.get(key, self.burst)
                     + (now - self._at.get(key, now)) * self.per_s)  # fmt: skip
        self._at[key] = now
        if tokens < 1.0:
            self._tokens[key] = tokens
            self._held[key] = self._held.get(key, 0) + 1
            self.suppressed_total += 1
            return None
        self._tokens[key] = tokens - 1.0
        return self._held.pop(key, 0)

    def refusal(
        self, log: logging.Logger, user: str, code: str, reason: str, counted: bool
    ) -> None:
        """One refusal of ``user``'s as a log line, unless its code's bucket is empty: a refused
        message at WARNING ("rejected"), a condition (no path, shutdown) at INFO."""
        held = self.allow(code, time.monotonic())
        if held is None:
            return
        fields: dict[str, object] = {"user": user, "code": code, "reason": reason}
        if held:
            fields["suppressed"] = held  # lines of this code held back since the last
        level = logging.WARNING if counted else logging.INFO
        log.log(level, "rejected" if counted else code, extra={"fields": fields})
