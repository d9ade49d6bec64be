"""One user's worker thread: it waits for its own turn, steps, and between steps runs what
the loop hands it, in order, settling an asyncio future with each result.

The thread owns its pacing (``UserRunner._serve``): it sleeps on its own queue until an input
rings it or its step period has passed, so a step costs the loop nothing. Before, the loop
waited out each user's period (``asyncio.wait_for``: a task and a timer), handed the step
over and was woken again with its result: two thread hand-overs and ~100 µs of the loop's
Python a step, ~25,000 context switches a second at 50 users (dev VM, round 14). The queue is a
``queue.SimpleQueue`` (C: ``put`` and a timed ``get`` that releases the GIL), not a
``Condition`` (Python); a job's result comes back with one ``call_soon_threadsafe``.
"""

from __future__ import annotations

import asyncio
import contextlib
import queue
import threading
from collections.abc import Callable
from typing import Any

_STOP = object()
_RING = object()
"""Wakes the thread to look at its inputs again (a ring it no longer needs is harmless)."""


def _settle(future: asyncio.Future, ok: bool, value: Any) -> None:
    if future.cancelled():
        return
    if ok:
        future.set_result(value)
    else:
        future.set_exception(value)


class StepThread:
    """A thread that runs ``serve()`` and, whenever ``serve`` waits (``wait``, ``poll``), the
    callables the loop gives it, in the order given. ``close`` ends it once those given
    before have run. ``run`` and ``close`` come from the loop's thread; ``ring`` from any."""

    def __init__(self, name: str, serve: Callable[[], None] | None = None) -> None:
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._closed = False
        self._stopped = False
        """The thread has taken the stop: ``serve`` must return."""
        self._serve = serve or self._idle
        self._thread = threading.Thread(target=self._main, name=name, daemon=True)

    def start(self) -> StepThread:
        """Start the thread (once whoever ``serve`` belongs to holds this object)."""
        self._thread.start()
        return self

    def run(self, fn: Callable[..., Any], *args: Any) -> asyncio.Future:
        """``fn(*args)`` on this thread; its result (or exception) in the returned future."""
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        if self._closed:
            future.cancel()
        else:
            self._queue.put((loop, future, fn, args))
        return future

    @property
    def alive(self) -> bool:
        """The thread runs and has not been told to stop."""
        return self._thread.is_alive() and not self._stopped

    def ring(self) -> None:
        """Wake the thread from ``wait`` (any thread)."""
        self._queue.put(_RING)

    def close(self) -> None:
        """No more work: the thread ends after what it was given (a later ``run`` is
        cancelled at once)."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)

    # -- on the thread --------------------------------------------------------------------

    def wait(self, timeout: float | None) -> bool:
        """Sleep until rung, a job has run, or ``timeout`` seconds have passed (None: no
        limit). False once the thread is told to stop."""
        if self._stopped:
            return False
        if timeout is not None and timeout <= 0:
            return self.poll()
        try:
            item = self._queue.get(timeout=timeout)
        except queue.Empty:
            return True
        self._take(item)
        return not self._stopped

    def poll(self) -> bool:
        """Run the jobs given so far without waiting; False once told to stop."""
        while not self._stopped:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            self._take(item)
        return not self._stopped

    def _take(self, item: Any) -> None:
        if item is _STOP:
            self._stopped = True
        elif item is not _RING:
            loop, future, fn, args = item
            try:
                ok, value = True, fn(*args)
            except BaseException as exc:  # the awaiting coroutine decides what it means
                ok, value = False, exc
            with contextlib.suppress(RuntimeError):  # the loop closed: nobody awaits it
                loop.call_soon_threadsafe(_settle, future, ok, value)

    def _idle(self) -> None:
        while self.wait(None):
            pass

    def _main(self) -> None:
        try:
            self._serve()
        finally:
            # Jobs given before the stop still run (a user's last words are one).
            while not self._stopped:
                self._take(self._queue.get())
