"""The combining of concurrent calls into posts (``cuda/combine.py``), with a fake device
call: runs without a GPU. Threads are real; a post that must stay in flight waits on a gate.
"""

from __future__ import annotations

import random
import threading
import time

import pytest

from daemon.planning.cuda.combine import Combiner

pytestmark = pytest.mark.timeout(30)


class FakeDevice:
    """A post: each item's result is ``("done", item)``; an item ``("fail", x)`` is its own
    ValueError; the whole post raises when an item is ``"crash"``. Records every post, and
    checks that no two overlap."""

    def __init__(self) -> None:
        self.posts: list[list] = []
        self.gate = threading.Event()
        self.gate.set()
        self.entered = threading.Event()
        self._in = False

    def post(self, items: list) -> list:
        assert not self._in, "two posts at once"
        self._in = True
        try:
            self.posts.append(list(items))
            self.entered.set()
            self.gate.wait(10)
            if "crash" in items:
                raise RuntimeError("the device fell over")
            return [ValueError(it[1]) if it[0] == "fail" else ("done", it) for it in items]
        finally:
            self._in = False


def key(item) -> object:
    return item[1] if isinstance(item, tuple) else item


def queued(c: Combiner, n: int) -> None:
    deadline = time.monotonic() + 10
    while len(c._queue) < n:
        assert time.monotonic() < deadline, "the calls never queued"
        time.sleep(0.001)


def call_in_thread(c: Combiner, item, out: dict) -> threading.Thread:
    def run() -> None:
        try:
            out[item] = c.call(item)
        except Exception as exc:
            out[item] = exc

    t = threading.Thread(target=run)
    t.start()
    return t


def test_a_call_alone_is_posted_alone_at_once():
    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 16, key)
    for k in range(5):
        assert c.call(("u", k)) == ("done", ("u", k))
    assert dev.posts == [[("u", k)] for k in range(5)]
    assert not c._busy and not c._queue


def test_calls_made_during_a_post_go_together_as_the_next_posts():
    """One post in flight; seven calls from seven threads queue behind it and are posted in
    arrival order, ``limit`` at a time; each thread gets its own result."""
    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 3, key)
    dev.gate.clear()
    out: dict = {}
    first = call_in_thread(c, ("u", 0), out)
    assert dev.entered.wait(5)
    threads = []
    for k in range(1, 8):
        threads.append(call_in_thread(c, ("u", k), out))
        queued(c, k)  # one at a time: the queue's order is known
    dev.gate.set()
    for t in [first, *threads]:
        t.join(5)
    assert [len(p) for p in dev.posts] == [1, 3, 3, 1]
    assert [it for p in dev.posts for it in p] == [("u", k) for k in range(8)]
    assert out == {("u", k): ("done", ("u", k)) for k in range(8)}
    assert (c.posts, c.calls) == (4, 8) and not c._busy


def test_a_key_never_twice_in_a_post():
    """Two calls of one planner (key) queued: the second waits for the post after."""
    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 16, key)
    dev.gate.clear()
    out: dict = {}
    threads = [call_in_thread(c, ("a", 0), out)]
    assert dev.entered.wait(5)
    for n, item in enumerate([("a", 1), ("b", 2), ("c", 1)], start=1):
        threads.append(call_in_thread(c, item, out))
        queued(c, n)
    dev.gate.set()
    for t in threads:
        t.join(5)
    assert dev.posts == [[("a", 0)], [("a", 1), ("b", 2)], [("c", 1)]]
    assert len(out) == 4


def test_a_failure_reaches_its_own_caller_alone():
    """An item's exception is raised in its thread only; a post that raises fails the calls
    it held, and the calls queued behind it are still served."""
    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 16, key)
    dev.gate.clear()
    out: dict = {}
    threads = [call_in_thread(c, ("u", 0), out)]
    assert dev.entered.wait(5)
    for n, item in enumerate([("u", 1), ("fail", 2), ("u", 3)], start=1):
        threads.append(call_in_thread(c, item, out))
        queued(c, n)
    dev.gate.set()
    for t in threads:
        t.join(5)
    assert isinstance(out[("fail", 2)], ValueError)
    assert [out[("u", k)] for k in (0, 1, 3)] == [("done", ("u", k)) for k in (0, 1, 3)]

    dev.gate.clear()
    dev.entered.clear()
    out.clear()
    threads = [call_in_thread(c, ("u", 0), out)]
    assert dev.entered.wait(5)
    threads += [call_in_thread(c, "crash", out)]
    queued(c, 1)
    threads += [call_in_thread(c, ("u", 1), out)]
    queued(c, 2)
    dev.gate.set()
    for t in threads:
        t.join(5)
    assert out[("u", 0)] == ("done", ("u", 0))
    assert isinstance(out["crash"], RuntimeError) and isinstance(out[("u", 1)], RuntimeError)
    assert c.call(("u", 9)) == ("done", ("u", 9)) and not c._busy


def test_many_threads_at_random_every_call_its_own_result_and_no_thread_left():
    """Eight threads call 150 times each at random moments: every result is the caller's,
    posts never overlap nor exceed the limit nor repeat a key, and the combiner starts no
    thread of its own."""
    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 4, key)
    before = set(threading.enumerate())
    wrong: list = []

    def user(u: int) -> None:
        rng = random.Random(u)
        for k in range(150):
            if rng.random() < 0.3:
                time.sleep(rng.random() * 1e-4)
            if c.call((u, k)) != ("done", (u, k)):
                wrong.append((u, k))

    threads = [threading.Thread(target=user, args=(u,)) for u in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(20)
    assert not wrong
    assert c.calls == 8 * 150 and not c._busy and not c._queue
    assert all(len(p) <= 4 and len({it[0] for it in p}) == len(p) for p in dev.posts)
    assert set(threading.enumerate()) == before


def test_contended_once_calls_queue_and_again_not_after_posts_alone():
    """A thread alone never makes the combiner contended (its waits never yield the GIL); a
    call that queues does, until ``CONTENDED_POSTS`` posts have gone by."""
    from daemon.planning.cuda.combine import CONTENDED_POSTS

    dev = FakeDevice()
    c = Combiner(dev.post, lambda: 16, key)
    for k in range(3):
        c.call(("u", k))
    assert not c.contended
    dev.gate.clear()
    out: dict = {}
    threads = [call_in_thread(c, ("u", 0), out)]
    assert dev.entered.wait(5)
    threads.append(call_in_thread(c, ("u", 1), out))
    queued(c, 1)
    assert c.contended
    dev.gate.set()
    for t in threads:
        t.join(5)
    alone = 0
    while c.contended:
        c.call(("u", alone))
        alone += 1
    # the queued call's own post counts as one of them
    assert alone == CONTENDED_POSTS - 1


def test_a_call_alone_goes_to_solo_and_a_queue_behind_it_to_post():
    """With ``solo`` (the cuda backend's single step), a call that finds no post in flight is
    solo's: its result returned, its exception raised in its own thread, and the combiner
    free again either way; calls that queue behind it still go together through ``post``."""
    dev = FakeDevice()
    solos: list = []

    def solo(item):
        solos.append(item)
        (out,) = dev.post([item])
        if isinstance(out, BaseException):
            raise out
        return out

    c = Combiner(dev.post, lambda: 16, key, solo=solo)
    assert c.call(("u", 0)) == ("done", ("u", 0))
    with pytest.raises(ValueError):
        c.call(("fail", 1))
    assert solos == [("u", 0), ("fail", 1)] and not c._busy
    dev.gate.clear()
    out: dict = {}
    threads = [call_in_thread(c, ("u", 2), out)]
    assert dev.entered.wait(5)
    for n, item in enumerate([("u", 3), ("v", 4)], start=1):
        threads.append(call_in_thread(c, item, out))
        queued(c, n)
    dev.gate.set()
    for t in threads:
        t.join(5)
    assert solos[-1] == ("u", 2) and dev.posts[-1] == [("u", 3), ("v", 4)]
    assert out == {it: ("done", it) for it in [("u", 2), ("u", 3), ("v", 4)]}
    assert not c._busy and not c._queue
