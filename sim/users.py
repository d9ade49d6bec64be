"""Many users on one planner backend (issue 28): ``guidebelt bench --users N``.

Each user walks its own seeded scenario once with the daemon's navigator on the CPU, and the
planner calls that walk made (``plan``, then ``update_and_path`` with each step's delta and
the user's cell; ``update`` and ``path`` where the walk made them) are recorded. The bench
then gives every user a planner of the backend under test and replays the users' calls:

- ``round-robin``: user 0's step, user 1's, ..., as the daemon's sessions take turns; a
  step's latency is its own call's wall clock.
- ``rate`` (``--rate HZ``): every user steps at HZ, the users' phases spread evenly over a
  period; one host thread serves the steps in the order they fall due, so a step's latency is
  from when it fell due to when its call returned: the wait behind other users' steps
  included. On cuda the steps due when the host comes round go to the device as one batch
  (``daemon/planning/cuda/batch.py``: served side by side); on cpu one after another. Users
  whose walk is done start it again (their planner plans from scratch).
- ``rate threads`` (``--rate HZ --threads``): the same steps, each user on a thread of its
  own as the daemon runs them; on cuda the calls that meet combine into shared posts.

Every replayed path must equal the recorded one, which the CPU planner read from its exact
field (its contract, tested against the reference Dijkstra): a mismatch ends the bench with
an error. With more users than ``walks`` recorded, user ``i`` replays walk ``i % walks``
with a planner of its own.
"""

from __future__ import annotations

import heapq
import pickle
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .courtyard import Scenario
from .walk import paper_settings, walk


@dataclass
class Recording:
    """One walk's planner calls: (``plan``, blocked, goal), (``step``, cells, values, cell,
    path), (``update``, cells, values) or (``path``, cell, path)."""

    ops: list[tuple] = field(default_factory=list)

    @property
    def steps(self) -> int:
        return sum(op[0] == "step" for op in self.ops)


class _Recorder:
    """The navigator's planner, every call recorded (copies: the navigator reuses arrays)."""

    def __init__(self, planner: Any, rec: Recording) -> None:
        self._p, self._rec = planner, rec

    def __getattr__(self, name: str) -> Any:
        return getattr(self._p, name)

    def plan(self, blocked: np.ndarray, goal: tuple[int, int]) -> Any:
        self._rec.ops.append(("plan", np.array(blocked, copy=True), tuple(goal)))
        return self._p.plan(blocked, goal)

    def update(self, cells: np.ndarray, values: np.ndarray) -> Any:
        self._rec.ops.append(("update", np.array(cells), np.array(values)))
        return self._p.update(cells, values)

    def update_and_path(self, cells: np.ndarray, values: np.ndarray, start: Any) -> Any:
        stats, path = self._p.update_and_path(cells, values, start)
        cell = (int(start[0]), int(start[1]))
        self._rec.ops.append(("step", np.array(cells), np.array(values), cell, path.copy()))
        return stats, path

    def path(self, start: Any) -> np.ndarray:
        path = self._p.path(start)
        self._rec.ops.append(("path", (int(start[0]), int(start[1])), path.copy()))
        return path


_RECORDED: dict[tuple, Recording] = {}


def record(scenario: Scenario, max_steps: int | None = None) -> Recording:
    """The planner calls of one EDS walk of ``scenario`` on the CPU (kept for the process:
    rows for several user counts replay the same walks)."""
    from daemon.navigation import Navigator

    key = (scenario.name, scenario.shape, scenario.unknown, scenario.seed, max_steps)
    if key in _RECORDED:
        return _RECORDED[key]

    rec = Recording()
    nav = Navigator("rec", paper_settings(scenario, "eds", "cpu", "fast"))
    nav.route.planner = _Recorder(nav.route.planner, rec)
    walk(scenario, backend="cpu", mode="eds", max_steps=max_steps, navigator=nav)
    _RECORDED[key] = rec
    return rec


class Replay:
    """One user: a planner and the recording it replays, op by op."""

    def __init__(self, planner: Any, rec: Recording, user: int) -> None:
        self.p, self.rec, self.user = planner, rec, user
        self.at = 0
        self.laps = 0

    def until_step(self) -> tuple | None:
        """Run the ops before the next step (untimed); the step, or None at the walk's end."""
        while self.at < len(self.rec.ops):
            op = self.rec.ops[self.at]
            self.at += 1
            if op[0] == "step":
                return op
            if op[0] == "plan":
                self.p.plan(op[1], op[2])
            elif op[0] == "update":
                self.p.update(op[1], op[2])
            else:
                self.check(self.p.path(op[1]), op[2])
        return None

    def step(self, op: tuple) -> float:
        """The step's call; its wall clock in ms. Then the planner's work left for between
        steps, untimed, as the daemon's runner does it once a step's output is out."""
        t0 = time.perf_counter()
        _, path = self.p.update_and_path(op[1], op[2], op[3])
        ms = (time.perf_counter() - t0) * 1e3
        self.check(path, op[4])
        self.p.between_steps()
        return ms

    def check(self, path: np.ndarray, want: np.ndarray) -> None:
        if not np.array_equal(path, want):
            raise AssertionError(f"user {self.user}: a replayed path differs from the CPU's")


def spread(ms: np.ndarray) -> dict[str, float]:
    if ms.size == 0:
        return {"median": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {
        "median": float(np.median(ms)),
        "p99": float(np.percentile(ms, 99)),
        "max": float(ms.max()),
    }


def round_robin(users: list[Replay]) -> dict[str, Any]:
    """Every user's walk once, one step each in turn."""
    ms: list[float] = []
    live = list(users)
    t0 = time.perf_counter()
    while live:
        for u in list(live):
            op = u.until_step()
            if op is None:
                live.remove(u)
                continue
            ms.append(u.step(op))
    total = time.perf_counter() - t0
    arr = np.asarray(ms)
    return {"steps": int(arr.size), "total_s": total, "steps_per_s": arr.size / total,
            **spread(arr)}  # fmt: skip


def at_rate(
    users: list[Replay],
    hz: float,
    seconds: float,
    batch: Callable[[list], list] | None = None,
    between: Callable[[list], list] | None = None,
) -> dict[str, Any]:
    """Every user steps at ``hz`` for ``seconds``; latency from due to done. With ``batch``
    (``cuda.batch.step_many``), the steps due when the host comes round go to it together
    (their latency ends when the batch returns), then their planners' work for between steps
    to ``between`` (``cuda.batch.between_steps_many``; default: each planner's own); else one
    after another."""
    n = len(users)
    period = 1.0 / hz
    # (due, user): the users' phases spread over a period; a heap, since a scan of 1,000
    # users per step would cost the host ~50 µs of the ~100 µs a step may take at 10 kHz.
    # Due times are multiplied out, not summed: a sum drifts and lets a step more in.
    queue = [(k * period / n, k, 0) for k in range(n)]
    ops = [u.until_step() for u in users]
    late: list[float] = []
    own: list[float] = []
    sizes: list[int] = []
    t0 = time.perf_counter()
    while queue[0][0] < seconds:
        while time.perf_counter() - t0 < queue[0][0]:
            pass  # wait for the step to fall due: a sleep's timer slack is ~50 µs
        now = time.perf_counter() - t0
        due = [heapq.heappop(queue)]
        while batch is not None and queue and queue[0][0] <= now:
            due.append(heapq.heappop(queue))
        for _, k, _ in due:
            if ops[k] is None:  # the walk is done: again from its plan
                u = users[k]
                u.at, u.laps = 0, u.laps + 1
                ops[k] = u.until_step()
                assert ops[k] is not None
        if batch is None:
            own.append(users[due[0][1]].step(ops[due[0][1]]))
            late.append((time.perf_counter() - t0 - due[0][0]) * 1e3)
        else:
            b0 = time.perf_counter()
            results = batch([(users[k].p, *ops[k][1:4]) for _, k, _ in due])
            done = time.perf_counter()
            for (when, k, _), res in zip(due, results, strict=True):
                if isinstance(res, BaseException):
                    raise res
                users[k].check(res[1], ops[k][4])
                late.append((done - t0 - when) * 1e3)
                own.append((done - b0) * 1e3)
            # after the batch's answers, as the daemon after its outputs: posted together
            planners = [users[k].p for _, k, _ in due]
            for res in between(planners) if between else [p.between_steps() for p in planners]:
                if isinstance(res, BaseException):
                    raise res
            sizes.append(len(due))
        for _, k, j in due:
            ops[k] = users[k].until_step()
            heapq.heappush(queue, (k * period / n + (j + 1) * period, k, j + 1))
    total = time.perf_counter() - t0
    lat = np.asarray(late)
    row = {"hz": hz, "seconds": total, "steps": int(lat.size), "steps_per_s": lat.size / total,
           "kept_up": kept_up(lat, total, n * hz, period * 1e3),
           **spread(lat), "own": spread(np.asarray(own))}  # fmt: skip
    if sizes:
        row["batches"] = len(sizes)
        row["batch_mean"] = float(np.mean(sizes))
        row["batch_max"] = int(max(sizes))
    return row


def at_rate_threads(users: list[Replay], hz: float, seconds: float) -> dict[str, Any]:
    """``at_rate`` as the daemon serves its users: each user on a thread of its own
    (``daemon/service/runner.py``), sleeping until its step falls due and then calling its
    planner's ``update_and_path``; the cuda backend combines the calls that meet on the device
    into shared posts (``daemon/planning/cuda/combine.py``). Latency from due to the call's
    return, the thread's wake-up and its wait for the GIL included."""
    n = len(users)
    period = 1.0 / hz
    late: list[list[float]] = [[] for _ in range(n)]
    own: list[list[float]] = [[] for _ in range(n)]
    failed: list[BaseException] = []
    ready = threading.Barrier(n + 1)
    t0 = 0.0

    def run(k: int) -> None:
        u = users[k]
        op = u.until_step()
        ready.wait()
        try:
            for j in range(int(seconds * hz) + 1):
                due = k * period / n + j * period
                if due >= seconds or failed:
                    break
                if op is None:  # the walk is done: again from its plan
                    u.at, u.laps = 0, u.laps + 1
                    op = u.until_step()
                    assert op is not None
                wait = t0 + due - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                b0 = time.perf_counter()
                _, path = u.p.update_and_path(op[1], op[2], op[3])
                done = time.perf_counter()
                u.check(path, op[4])
                late[k].append((done - t0 - due) * 1e3)
                own[k].append((done - b0) * 1e3)
                u.p.between_steps()
                op = u.until_step()
        except BaseException as exc:
            failed.append(exc)

    threads = [threading.Thread(target=run, args=(k,), name=f"user-{k}") for k in range(n)]
    for t in threads:
        t.start()
    t0 = time.perf_counter() + 0.05  # every thread at its first sleep before the first step
    ready.wait()
    for t in threads:
        t.join()
    total = time.perf_counter() - t0
    if failed:
        raise failed[0]
    lat = np.concatenate([np.asarray(v) for v in late])
    return {"hz": hz, "seconds": total, "steps": int(lat.size), "steps_per_s": lat.size / total,
            "kept_up": kept_up(lat, total, n * hz, period * 1e3),
            **spread(lat), "own": spread(np.concatenate([np.asarray(v) for v in own]))}  # fmt: skip


def kept_up(late_ms: np.ndarray, total_s: float, due_per_s: float, period_ms: float) -> bool:
    """Whether the device kept up with the users: it served the steps at the rate they fell
    due, and 99 % of them within one period of falling due. Every due step is served in the
    end (the run goes on past its seconds), so a count alone says nothing: at 1,000 users a
    backlog grew to ~0.5 s while all 10,000 a second were served."""
    if late_ms.size == 0:
        return False
    at_rate = late_ms.size / total_s >= 0.95 * due_per_s
    return bool(at_rate and np.percentile(late_ms, 99) <= period_ms)


def memory_per_user(planner: Any) -> dict[str, int]:
    """Bytes a user's planner holds: device memory, and page-locked host memory (cuda)."""
    out = {"device_bytes": int(getattr(planner, "device_bytes", lambda: 0)())}
    from daemon.planning.deferred_blocks import DeferredBlocks

    if isinstance(planner, DeferredBlocks):  # EDS's wrapper holds no buffers of its own
        planner = planner.inner
    # The cuda backend's EDS wraps the planner that serves the map (small_grids.py), whose
    # private buffers its attribute lookup does not pass on.
    planner = getattr(planner, "_serving", None) or planner
    pinned = [getattr(planner, n, None) for n in ("_io_host", "_stage")]
    out["pinned_bytes"] = int(sum(p.array.nbytes for p in pinned if p is not None))
    return out


def run_users(
    scenario_name: str,
    grid: int,
    unknown: float,
    backend: str,
    users: int,
    *,
    seed: int = 0,
    walks: int = 16,
    max_steps: int | None = None,
    hz: float | None = None,
    seconds: float = 10.0,
    cache: Path | None = None,
    threads: bool = False,
) -> dict[str, Any]:
    """Record ``min(users, walks)`` walks (seeds ``seed``, ``seed + 1``, ...), give each of
    ``users`` users a planner of ``backend`` and replay them round-robin, or at ``hz`` each
    for ``seconds`` when given (``threads``: a thread per user, as the daemon). Returns the row
    for the JSON."""
    from daemon.planning.registry import make_planner

    from .benchmark import device_name
    from .scenarios import make_scenario

    if cache is not None and cache.exists():
        _RECORDED.update(pickle.loads(cache.read_bytes()))
    recs = [
        record(make_scenario(scenario_name, grid, unknown, seed + k), max_steps)
        for k in range(min(users, walks))
    ]
    if cache is not None:
        cache.write_bytes(pickle.dumps(_RECORDED))
    t0 = time.perf_counter()
    replays = [Replay(make_planner("eds", backend), recs[i % len(recs)], i) for i in range(users)]
    firsts = [u.until_step() for u in replays]  # every user's first plan, untimed
    for u, op in zip(replays, firsts, strict=True):
        if op is None:
            continue
        if hz is None:
            u.at -= 1  # the step itself is replayed by the run
        else:
            # At a rate, users walk on: their first step (every tile's path exits computed
            # for the first time) is taken here, as a venue's users join over time, not all
            # in the same period.
            u.step(op)
    setup_s = time.perf_counter() - t0
    row: dict[str, Any] = {
        "scenario": scenario_name, "grid": grid, "unknown": unknown, "backend": backend,
        "device": device_name(backend), "users": users, "walks": len(recs),
        "walk_steps": [r.steps for r in recs], "setup_s": setup_s,
        **memory_per_user(replays[0].p),
    }  # fmt: skip
    if hz is None:
        row["mode"] = "round-robin"
        row.update(round_robin(replays))
    elif threads:
        row["mode"] = "rate threads"
        before = _posts(backend)
        row.update(at_rate_threads(replays, hz, seconds))
        after = _posts(backend)
        if before is not None and after is not None:
            row["batches"] = after[0] - before[0]
            row["batch_mean"] = (after[1] - before[1]) / max(row["batches"], 1)
    else:
        row["mode"] = "rate" if backend != "cuda" else "rate batched"
        step_many = between_steps_many = None
        if backend == "cuda":
            from daemon.planning.cuda.batch import between_steps_many, step_many
        row.update(at_rate(replays, hz, seconds, step_many, between_steps_many))
    return row


def _posts(backend: str) -> tuple[int, int] | None:
    """The cuda backend's (posts, calls) so far: the threads' mean batch is their ratio."""
    if backend != "cuda":
        return None
    from daemon.planning.cuda.posting import STEPS

    return STEPS.posts, STEPS.calls
