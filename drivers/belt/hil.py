"""Hardware in the loop: start the simulated belt (simavr harness or Python mock) and watch it.

``SimulatedBelt`` runs either ``build/belt/belt-harness`` (the real firmware on simavr) or
``python -m drivers.belt.mock_firmware``; both print the same lines (see the harness's
header) and keep a symlink to their pty at a fixed path, so a driver survives restarts.
``start_simulated_belt`` adds the ``guidebelt belt`` driver process, for the demo.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / "build" / "belt"
FIRMWARE_DIR = Path(__file__).resolve().parent / "firmware"
ELF = BUILD / "belt.elf"
HARNESS = BUILD / "belt-harness"
FRAME_CHECK = BUILD / "frame-check"
KINDS = ("simavr", "mock")


def simavr_missing() -> str | None:
    """Why the simavr belt cannot be built here, or None when it can."""
    for tool in ("avr-gcc", "avr-objcopy", "cc", "make", "pkg-config"):
        if shutil.which(tool) is None:
            return f"{tool} not found"
    for header in ("/usr/include/simavr/sim_avr.h", "/usr/include/simavr/parts/uart_pty.h"):
        if not Path(header).is_file():
            return f"{header} not found"
    if not Path("/usr/lib/avr/include/avr/io.h").is_file():
        return "avr-libc not installed"
    return None


def build_firmware() -> None:
    """``make`` in the firmware directory: the ELF, the HEX, the harness, frame-check."""
    missing = simavr_missing()
    if missing:
        raise RuntimeError(f"cannot build the belt firmware: {missing} (run `make system-deps`)")
    out = subprocess.run(
        ["make", "-s", "-C", str(FIRMWARE_DIR), f"BUILD={BUILD}"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"firmware build failed:\n{out.stdout}\n{out.stderr}")


@dataclass(frozen=True)
class PwmEvent:
    mono: float  # host time.monotonic() when the output changed
    sim_s: float  # the belt's own clock (simulated time for simavr)
    motor: int
    level: int


class SimulatedBelt:
    """One belt process; ``levels`` is the motors' output as the process last reported it.

    The process dies with the thread that started it (``PR_SET_PDEATHSIG``, so a crashed
    test leaks nothing): start it from a thread that outlives its use."""

    def __init__(self, kind: str, link: str | Path) -> None:
        if kind not in KINDS:
            raise ValueError(f"belt kind must be one of {KINDS}, not {kind!r}")
        self.kind = kind
        self.link = str(link)
        self.proc: subprocess.Popen[str] | None = None
        self.events: list[PwmEvent] = []
        self.levels = [0, 0, 0, 0]
        self.pty: str | None = None
        self.stats: str | None = None
        self.rx_bursts: list[float] = []  # monotonic times the host started talking
        self.rx_sim: list[float] = []  # the same moments on the belt's clock
        self.pins: list[tuple[float, float, int, int]] = []  # (mono, sim_s, button, down)
        self.ready_at = 0.0  # monotonic time of the last start's "ready" (pty in place)
        self._cond = threading.Condition()
        self._reader: threading.Thread | None = None
        self._ready = False

    def command(self) -> list[str]:
        if self.kind == "simavr":
            return [str(HARNESS), str(ELF), "--link", self.link]
        return [sys.executable, "-m", "drivers.belt.mock_firmware", "--link", self.link]

    def start(self, timeout: float = 10.0) -> SimulatedBelt:
        if self.kind == "simavr" and not (HARNESS.exists() and ELF.exists()):
            build_firmware()
        self._ready = False
        self.proc = subprocess.Popen(
            self.command(), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, text=True, cwd=ROOT, bufsize=1,
        )  # fmt: skip
        self._reader = threading.Thread(target=self._read, args=(self.proc,), daemon=True)
        self._reader.start()
        if not self.wait_for(lambda: self._ready, timeout):
            self.stop()
            raise RuntimeError(f"{self.kind} belt did not start within {timeout} s")
        return self

    def _read(self, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            words = line.split()
            with self._cond:
                if words[:1] == ["pwm"] and len(words) == 5:
                    t_us, mono_us, motor, level = map(int, words[1:])
                    self.events.append(PwmEvent(mono_us / 1e6, t_us / 1e6, motor, level))
                    self.levels[motor] = level
                elif words[:1] == ["pty"] and len(words) == 2:
                    self.pty = words[1]
                elif words[:1] == ["rx"] and len(words) == 3:
                    self.rx_sim.append(int(words[1]) / 1e6)
                    self.rx_bursts.append(int(words[2]) / 1e6)
                elif words == ["ready"]:
                    self._ready = True
                    self.ready_at = time.monotonic()
                elif words[:1] == ["button"] and len(words) == 5:
                    t_us, mono_us, button, down = map(int, words[1:])
                    self.pins.append((mono_us / 1e6, t_us / 1e6, button, down))
                elif words[:1] == ["stats"]:
                    self.stats = line.strip()
                self._cond.notify_all()

    def _tell(self, line: str) -> None:
        assert self.proc is not None and self.proc.stdin is not None, "belt not running"
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def button(self, button: int, down: bool) -> float:
        """Push (``down``) or release a button on the belt; the monotonic time the belt
        process applied it to the pin (it reports that moment)."""
        with self._cond:
            n = len(self.pins)
        self._tell(f"button {button} {int(down)}")
        if not self.wait_for(lambda: len(self.pins) > n, 2.0):
            raise RuntimeError("the belt did not apply the button")
        with self._cond:
            return self.pins[n][0]

    def press(self, button: int, hold_s: float = 0.1) -> float:
        """A whole press (down, ``hold_s``, up); the moment of the release, when the belt
        reports a short press (a long one, ``hold_s`` ≥ 0.8, is reported while held)."""
        self.button(button, True)
        time.sleep(hold_s)
        return self.button(button, False)

    def battery(self, millivolts: int) -> None:
        """The battery's voltage from now on (the Nano reads half of it on A0)."""
        self._tell(f"battery {int(millivolts)}")

    def wait_for(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait until ``predicate()`` (checked under the lock, after each line) holds."""
        with self._cond:
            return self._cond.wait_for(predicate, timeout)

    def wait_levels(self, levels: tuple[int, ...], timeout: float) -> PwmEvent | None:
        """Wait until the outputs equal ``levels``; the event that completed them, or None."""
        if not self.wait_for(lambda: tuple(self.levels) == tuple(levels), timeout):
            return None
        with self._cond:
            return self.events[-1] if self.events else None

    def stop(self, kill: bool = False, timeout: float = 5.0) -> None:
        proc, self.proc = self.proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL if kill else signal.SIGTERM)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout)
        if self._reader is not None:
            self._reader.join(timeout)
        for pipe in (proc.stdin, proc.stdout):
            if pipe is not None:
                with contextlib.suppress(OSError):
                    pipe.close()
        with self._cond:
            self.levels = [0, 0, 0, 0]  # a dead Nano drives nothing (its pins float)

    def __enter__(self) -> SimulatedBelt:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


@contextlib.contextmanager
def start_simulated_belt(
    kind: str,
    user: str,
    connect: list[str],
    link: str | Path | None = None,
    connect_timeout: float = 20.0,
) -> Iterator[SimulatedBelt]:
    """The simulated belt plus a ``guidebelt belt`` driver process connected to ``connect``.

    Yields the running belt once the driver talks to it (the driver pings every 100 ms);
    the driver follows ``user``'s patterns."""
    link = Path(link or f"/tmp/guidebelt-belt-{os.getpid()}")
    with SimulatedBelt(kind, link) as belt:
        cmd = [sys.executable, "-m", "cli.app", "belt", "--port", str(link),
               "--user", user, "--no-multicast", "--log-level", "WARNING"]  # fmt: skip
        for endpoint in connect:
            cmd += ["--connect", endpoint]
        driver = subprocess.Popen(cmd, cwd=ROOT)
        try:
            if not belt.wait_for(lambda: bool(belt.rx_bursts), connect_timeout):
                raise RuntimeError(f"belt driver not talking within {connect_timeout} s")
            yield belt
        finally:
            driver.send_signal(signal.SIGTERM)
            try:
                driver.wait(5)
            except subprocess.TimeoutExpired:
                driver.kill()
                driver.wait(5)
            # Give the belt a moment to report the driver's parting STOP.
            time.sleep(0.05)


@contextlib.contextmanager
def belt_in_loop(kind: str, user: str, daemon_port: int) -> Iterator[SimulatedBelt | None]:
    """For ``guidebelt demo --belt simavr|mock|none``: the belt and its driver joined to the
    daemon on 127.0.0.1:``daemon_port``, or nothing for ``none``."""
    if kind == "none":
        yield None
        return
    endpoint = f"tcp/127.0.0.1:{daemon_port}"
    with start_simulated_belt(kind, user, [endpoint]) as belt:
        yield belt


def summary(belt: SimulatedBelt) -> str:
    """One line on what the simulated belt did, for the demo's report."""
    label = "firmware on simavr" if belt.kind == "simavr" else "Python mock firmware"
    patterns = sum(1 for e in belt.events if e.level)
    line = f"belt ({label}): {len(belt.events)} PWM changes, {patterns} of them motors on"
    if belt.kind == "simavr" and belt.stats:
        sim_s, wall_s, lag_ms, slips, sleep = belt.stats.split()[1:6]
        line += (f"; {sim_s} s simulated in {wall_s} s, max lag {lag_ms} ms, {slips} slips, "
                 f"AVR asleep {sleep} % of cycles")  # fmt: skip
    return line
