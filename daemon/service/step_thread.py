"""One user's worker thread: runs what the loop hands it, in order, and settles an asyncio
future with the result.

What ``loop.run_in_executor`` on a one-thread ``ThreadPoolExecutor`` did, with less on the
way: an executor's ``submit`` takes two locks, builds a ``concurrent.futures.Future`` (a
``Condition`` of its own), puts on a ``queue.Queue`` (Python code, another ``Condition``) and
checks its idle semaphore; asyncio then chains that future to one of its own. Here the
item goes on a ``queue.SimpleQueue`` (C) and the result comes back with one
``call_soon_threadsafe``. Dispatch is paid on every step of every user: 20-23 µs of CPU a
step here against 39-54 µs through the executor (25 users × 400 empty steps under uvloop,
dev VM); a worker at 25 users spent ~10 % of its GIL time in ``submit`` (py-spy).
"""

from __future__ import annotations

import asyncio
import contextlib
import queue
import threading
from collections.abc import Callable
from typing import Any

_STOP = None


def _settle(future: asyncio.Future, ok: bool, value: Any) -> None:
    if future.cancelled():
        return
    if ok:
        future.set_result(value)
    else:
        future.set_exception(value)


class StepThread:
    """A thread that runs callables in the order given; ``close`` ends it once those given
    before have run. Every call comes from the loop's thread."""

    def __init__(self, name: str) -> None:
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._closed = False
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def run(self, fn: Callable[..., Any], *args: Any) -> asyncio.Future:
        """``fn(*args)`` on this thread; its result (or exception) in the returned future."""
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        if self._closed:
            future.cancel()
        else:
            self._queue.put((loop, future, fn, args))
        return future

    def close(self) -> None:
        """No more work: the thread ends after what it was given (a later ``run`` is
        cancelled at once)."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)

    def _serve(self) -> None:
        while (item := self._queue.get()) is not _STOP:
            loop, future, fn, args = item
            try:
                ok, value = True, fn(*args)
            except BaseException as exc:  # the awaiting coroutine decides what it means
                ok, value = False, exc
            with contextlib.suppress(RuntimeError):  # the loop closed: nobody awaits it
                loop.call_soon_threadsafe(_settle, future, ok, value)
