"""A Python stand-in for the belt firmware on a pseudo-terminal, for machines without simavr.

Same behaviour as ``firmware/main.c`` (acks, heartbeats every 200 ms, the 500 ms link
watchdog, the pattern's TTL, pulses that keep their phase when a pattern is repeated, the
bad-frame counters, intensity, debounced buttons repeated until acked, the battery in
STATUS) and the same stdout lines and stdin commands as the simavr harness, so tests and the
demo drive either one the same way::

    python -m drivers.belt.mock_firmware [--link PATH]

    pty PATH / link PATH / ready / pwm T_US MONO_US MOTOR LEVEL / rx T_US MONO_US /
    button T_US MONO_US ID DOWN / battery T_US MONO_US MV / stats ...
    stdin: button ID DOWN / battery MV
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
        self.next_status = 0
        self.intensity = F.INTENSITY_MAX
        self.battery_mv = 4000  # what the pin would read, times the divider
        self.down = [False] * F.BUTTONS  # the pins, as the harness sets them
        self.raw = [False] * F.BUTTONS
        self.stable = [False] * F.BUTTONS
        self.long_sent = [False] * F.BUTTONS
        self.changed_at = [0] * F.BUTTONS
        self.pressed_at = [0] * F.BUTTONS
        self.pending: list[list[int]] = []  # [press, button, kind, at, sent]
        self.presses = self.presses_dropped = 0

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
        elif frame.ftype == F.FrameType.INTENSITY and len(frame.payload) == F.INTENSITY_LEN:
            ok = frame.payload[0] <= F.INTENSITY_MAX
            if ok and frame.payload[0] != self.intensity:
                self.intensity = frame.payload[0]
                self.next_status = now
        elif frame.ftype == F.FrameType.BUTTON_ACK and len(frame.payload) == F.BUTTON_ACK_LEN:
            press = int.from_bytes(frame.payload, "little")
            self.pending = [q for q in self.pending if q[0] != press]
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
        self.outputs = [F.scale_level(m, self.intensity) if on else 0 for m in self.pattern.motors]

    def _queue_press(self, button: int, kind: F.PressKind, now: int) -> bytes:
        self.presses = (self.presses + 1) & 0xFFFF or 1
        if len(self.pending) == F.BUTTON_QUEUE:
            self.presses_dropped += 1
            return b""
        self.pending.append([self.presses, button, kind, now, now])
        return self._send(F.FrameType.BUTTON, F.Button(self.presses, button, kind).payload())

    def _buttons(self, now: int) -> bytes:
        out = b""
        for i in range(F.BUTTONS):
            if self.down[i] != self.raw[i]:
                self.raw[i], self.changed_at[i] = self.down[i], now
            if self.raw[i] != self.stable[i] and now >= self.changed_at[i] + F.DEBOUNCE_MS:
                self.stable[i] = self.raw[i]
                if self.stable[i]:
                    self.pressed_at[i], self.long_sent[i] = now, False
                elif not self.long_sent[i]:
                    out += self._queue_press(i, F.PressKind.SHORT, now)
            if self.stable[i] and not self.long_sent[i] and (
                now >= self.pressed_at[i] + F.LONG_PRESS_MS
            ):
                self.long_sent[i] = True
                out += self._queue_press(i, F.PressKind.LONG, now)
        for q in list(self.pending):
            if now >= q[3] + F.BUTTON_EXPIRE_MS:
                self.pending.remove(q)
                self.presses_dropped += 1
            elif now >= q[4] + F.BUTTON_RESEND_MS:
                q[4] = now
                out += self._send(F.FrameType.BUTTON, F.Button(q[0], q[1], q[2]).payload())
        return out

    def status(self) -> F.Status:
        return F.Status(
            self.battery_mv, self.intensity, len(self.pending), self.presses,
            self.presses_dropped & 0xFFFF,
        )  # fmt: skip

    def tick(self, now: int) -> bytes:
        if self.parser.pending and now >= self.last_byte + F.BYTE_TIMEOUT_MS:
            self.parser.timeout()
        if self.state not in (F.BeltState.BOOT, F.BeltState.WATCHDOG) and (
            now >= self.last_valid + F.LINK_WATCHDOG_MS
        ):
            self.state = F.BeltState.WATCHDOG
            self.watchdog_trips += 1
        self._update_outputs(now)
        out = self._buttons(now)
        if now >= self.next_heartbeat:
            self.next_heartbeat = now + F.HEARTBEAT_MS
            out += self._send(F.FrameType.HEARTBEAT, self.heartbeat(now).payload())
        if now >= self.next_status:
            self.next_status = now + F.STATUS_MS
            out += self._send(F.FrameType.STATUS, self.status().payload())
        return out

    def heartbeat(self, now: int) -> F.Heartbeat:
        return F.Heartbeat(
            F.BeltState(self.state), self.last_seq, tuple(self.outputs),  # type: ignore[arg-type]
            self.parser.counters(), self.watchdog_trips & 0xFFFF, now & 0xFFFFFFFF,
        )  # fmt: skip


def _command(logic: BeltLogic, words: list[str], t0: float) -> None:
    """One stdin command, as the harness takes it: ``button ID DOWN`` or ``battery MV``."""
    mono = time.monotonic()
    stamp = f"{int((mono - t0) * 1e6)} {int(mono * 1e6)}"
    if words[:1] == ["button"] and len(words) == 3 and 0 <= int(words[1]) < F.BUTTONS:
        logic.down[int(words[1])] = words[2] != "0"
        print(f"button {stamp} {int(words[1])} {int(words[2] != '0')}", flush=True)
    elif words[:1] == ["battery"] and len(words) == 2:
        # The ADC's steps (5 V / 1024 through the 1:2 divider) and the firmware's mean are
        # not modelled: the mock reports the voltage as set.
        logic.battery_mv = int(words[1])
        print(f"battery {stamp} {int(words[1])}", flush=True)


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
    stdin = sys.stdin.fileno()
    os.set_blocking(stdin, False)
    with contextlib.suppress(ValueError, OSError, PermissionError):
        sel.register(stdin, selectors.EVENT_READ)
    pending_line = b""
    print("ready", flush=True)
    next_tick = 0
    last_rx = -1.0
    while not stop:
        now = int((time.monotonic() - t0) * 1000)
        out = b""
        if now >= next_tick:
            out += logic.tick(now)
            next_tick = now + 1
        ready = {key.fd for key, _ in sel.select(timeout=max(0.0, (next_tick - now) / 1000))}
        if stdin in ready:
            try:
                chunk = os.read(stdin, 4096)
            except BlockingIOError:
                chunk = b""
            if not chunk:
                sel.unregister(stdin)  # stdin closed: no more commands
            pending_line += chunk
            while b"\n" in pending_line:
                line, pending_line = pending_line.split(b"\n", 1)
                _command(logic, line.decode(errors="replace").split(), t0)
        if master in ready:
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
