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
        worker = StepThread("plan-test").start()
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


@pytest.mark.timeout(10)
def test_the_thread_paces_itself_a_ring_wakes_it_and_jobs_run_while_it_waits():
    async def main() -> None:
        woke: list[tuple[str, float]] = []
        worker: StepThread

        def serve() -> None:
            t0 = time.monotonic()
            assert worker.wait(0.05)  # nobody rings: the period passes
            woke.append(("timeout", time.monotonic() - t0))
            t0 = time.monotonic()
            assert worker.wait(5.0)  # rung long before the 5 s
            woke.append(("ring", time.monotonic() - t0))
            while worker.wait(None):  # jobs, then the stop
                pass
            woke.append(("stopped", 0.0))

        worker = StepThread("plan-paced", serve)
        worker.start()
        # Rung once its first wait has timed out (not after a fixed 0.2 s: a thread started
        # late on a loaded machine would be rung before that wait, and not time out).
        deadline = time.monotonic() + 5.0
        while not woke:
            assert time.monotonic() < deadline, "the first wait never timed out"
            await asyncio.sleep(0.01)
        worker.ring()
        assert await worker.run(threading.current_thread) is not threading.current_thread()
        worker.close()
        deadline = time.monotonic() + 2.0
        while len(woke) < 3:
            assert time.monotonic() < deadline, "the thread did not stop"
            await asyncio.sleep(0.01)
        assert woke[0][0] == "timeout" and woke[0][1] >= 0.05
        assert woke[1][0] == "ring" and woke[1][1] < 1.0
        assert woke[2][0] == "stopped"

    asyncio.run(main())


@pytest.mark.timeout(10)
def test_steps_recorded_on_worker_threads_reach_admission_only_when_the_loop_flushes():
    from daemon.service.pacing import Pacing

    got: list[tuple[str, float, float, float, bool, str]] = []
    pacing = Pacing(record=lambda *a: got.append((*a, threading.current_thread().name)))
    workers = [
        threading.Thread(target=pacing.record, args=(f"u{i}", 5.0, 0.5, i != 1), name=f"plan-u{i}")
        for i in range(3)
    ]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert got == []  # nothing touched on the workers' threads
    before = time.monotonic()
    pacing.flush()
    assert sorted(u for u, *_ in got) == ["u0", "u1", "u2"]
    assert all(lag == 5.0 and cpu == 0.5 and at <= before for _, lag, cpu, at, _, _ in got)
    assert {u: urgent for u, _, _, _, urgent, _ in got} == {"u0": True, "u1": False, "u2": True}
    assert {name for *_, name in got} == {threading.current_thread().name}
    pacing.flush()
    assert len(got) == 3  # each step once
