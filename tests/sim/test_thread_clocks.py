"""``host_clocks`` reads every thread's CPU time from ``/proc``; a thread may end meanwhile."""

from __future__ import annotations

import os
import threading

from sim import thread_clocks


def test_a_thread_that_ends_during_the_read_leaves_the_others_listed(monkeypatch) -> None:
    listdir = os.listdir

    def with_a_gone_thread(path: str) -> list[str]:
        names = listdir(path)
        # A thread listed, then gone before its stat is read: first in the order read.
        return ["999999999", *names] if path == "/proc/self/task" else names

    monkeypatch.setattr(thread_clocks.os, "listdir", with_a_gone_thread)
    clocks = thread_clocks.host_clocks()
    assert any(k.endswith(f":{threading.get_native_id()}") for k in clocks)
    assert not any(k.endswith(":999999999") for k in clocks)
    assert "steal" in clocks
