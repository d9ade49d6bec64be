"""A mock reader on a pseudo-terminal: the tags of the simulated world answer as the user walks.

It writes the same lines a real reader sends (``protocol.format_read``), one inventory
round every ``1/round_hz`` s, drawn from the RSSI model at the position ``position(t)``
returns. A tag with user memory (``memories``: the obstacle it carries, ``tag_payload``)
has it sent once per connection, after its first read, as a reader reads a tag's memory
when the tag first answers. ``unplug()``/``plug()`` close and reopen the pty as a USB
unplug would; ``link`` is a stable path (like a udev symlink) that follows the current pty.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
import tty
from collections.abc import Callable

from .protocol import format_memory, format_read
from .rssi import ReadModel

Position = Callable[[float], "tuple[float, float] | None"]


class MockReader:
    def __init__(
        self,
        model: ReadModel,
        position: Position,
        *,
        link: str | None = None,
        round_hz: float = 50.0,
        uhf_every: int = 5,
        clock: Callable[[], float] = time.time,
        memories: dict[str, bytes] | None = None,
    ) -> None:
        self.model = model
        self.memories = dict(memories or {})
        self._memory_sent: set[str] = set()
        self.position = position
        self.link = link
        self.period = 1.0 / round_hz
        # A UHF inventory of ~20 tags every 0.1 s fills about 80 % of a 115200 baud line;
        # the LF floor antenna is polled every round.
        self.uhf_every = max(1, uhf_every)
        self.clock = clock
        self.rounds = 0
        self.lines = 0
        self._t0 = time.monotonic()
        self._lock = threading.Lock()
        self._master: int | None = None
        self._slave: int | None = None
        self.slave_name = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def path(self) -> str:
        return self.link or self.slave_name

    def plug(self) -> None:
        """A fresh pty (the device appears), with ``link`` pointing at it."""
        with self._lock:
            if self._master is not None:
                return
            master, slave = os.openpty()
            tty.setraw(slave)  # no echo, no line editing before the driver opens it
            os.set_blocking(master, False)  # nobody listening must not stall the mock
            self._master, self._slave = master, slave
            self._memory_sent = set()  # a new connection: the host has read no memory yet
            self.slave_name = os.ttyname(slave)
            if self.link:
                tmp = f"{self.link}.tmp{os.getpid()}"
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
                os.symlink(self.slave_name, tmp)
                os.replace(tmp, self.link)

    def unplug(self) -> None:
        """Close the pty (the device disappears): the driver's reads fail."""
        with self._lock:
            if self.link:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(self.link)
            for fd in (self._master, self._slave):
                if fd is not None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._master = self._slave = None

    def write(self, raw: bytes) -> bool:
        """Send raw bytes (a test's garbage); False when unplugged or the pty is full."""
        with self._lock:
            if self._master is None:
                return False
            try:
                os.write(self._master, raw)
            except OSError:  # full (nobody reads) or gone: a real reader's bytes are lost too
                return False
            return True

    def round(self) -> int:
        """One round at the current position; the number of reads sent."""
        now = self.clock()
        pos = self.position(now)
        if pos is None:
            return 0
        ms = int((time.monotonic() - self._t0) * 1000)
        uhf = self.rounds % self.uhf_every == 0
        reads = self.model.round(pos[0], pos[1], now, ms, uhf=uhf)
        payload = b"".join(format_read(r.tag_id, r.rssi, r.reader_ms) for r in reads)
        fresh = {r.tag_id for r in reads if r.tag_id in self.memories} - self._memory_sent
        payload += b"".join(format_memory(t, self.memories[t]) for t in sorted(fresh))
        self.rounds += 1
        if payload and self.write(payload):
            self.lines += len(reads) + len(fresh)
            self._memory_sent |= fresh
        return len(reads)

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            self.round()
            next_t += self.period
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    def start(self) -> MockReader:
        self.plug()
        self._thread = threading.Thread(target=self._run, name="mock-rfid", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.unplug()

    def __enter__(self) -> MockReader:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
