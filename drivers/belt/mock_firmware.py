"""A Python stand-in for the belt firmware on a pseudo-terminal, for machines without simavr.

Same behaviour as ``firmware/main.c`` (acks, heartbeats every 200 ms, the 500 ms link
watchdog, the pattern's TTL, pulses that keep their phase when a pattern is repeated, the
bad-frame counters) and the same stdout lines as the simavr harness, so tests and the demo
drive either one the same way::

    python -m drivers.belt.mock_firmware [--link PATH]

    pty PATH / link PATH / ready / pwm T_US MONO_US MOTOR LEVEL / rx T_US MONO_US / stats ...
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import os
import selectors
import signal
import sys
import termios
import time
import tty

from drivers.belt import frames as F


class BeltLogic:
    """The firmware's state machine, driven by a millisecond clock."""

    def __init__(self) -> None:
        self.parser = F.Parser()
        self.state = F.BeltState.BOOT
        self.pattern = F.Pattern((0, 0, 0, 0), 0, F.TTL_MIN_MS)
        self.outputs = [0, 0, 0, 0]
        self.last_seq = 0
        self.tx_seq = 0
        self.watchdog_trips = 0
        self.pattern_start = self.ttl_deadline = self.last_valid = self.last_byte = 0
        self.next_heartbeat = 0

    def _send(self, ftype: int, payload: bytes) -> bytes:
        frame = F.encode(ftype, self.tx_seq, payload)
        self.tx_seq = (self.tx_seq + 1) & 0xFFFF
        return frame

    def receive(self, data: bytes, now: int) -> bytes:
        """Bytes from the host; returns the bytes to send back (acks)."""
        self.last_byte = now
        out = b""
        for frame in self.parser.feed(data):
            out += self._handle(frame, now)
        return out

    def _handle(self, frame: F.Frame, now: int) -> bytes:
        ok = False
        if frame.ftype == F.FrameType.PATTERN and len(frame.payload) == F.PATTERN_LEN:
            ok = self._apply(F.Pattern.unpack(frame.payload), now)
        elif frame.ftype == F.FrameType.STOP and not frame.payload:
            self.state, ok = F.BeltState.STOPPED, True
        elif frame.ftype == F.FrameType.PING and not frame.payload:
            ok = True
        if not ok:
            self.parser.malformed += 1
            return self._send(F.FrameType.ACK, F.Ack(frame.seq, F.ACK_REFUSED).payload())
        self.last_valid = now
        self.last_seq = frame.seq
        self._update_outputs(now)
        return self._send(F.FrameType.ACK, F.Ack(frame.seq, F.ACK_APPLIED).payload())

    def _apply(self, pattern: F.Pattern, now: int) -> bool:
        if not pattern.valid():
            return False
        if not (self.state == F.BeltState.ACTIVE and pattern.motors == self.pattern.motors
                and pattern.period_ms == self.pattern.period_ms):  # fmt: skip
            self.pattern_start = now  # a repeat only refreshes the TTL
        self.pattern = pattern
        self.ttl_deadline = now + pattern.ttl_ms
        self.state = F.BeltState.ACTIVE
        return True

    def _update_outputs(self, now: int) -> None:
        if self.state == F.BeltState.ACTIVE and now >= self.ttl_deadline:
            self.state = F.BeltState.IDLE
        on = self.state == F.BeltState.ACTIVE
        period = self.pattern.period_ms
        if on and period:
            on = (now - self.pattern_start) % period < period // 2
        self.outputs = [m if on else 0 for m in self.pattern.motors]

    def tick(self, now: int) -> bytes:
        if self.parser.pending and now >= self.last_byte + F.BYTE_TIMEOUT_MS:
            self.parser.timeout()
        if self.state not in (F.BeltState.BOOT, F.BeltState.WATCHDOG) and (
            now >= self.last_valid + F.LINK_WATCHDOG_MS
        ):
            self.state = F.BeltState.WATCHDOG
            self.watchdog_trips += 1
        self._update_outputs(now)
        if now >= self.next_heartbeat:
            self.next_heartbeat = now + F.HEARTBEAT_MS
            return self._send(F.FrameType.HEARTBEAT, self.heartbeat(now).payload())
        return b""

    def heartbeat(self, now: int) -> F.Heartbeat:
        return F.Heartbeat(
            F.BeltState(self.state), self.last_seq, tuple(self.outputs),  # type: ignore[arg-type]
            self.parser.counters(), self.watchdog_trips & 0xFFFF, now & 0xFFFFFFFF,
        )  # fmt: skip


def _die_with_parent() -> None:
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


def run(link: str | None) -> None:
    master, slave = os.openpty()  # the slave stays open: the driver may come and go
    tty.setraw(slave, termios.TCSANOW)
    os.set_blocking(master, False)
    name = os.ttyname(slave)
    print(f"pty {name}", flush=True)
    if link:
        tmp = f"{link}.{os.getpid()}"
        os.symlink(name, tmp)
        os.replace(tmp, link)  # atomic: a driver never sees the link missing
        print(f"link {link}", flush=True)
    stop = False

    def on_signal(signum: int, frame: object) -> None:
        nonlocal stop
        stop = True

    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, on_signal)
    t0 = time.monotonic()
    logic = BeltLogic()
    shown = [-1, -1, -1, -1]
    sel = selectors.DefaultSelector()
    sel.register(master, selectors.EVENT_READ)
    print("ready", flush=True)
    next_tick = 0
    last_rx = -1.0
    while not stop:
        now = int((time.monotonic() - t0) * 1000)
        out = b""
        if now >= next_tick:
            out += logic.tick(now)
            next_tick = now + 1
        if sel.select(timeout=max(0.0, (next_tick - now) / 1000)):
            with contextlib.suppress(BlockingIOError):
                data = os.read(master, 4096)
                mono = time.monotonic()
                if mono - last_rx > 0.1:  # the start of a burst from the host
                    print(f"rx {int((mono - t0) * 1e6)} {int(mono * 1e6)}", flush=True)
                last_rx = mono
                out += logic.receive(data, int((mono - t0) * 1000))
        if out:
            with contextlib.suppress(BlockingIOError):  # nobody reading: drop, as a UART does
                os.write(master, out)
        for i, level in enumerate(logic.outputs):
            if level != shown[i]:
                shown[i] = level
                mono = time.monotonic()
                print(f"pwm {int((mono - t0) * 1e6)} {int(mono * 1e6)} {i} {level}", flush=True)
    if link and os.path.islink(link) and os.readlink(link) == name:
        os.unlink(link)
    print(f"stats {time.monotonic() - t0:.3f} {time.monotonic() - t0:.3f} 0 0 0", flush=True)
    os.close(master)
    os.close(slave)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--link", help="create a symlink to the pty at this path")
    args = ap.parse_args()
    _die_with_parent()
    try:
        run(args.link)
    except BrokenPipeError:
        sys.exit(0)


if __name__ == "__main__":
    main()
