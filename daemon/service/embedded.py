"""The daemon on a thread of this process, for the demo, the tests and the benchmark.

The same ``Daemon`` as ``guidebelt run``, on its own uvloop loop in a thread, listening
on a free 127.0.0.1 port with multicast scouting off; other nodes connect to it there.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

import uvloop
import zenoh

from protocol.session import ZenohSettings, loopback, open_session

from .config import DaemonConfig
from .daemon import Daemon, Observer

T = TypeVar("T")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def open_peer(port: int) -> zenoh.Session:
    """A zenoh session connected to the daemon listening on ``port`` of 127.0.0.1."""
    return open_session(loopback(connect_port=port))


START_TIMEOUT_S = 180.0


class DaemonThread:
    """``with DaemonThread(config) as d:`` runs the daemon until the block ends."""

    def __init__(
        self,
        config: DaemonConfig | None = None,
        zenoh_on: Callable[[int], ZenohSettings] | None = None,
        observers: Sequence[Observer] = (),
        **overrides: object,
    ) -> None:
        """``zenoh_on(port)`` gives the daemon's zenoh settings on its free port (default:
        plain TCP on 127.0.0.1; the TLS tests pass certificates and access rules);
        ``observers`` watch the daemon's own session (a recorder)."""
        self.port = free_port()
        base = config or DaemonConfig(**overrides)
        zenoh_settings = (zenoh_on or (lambda p: loopback(listen_port=p)))(self.port)
        update: dict[str, object] = {"zenoh": zenoh_settings}
        if "state_dir" not in base.model_fields_set:
            update["state_dir"] = None  # a test or demo never writes the system's state
        self.config = base.model_copy(update=update)
        self.daemon = Daemon(self.config, observers=observers)
        self._loop = uvloop.new_event_loop()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._main, name="guidebelt-daemon", daemon=True)

    def _main(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self.daemon.run(install_signals=False))
        except BaseException as exc:  # reported by __enter__/__exit__
            self._error = exc
            self.daemon.ready.set()
        finally:
            self._loop.close()

    def __enter__(self) -> DaemonThread:
        self._thread.start()
        # A fresh checkout compiles every kernel before READY (the warm-up): minutes on a
        # slow machine, and nothing may be left running if it never comes up.
        if not self.daemon.ready.wait(START_TIMEOUT_S) or self._error is not None:
            with contextlib.suppress(RuntimeError):
                self.stop(timeout_s=START_TIMEOUT_S)
            raise RuntimeError(f"daemon did not start: {self._error!r}")
        return self

    def peer(self) -> zenoh.Session:
        return open_peer(self.port)

    def call(self, fn: Callable[..., T], *args: object) -> T | None:
        """Run ``fn(*args)`` on the daemon's loop and return its result."""
        done = threading.Event()
        box: dict = {}

        def run() -> None:
            try:
                box["v"] = fn(*args)
            except BaseException as exc:
                box["e"] = exc
            done.set()

        self._loop.call_soon_threadsafe(run)
        done.wait(5.0)
        if "e" in box:
            raise box["e"]
        return box.get("v")

    def stop(self, timeout_s: float = 5.0) -> None:
        if self._thread.is_alive():
            self._loop.call_soon_threadsafe(self.daemon.stop)
            self._thread.join(timeout_s)
        if self._thread.is_alive():
            raise RuntimeError("daemon thread did not stop")

    def __exit__(self, *exc: object) -> None:
        self.stop()
