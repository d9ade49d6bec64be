"""Concurrent calls combined into one post (flat combining; databases call it group commit).

The daemon steps each user on a thread of its own (``daemon/service/runner.py``), and each
step is one ``update_and_path``. The device serves several users' steps side by side in one
post (``batch.py``), so calls that arrive together are combined here, without the daemon
knowing:

- A call that finds no post in flight leads: it posts itself alone, at once. One thread on
  its own pays a lock and a flag for this and waits for nothing: no timer, no window.
- A call that arrives while a post is in flight queues, and its thread blocks.
- When the post returns, its leader hands each of its calls its own result or its own
  exception, and, if calls are queued, hands the lead to the first of them. That thread posts
  the queue's first ``limit`` calls (one per key: a planner has one call in flight) as one
  post, and so on.

**The bound.** A call waits for the post in flight when it arrives, then for the posts of the
calls queued ahead of it, ``ceil(ahead / limit)`` of them, then for its own: with ``T``
threads calling (the daemon's step slots, one per core) at most ``ceil(T / limit) + 1`` posts,
each as long as its slowest call, plus one thread wake-up per hand-over. At 16 threads and
16 calls a post: the post in flight and its own.

A leader hands the lead on rather than posting the queue itself, so its own call's latency is
its post's alone; nothing here starts a thread.

**The GIL.** A post's wait spins on a mapped word, holding the GIL: a thread whose step falls
due meanwhile could not even queue it. So once calls have been seen to queue (``contended``)
the wait yields the GIL every ~256 polls (``resident.wait``'s ``share``); a thread that steps
alone never yields, since a yield that lets another thread in is a ``sleep(0)``, 50-70 µs of
Linux's timer slack.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from typing import Any, Generic, TypeVar

T = TypeVar("T")

CONTENDED_POSTS = 64
"""Posts after a call last queued during which the combiner counts as contended."""


class _Call(Generic[T]):
    __slots__ = ("failed", "item", "key", "lead", "outcome", "wake")

    def __init__(self, item: T, key: Hashable) -> None:
        self.item, self.key = item, key
        self.outcome: Any = None
        self.failed = False
        self.lead: list[_Call[T]] | None = None
        """Set when this call's thread is to post these calls (itself first)."""
        self.wake: threading.Lock | None = None
        """Held while the call waits in the queue; released when it is served or leads (a
        bare lock is a cheaper one-shot signal than an Event)."""

    def result(self) -> Any:
        if self.failed:
            raise self.outcome
        return self.outcome


class Combiner(Generic[T]):
    """``call(item)`` from any thread: ``post(items)`` runs for batches of concurrent calls,
    one post at a time, and must return one result or exception per item, in order.
    ``limit()`` is how many items a post takes (asked when a queue is there to split);
    ``key(item)`` items of one key never share a post. ``solo(item)``, if given, posts a call
    that found no post in flight: it returns that call's result or raises (as ``post([item])``
    would have said it), without the lists."""

    def __init__(
        self,
        post: Callable[[list[T]], list[Any]],
        limit: Callable[[], int],
        key: Callable[[T], Hashable] = id,
        solo: Callable[[T], Any] | None = None,
    ) -> None:
        self._post, self._limit, self._key = post, limit, key
        self._solo = solo if solo is not None else self._solo_by_post
        self._lock = threading.Lock()
        self._busy = False
        self._queue: list[_Call[T]] = []
        self.posts = 0
        """Posts made, and calls they held (statistics: the mean batch is calls / posts)."""
        self.calls = 0
        self._queued_at = -CONTENDED_POSTS
        """``posts`` when a call last had to queue."""

    @property
    def contended(self) -> bool:
        """Whether a call queued within the last ``CONTENDED_POSTS`` posts: other threads call
        too, and a post's wait should let them have the GIL to queue (``resident.wait``)."""
        return self.posts - self._queued_at < CONTENDED_POSTS

    def call(self, item: T) -> Any:
        with self._lock:
            alone = not self._busy
            self._busy = True
            if not alone:
                me = _Call(item, self._key(item))
                me.wake = threading.Lock()
                me.wake.acquire()
                self._queue.append(me)
                self._queued_at = self.posts
        if alone:
            # No post in flight: this one at once, with as little as can be on the way (a
            # step at 400² costs the host ~35 µs in all).
            self.posts += 1
            self.calls += 1
            try:
                return self._solo(item)
            finally:  # no waiter may be left blocked, whatever the post raised
                self._hand_on()
        me.wake.acquire()  # blocks until served, or handed the lead
        if me.lead is not None:
            self._serve(me.lead)
        return me.result()

    def _solo_by_post(self, item: T) -> Any:
        (out,) = self._post([item])
        if isinstance(out, BaseException):
            raise out
        return out

    def _serve(self, batch: list[_Call[T]]) -> None:
        self.posts += 1
        self.calls += len(batch)
        try:
            outcomes = self._post([c.item for c in batch])
            if len(outcomes) != len(batch):
                raise RuntimeError(f"post returned {len(outcomes)} results for {len(batch)}")
            failed = [isinstance(o, BaseException) for o in outcomes]
        except BaseException as exc:  # no waiter may be left blocked
            outcomes, failed = [exc] * len(batch), [True] * len(batch)
        # The lead first: the next post starts before the served threads compete to return.
        self._hand_on()
        for c, o, f in zip(batch, outcomes, failed, strict=True):
            c.outcome, c.failed = o, f
            if c.wake is not None and c.lead is None:
                c.wake.release()
            c.lead = None

    def _hand_on(self) -> None:
        with self._lock:
            if not self._queue:
                self._busy = False
                return
            try:
                limit = max(1, self._limit())
            except Exception:  # a lead must pass on, whatever the sizing says
                limit = 1
            batch: list[_Call[T]] = []
            keys: set[Hashable] = set()
            rest: list[_Call[T]] = []
            for c in self._queue:
                if len(batch) < limit and c.key not in keys:
                    keys.add(c.key)
                    batch.append(c)
                else:
                    rest.append(c)
            self._queue = rest
        head = batch[0]
        head.lead = batch
        head.wake.release()  # type: ignore[union-attr]  # queued calls hold a wake lock
