"""The belt driver: belt patterns from zenoh to the Nano over serial, health back to zenoh.

``BeltLink`` owns the serial port. pyserial opens and configures it (115200 8N1, raw,
exclusive lock) and leaves the descriptor non-blocking; the asyncio loop then watches the
descriptor itself (``add_reader``) and writes frames with ``os.write``, so nothing ever
blocks the loop and a vanished port shows up at once as EIO. When the port goes away the
link retries with exponential backoff (50 ms doubling to 250 ms), and on reconnecting it
re-sends the current pattern, so the belt resumes within a second of the port's return.

The current pattern is re-sent every 100 ms until its TTL runs out (the firmware turns
every motor off after 500 ms without a valid frame); when there is nothing to show, a PING
keeps the link checked and measured. ``service.BeltService`` wires the link to zenoh.

Buttons: the belt repeats each press until a BUTTON_ACK; the link acks every copy and hands
each press number on once (``on_button``), which the service publishes on ``belt/button``.
Intensity: the user's (``settings``, from the daemon) goes to the belt on every connection
and again whenever the belt's STATUS shows another.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import statistics
import time
from collections import deque
from collections.abc import Callable

import serial

from drivers.belt import frames as F

log = logging.getLogger("guidebelt.belt")

KEEPALIVE_S = 0.1
BACKOFF_MIN_S = 0.05
BACKOFF_MAX_S = 0.25
SILENCE_S = 1.0  # no byte from the belt for this long: the link is dead, reopen it
# Opening a Nano's port pulses DTR, which resets it into its bootloader for about a second
# before the firmware's first heartbeat; reopening sooner would reset it again, for ever.
BOOT_GRACE_S = 3.0
PRESS_MEMORY_S = 3.0  # longer than the belt repeats a press (2 s): a copy, not a new press


class BeltLink:
    """One serial link to the belt firmware, reconnecting for ever until ``close()``."""

    def __init__(
        self,
        port: str,
        baudrate: int = 115200,
        on_button: Callable[[F.Button], None] | None = None,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.on_button = on_button
        self.intensity = F.INTENSITY_MAX  # the user's, sent to the belt
        self.status: F.Status | None = None
        self.presses = 0
        self._pressed: dict[int, float] = {}  # press number -> when first heard
        self.connected = asyncio.Event()
        self.pattern: F.Pattern | None = None
        self.expires = 0.0  # monotonic time the current pattern's TTL runs out
        self.parser = F.Parser()
        self.heartbeat: F.Heartbeat | None = None
        self.heartbeat_at: float | None = None
        self.frames_sent = self.acks = self.refused = self.dropped = self.reconnects = 0
        self.rtts: deque[float] = deque(maxlen=32)
        self._sent_at: dict[int, float] = {}
        self._seq = 0
        self._serial: serial.Serial | None = None
        self._fd = -1
        self._lost: asyncio.Event | None = None
        self._last_rx = 0.0
        self._heard = False  # any byte since the port was opened
        self._was_connected = False
        self._closing = False

    # ---- commands (call on the loop's thread) ----

    def show(self, pattern: F.Pattern) -> None:
        """Show ``pattern`` now and keep it alive until its TTL runs out."""
        self.pattern = pattern
        self.expires = time.monotonic() + pattern.ttl_ms / 1000
        self._send_current()

    def set_intensity(self, intensity: int) -> None:
        """The user's intensity (0..100), to the belt now and after every reconnection."""
        self.intensity = max(0, min(F.INTENSITY_MAX, int(intensity)))
        self._write(F.intensity_frame(self._next_seq(), self.intensity))

    def stop(self) -> None:
        """Every motor off now, and nothing more until the next pattern."""
        self.pattern = None
        self._write(F.stop_frame(self._next_seq()))

    def close(self) -> None:
        self._closing = True
        if self._lost is not None:
            self._lost.set()

    # ---- the connection loop ----

    async def run(self) -> None:
        backoff = BACKOFF_MIN_S
        while not self._closing:
            try:
                ser = serial.Serial(self.port, self.baudrate, timeout=0, exclusive=True)
            except (serial.SerialException, OSError, ValueError) as exc:
                log.debug("belt port %s not available: %s", self.port, exc)
                await asyncio.sleep(backoff)
                backoff = min(backoff * 2, BACKOFF_MAX_S)
                continue
            backoff = BACKOFF_MIN_S
            await self._serve(ser)

    async def _serve(self, ser: serial.Serial) -> None:
        loop = asyncio.get_running_loop()
        try:
            ser.reset_input_buffer()  # heartbeats queued while nobody listened are stale
        except (OSError, serial.SerialException):
            ser.close()  # gone again already: the caller retries
            return
        self.reconnects += self._was_connected
        self._was_connected = True
        self._serial, self._lost = ser, asyncio.Event()
        if self._closing:
            self._lost.set()
        self.parser.buf.clear()
        self._last_rx, self._heard = time.monotonic(), False
        fd = self._fd = ser.fileno()
        loop.add_reader(fd, self._on_readable)
        self.connected.set()
        log.info("belt connected on %s", self.port)
        keepalive = asyncio.create_task(self._keepalive())
        try:
            self._write(F.intensity_frame(self._next_seq(), self.intensity))
            self._send_current()
            await self._lost.wait()
        finally:
            keepalive.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await keepalive
            loop.remove_reader(fd)
            self.connected.clear()
            self._serial = None
            self._sent_at.clear()
            with contextlib.suppress(OSError, serial.SerialException):
                ser.close()
            (log.info if self._closing else log.warning)("belt disconnected from %s", self.port)

    async def _keepalive(self) -> None:
        while True:
            await asyncio.sleep(KEEPALIVE_S)
            limit = SILENCE_S if self._heard else BOOT_GRACE_S
            if time.monotonic() - self._last_rx > limit:
                log.warning("belt silent for %.1f s: reopening %s", limit, self.port)
                self._drop_link()
                return
            self._send_current()

    def _send_current(self) -> None:
        if self._serial is None:
            return
        remaining_ms = int((self.expires - time.monotonic()) * 1000)
        if self.pattern is not None and remaining_ms >= F.TTL_MIN_MS:
            # The remaining TTL, so every repeat ends the pattern at the same moment.
            p = self.pattern
            self._write(F.pattern_frame(self._next_seq(), F.Pattern(p.motors, p.period_ms,
                                                                    remaining_ms)))  # fmt: skip
        else:
            self._write(F.ping_frame(self._next_seq()))

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFF
        return self._seq

    def _write(self, frame: bytes) -> None:
        if self._serial is None:
            self.dropped += 1
            return
        try:
            n = os.write(self._serial.fileno(), frame)
        except BlockingIOError:
            n = 0
        except OSError:
            self.dropped += 1
            self._drop_link()
            return
        if n != len(frame):  # a partial frame is finished off by the belt's byte timeout
            self.dropped += 1
            return
        self.frames_sent += 1
        self._sent_at[frame[4] | frame[5] << 8] = time.monotonic()
        if len(self._sent_at) > 256:  # acks that never came
            self._sent_at.pop(next(iter(self._sent_at)))

    def _drop_link(self) -> None:
        if self._lost is not None:
            self._lost.set()

    def _on_readable(self) -> None:
        try:
            data = os.read(self._serial.fileno(), 4096) if self._serial else b""
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:  # EIO or end of file: the port is gone
            asyncio.get_running_loop().remove_reader(self._fd)
            self._drop_link()
            return
        now = time.monotonic()
        self._last_rx, self._heard = now, True
        for frame in self.parser.feed(data):
            msg = frame.decode()
            if isinstance(msg, F.Ack):
                self.acks += 1
                self.refused += msg.result != F.ACK_APPLIED
                sent = self._sent_at.pop(msg.seq, None)
                if sent is not None:
                    self.rtts.append(now - sent)
            elif isinstance(msg, F.Heartbeat):
                self.heartbeat, self.heartbeat_at = msg, now
            elif isinstance(msg, F.Button):
                self._on_press(msg, now)
            elif isinstance(msg, F.Status):
                self.status = msg
                if msg.intensity != self.intensity:  # a belt that rebooted, or a lost frame
                    self._write(F.intensity_frame(self._next_seq(), self.intensity))
            else:
                self.parser.malformed += 1

    def _on_press(self, press: F.Button, now: float) -> None:
        # Every copy is acked (the ack of an earlier copy may be the one that was lost);
        # only the first is handed on.
        self._write(F.button_ack_frame(self._next_seq(), press.press))
        for old in [n for n, t in self._pressed.items() if now - t > PRESS_MEMORY_S]:
            del self._pressed[old]
        if press.press in self._pressed:
            return
        self._pressed[press.press] = now
        self.presses += 1
        if self.on_button is not None:
            self.on_button(press)

    def health(self) -> dict[str, object]:
        """The fields of ``protocol.messages.BeltHealth`` (without the stamp)."""
        hb = self.heartbeat
        c = hb.counters if hb else F.Counters()
        p = self.parser
        connected = self.connected.is_set()
        st = self.status
        return {
            "port": self.port,
            "connected": connected,
            "belt_state": hb.state.name.lower() if hb and connected else "unknown",
            "frames_sent": self.frames_sent,
            "acks": self.acks,
            "refused": self.refused,
            "dropped": self.dropped,
            "reconnects": self.reconnects,
            "rx_errors": p.crc_errors + p.oversized + p.truncated + p.malformed,
            "belt_crc_errors": c.crc_errors,
            "belt_oversized": c.oversized,
            "belt_truncated": c.truncated,
            "belt_malformed": c.malformed,
            "watchdog_trips": hb.watchdog_trips if hb else 0,
            "latency_ms": statistics.median(self.rtts) * 1000 if self.rtts else None,
            "heartbeat_age_s": time.monotonic() - self.heartbeat_at if self.heartbeat_at else None,
            "battery_v": st.battery_mv / 1000 if st and connected else None,
            "intensity": st.intensity if st and connected else None,
            "presses": self.presses,
            "presses_dropped": st.presses_dropped if st else 0,
        }
