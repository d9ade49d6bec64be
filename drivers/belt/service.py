"""The belt driver's zenoh side: ``BeltService`` wires a ``BeltLink`` to zenoh — patterns in,
``BeltHealth`` and button presses out, the user's intensity in, STOP as soon as the daemon's
liveliness token disappears — and ``serve`` runs both (the ``guidebelt belt`` command)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from typing import TYPE_CHECKING

from drivers.belt import frames as F
from drivers.belt.driver import BeltLink

if TYPE_CHECKING:  # zenoh and pydantic load only where the driver meets zenoh
    import zenoh

    from protocol.settings import ZenohSettings

log = logging.getLogger("guidebelt.belt")


class BeltService:
    """Zenoh side of the driver: one user's patterns in, the link's health out."""

    def __init__(self, session, user: str, link: BeltLink, health_period_s: float = 0.5) -> None:
        self.session = session
        self.user = user
        self.link = link
        self.health_period_s = health_period_s
        self.rejected = 0
        self.daemons_alive = 0

    async def run(self) -> None:
        import zenoh

        from protocol import session as wire
        from protocol import topics as T

        loop = asyncio.get_running_loop()

        def on_pattern(sample: zenoh.Sample) -> None:  # zenoh's thread: hand over, never block
            loop.call_soon_threadsafe(self._on_pattern, sample.payload.to_bytes())

        def on_alive(sample: zenoh.Sample) -> None:
            loop.call_soon_threadsafe(self._on_alive, sample.kind == zenoh.SampleKind.PUT)

        def on_settings(sample: zenoh.Sample) -> None:
            loop.call_soon_threadsafe(self._on_settings, sample.payload.to_bytes())

        def on_reply(reply: zenoh.Reply) -> None:
            if reply.ok is not None:
                on_settings(reply.ok)

        sub = wire.declare_subscriber(self.session, T.BELT, on_pattern, self.user)
        settings = wire.declare_subscriber(self.session, T.SETTINGS, on_settings, self.user)
        alive = wire.watch_liveliness(self.session, T.ALIVE, on_alive)
        pub = wire.declare_publisher(self.session, T.BELT_HEALTH, self.user)
        buttons = wire.declare_publisher(self.session, T.BELT_BUTTON, self.user)
        self.link.on_button = lambda press: self._publish_press(buttons, press)
        # The user's intensity as the daemon has it now; later changes come on SETTINGS.
        wire.get(self.session, T.SETTINGS_QUERY, self.user, on_reply, 2.0)
        link_task = asyncio.create_task(self.link.run())
        try:
            while not link_task.done():
                pub.put(self.health().model_dump_json())
                await asyncio.sleep(self.health_period_s)
            link_task.result()  # surface a crash of the link loop
        finally:
            self.link.close()
            link_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await link_task
            for entity in (sub, settings, alive, pub, buttons):
                entity.undeclare()

    def health(self):
        from protocol.messages import BeltHealth

        return BeltHealth(**self.link.health(), stamp=time.time())

    def _decoded(self, kind, raw: bytes, what: str):
        """``raw`` as a ``kind``, or None: counted and logged as rejected."""
        from protocol.codec import DecodeError, decode

        try:
            return decode(kind, raw)
        except DecodeError as exc:
            self.rejected += 1
            log.warning("%s rejected: %s", what, exc)
            return None

    def _on_pattern(self, raw: bytes) -> None:
        from protocol.messages import BeltPattern

        msg = self._decoded(BeltPattern, raw, "belt pattern")
        if msg is None:
            return
        # The firmware pulses no faster than 20 ms; a shorter period is a fast pulse.
        period = msg.period_ms if msg.period_ms == 0 else max(msg.period_ms, F.PERIOD_MIN_MS)
        self.link.show(F.Pattern(tuple(msg.motors), period, msg.ttl_ms))

    def _publish_press(self, publisher, press: F.Button) -> None:
        from protocol.messages import BeltButton

        kind = "long" if press.kind == F.PressKind.LONG else "short"
        msg = BeltButton(press=press.press, button=press.button, kind=kind, stamp=time.time())
        publisher.put(msg.model_dump_json())

    def _on_settings(self, raw: bytes) -> None:
        from protocol.messages import UserSettings

        msg = self._decoded(UserSettings, raw, "settings")
        # A settings message may leave the intensity out (null): the belt keeps its own.
        if msg is not None and msg.intensity is not None and msg.intensity != self.link.intensity:
            self.link.set_intensity(msg.intensity)

    def _on_alive(self, alive: bool) -> None:
        was_alive = self.daemons_alive > 0
        self.daemons_alive = max(0, self.daemons_alive + (1 if alive else -1))
        if was_alive and self.daemons_alive == 0:
            log.warning("daemon liveliness lost: STOP")
            self.link.stop()


async def serve(port: str, user: str, settings: ZenohSettings, stop: asyncio.Event) -> None:
    """Run the driver until ``stop`` is set (the ``guidebelt belt`` command)."""
    from protocol.session import open_session

    session = open_session(settings)
    try:
        service = BeltService(session, user, BeltLink(port))
        task = asyncio.create_task(service.run())
        stopper = asyncio.create_task(stop.wait())
        await asyncio.wait({task, stopper}, return_when=asyncio.FIRST_COMPLETED)
        stopper.cancel()
        if not task.done():
            service.link.stop()  # leave the belt quiet, not guiding on a dead driver
            await asyncio.sleep(0.02)
            task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
    finally:
        session.close()
