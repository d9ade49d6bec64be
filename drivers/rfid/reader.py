"""The asyncio driver for the reader on a serial port: lines in, filtered reads out.

pyserial opens and configures the port (115200 8N1, raw); the loop then watches its file
descriptor, so no thread blocks on it. When the device goes away (USB unplugged: the read
fails or returns nothing though the port said it was readable) the driver closes it and
tries again with exponential backoff until it is back, for as long as it runs.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import time
from collections.abc import Callable

import serial

from .protocol import MAX_LINE_BYTES, Memory, Read, ReadFilter

log = logging.getLogger(__name__)


class RfidReader:
    """Reads lines from ``port`` and hands each accepted read to ``on_read`` (loop thread)."""

    def __init__(
        self,
        port: str,
        known_ids: frozenset[str] | set[str],
        on_read: Callable[[Read], None],
        *,
        on_memory: Callable[[Memory], None] | None = None,
        baudrate: int = 115200,
        backoff_min_s: float = 0.05,
        backoff_max_s: float = 2.0,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.port = port
        self.baudrate = baudrate
        self.on_read = on_read
        self.on_memory = on_memory
        """A tag's user memory (the obstacle it carries), when the reader reports one."""
        self.filter = ReadFilter(known_ids)
        self.backoff_min_s = backoff_min_s
        self.backoff_max_s = backoff_max_s
        self.clock = clock
        self.connected = asyncio.Event()
        self.connects = 0
        self.disconnects = 0
        self._buf = bytearray()
        self._discarding = False

    def stats(self) -> dict[str, int | bool]:
        return {
            **self.filter.counts(),
            "connected": self.connected.is_set(),
            "connects": self.connects,
            "disconnects": self.disconnects,
        }

    async def run(self) -> None:
        """Read until cancelled, reconnecting whenever the port is lost."""
        delay = self.backoff_min_s
        while True:
            try:
                ser = serial.Serial(self.port, self.baudrate, timeout=0, exclusive=True)
            except (serial.SerialException, OSError) as exc:
                log.debug("rfid reader %s not available: %s", self.port, exc)
                await asyncio.sleep(delay)
                delay = min(delay * 2, self.backoff_max_s)
                continue
            delay = self.backoff_min_s
            with contextlib.suppress(Exception):
                ser.reset_input_buffer()  # reads queued while nobody listened are stale
            self.connects += 1
            log.info("rfid reader connected on %s", self.port)
            try:
                await self._pump(ser)
            finally:
                self.connected.clear()
                with contextlib.suppress(Exception):
                    ser.close()
            self.disconnects += 1
            log.warning("rfid reader on %s lost; reconnecting", self.port)

    async def _pump(self, ser: serial.Serial) -> None:
        """Feed lines from an open port until it fails."""
        loop = asyncio.get_running_loop()
        lost = loop.create_future()
        fd = ser.fileno()
        self._buf.clear()
        self._discarding = True  # the first line may have started before we opened

        def readable() -> None:
            try:
                data = os.read(fd, 4096)
            except BlockingIOError:
                return
            except OSError as exc:
                data = b""
                log.debug("rfid read failed: %s", exc)
            if not data:
                if not lost.done():
                    lost.set_result(None)
                return
            self._feed(data)

        loop.add_reader(fd, readable)
        self.connected.set()
        try:
            await lost
        finally:
            loop.remove_reader(fd)

    def _feed(self, data: bytes) -> None:
        now = self.clock()
        self._buf += data
        while True:
            nl = self._buf.find(b"\n")
            if nl < 0:
                break
            line = bytes(self._buf[: nl + 1])
            del self._buf[: nl + 1]
            if self._discarding:
                self._discarding = False
                if not line.startswith((b"TAG,", b"MEM,", b"#")):
                    continue  # the tail of a line cut by the (re)connection
            read = self.filter.feed(line, now)
            if isinstance(read, Memory):
                if self.on_memory is not None:
                    self.on_memory(read)
            elif read is not None:
                self.on_read(read)
        if len(self._buf) > MAX_LINE_BYTES + 2:
            # No line end in sight: count it once, drop through to the next newline.
            self.filter.rejected["garbage"] += 1
            self._buf.clear()
            self._discarding = True
