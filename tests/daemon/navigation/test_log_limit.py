"""Bad input is logged at a bounded rate, counted whole, and the counts reach the health."""

from __future__ import annotations

import logging
import time

from daemon.navigation import Inbox, Navigator, NavigatorSettings
from daemon.navigation.log_limit import LogLimiter
from daemon.navigation.outcomes import Rejection
from protocol.messages import StatusCode


def test_a_burst_then_one_a_second_and_the_held_lines_are_told() -> None:
    limit = LogLimiter(burst=3, per_s=1.0)
    let = [limit.allow("bad", 0.0) for _ in range(10)]
    assert let == [0, 0, 0] + [None] * 7 and limit.suppressed_total == 7
    assert limit.allow("bad", 0.5) is None  # half a token back
    assert limit.allow("bad", 1.6) == 8  # a token: this line says 8 were held back
    assert limit.allow("other", 1.6) == 0  # every key has its own bucket


def test_a_flood_of_bad_input_is_counted_whole_and_logged_a_few_times(caplog) -> None:
    nav = Navigator("u", NavigatorSettings(backend="cpu"))
    with caplog.at_level(logging.INFO, logger="guidebelt.navigation"):
        for _ in range(1000):
            rej = Rejection(StatusCode.MALFORMED, "not a pose")
            nav.step(Inbox(rejections=[rej]), time.time())
    lines = [r for r in caplog.records if r.getMessage() == "rejected"]
    assert nav.rejected == 1000 and nav.rejected_by_code == {StatusCode.MALFORMED: 1000}
    assert 5 <= len(lines) <= 10  # the burst, and one a second while the loop ran
    assert nav.log_limit.suppressed_total == 1000 - len(lines)


def test_the_health_carries_the_counts_by_code() -> None:
    from daemon.service.config import DaemonConfig
    from daemon.service.daemon import Daemon

    d = Daemon(DaemonConfig(backend="cpu"))
    d.rejected_unrouted = 2
    health = d.health()
    assert health.rejected == 2 and health.rejected_by_code == {"unrouted": 2}
    assert health.log_lines_suppressed == 0
