"""A user's worker thread: runs what the loop hands it in order, on one thread, settles the
loop's futures with results and exceptions, and ends when closed."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from daemon.service.step_thread import StepThread


@pytest.mark.timeout(10)
def test_runs_in_order_on_its_own_thread_and_ends_when_closed():
    async def main() -> None:
        worker = StepThread("plan-test")
        seen: list[tuple[int, str]] = []

        def step(i: int) -> int:
            time.sleep(0.001 * (5 - i))  # the first given is slowest: order, not speed
            seen.append((i, threading.current_thread().name))
            return i * i

        results = await asyncio.gather(*(worker.run(step, i) for i in range(5)))
        assert results == [0, 1, 4, 9, 16]
        assert seen == [(i, "plan-test") for i in range(5)]

        def fail() -> None:
            raise ValueError("bad step")

        with pytest.raises(ValueError, match="bad step"):
            await worker.run(fail)
        assert await worker.run(step, 3) == 9  # a failure does not end the thread
        last = worker.run(step, 4)
        worker.close()
        assert await last == 16  # given before the close: still run
        assert worker.run(step, 1).cancelled()
        deadline = time.monotonic() + 2.0
        while any(t.name == "plan-test" for t in threading.enumerate()):
            assert time.monotonic() < deadline, "the thread did not end"
            await asyncio.sleep(0.01)

    asyncio.run(main())
