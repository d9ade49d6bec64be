"""The RFID node: serial reader → localiser → ``Pose`` on zenoh at a fixed rate.

One process per user (one reader on the belt). Poses go to the ``POSE`` topic as the
``protocol.messages.Pose`` JSON the daemon validates; the reader's counters go to
``RFID_STATS`` (``protocol.messages.RfidStats``) once a second. With too few tags in
reach there is no pose: the node publishes nothing and the daemon's staleness check
(> 1 s) stops the guidance, rather than guiding from a stale position.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable

import zenoh

from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import Pose, RfidStats

from .localiser import DEFAULT_METHOD, Estimate, Localiser
from .pose_filter import PoseFilter
from .reader import RfidReader
from .tag_payload import ObstacleBook
from .tags import TagMap

log = logging.getLogger("guidebelt.rfid")


class RfidNode:
    def __init__(
        self,
        session: zenoh.Session,
        user: str,
        tag_map: TagMap,
        port: str,
        *,
        method: str = DEFAULT_METHOD,
        rate_hz: float = 20.0,
        clock: Callable[[], float] = time.time,
        book: ObstacleBook | None = None,
    ) -> None:
        """``book``: where the obstacles the UHF tags carry go as their memory is read
        (``tag_payload``); its ``delta`` is the map they make."""
        if rate_hz < 10.0:
            raise ValueError("the daemon expects poses at 10 Hz or more")
        self.user = T.check_user(user)
        self.clock = clock
        self.period = 1.0 / rate_hz
        # "filter": the pose filter, always a pose with its σ (no pedometer on the wire yet,
        # so its spread grows with time between fixes and the daemon says WAIT past 1 m).
        self.filter = PoseFilter(tag_map) if method == "filter" else None
        self.localiser = Localiser(tag_map, method="lsq" if self.filter else method)
        sink = self.filter.add if self.filter is not None else self.localiser.add
        self.book = book
        on_memory = (lambda m: book.read(m.data)) if book is not None else None
        self.reader = RfidReader(port, tag_map.ids, sink, clock=clock, on_memory=on_memory)
        self._pose_pub = wire.declare_publisher(session, T.POSE, user)
        self._stats_pub = wire.declare_publisher(session, T.RFID_STATS, user)
        self.published = 0
        self.last: Estimate | None = None

    def publish_once(self) -> Estimate | None:
        """Estimate now and publish the pose; None (nothing sent) without enough reads."""
        now = self.clock()
        sigma = None
        if self.filter is not None:
            fp = self.filter.pose(now)
            est = None if fp is None else Estimate(fp.x, fp.y, fp.heading, fp.quality, fp.source,
                                                   0, now)  # fmt: skip
            sigma = None if fp is None else min(fp.sigma_m, 100.0)
        else:
            est = self.localiser.estimate(now)
        if est is None:
            return None
        pose = Pose(x=est.x, y=est.y, heading=est.heading, stamp=now, quality=est.quality,
                    sigma_m=sigma)  # fmt: skip
        self._pose_pub.put(codec.encode(pose))
        self.published += 1
        self.last = est
        return est

    def stats(self) -> RfidStats:
        last = self.last
        return RfidStats(
            **self.reader.stats(),
            poses=self.published,
            source=last.source if last else None,
            quality=round(last.quality, 3) if last else None,
            stamp=self.clock(),
        )

    async def run(self) -> None:
        """Until cancelled: the reader in one task, poses at the fixed rate in this one."""
        reader = asyncio.create_task(self.reader.run(), name="rfid-reader")
        loop = asyncio.get_running_loop()
        next_t = loop.time()
        next_stats = next_t + 1.0
        try:
            while True:
                self.publish_once()
                if loop.time() >= next_stats:
                    self._stats_pub.put(codec.encode(self.stats()))
                    next_stats += 1.0
                next_t += self.period
                delay = next_t - loop.time()
                if delay < -self.period:  # fell behind (a stall): skip, don't burst
                    next_t = loop.time()
                    delay = 0.0
                await asyncio.sleep(max(0.0, delay))
        finally:
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)

    def close(self) -> None:
        self._pose_pub.undeclare()
        self._stats_pub.undeclare()
