"""Where a ``fast`` call's time goes, step by step of a walk: the device's phase stamps.

``fast.cu`` stamps the global timer at each phase boundary of a call (``abi.C_STAMP``, block
0 after the grid barrier that ends the phase; the last block at the end). This module walks
scenarios as the benchmark does (``sim.walk``), records every ``update_and_path`` call's
phases, statistics and own time, and prints, per walk, the median and p99 call and what the
calls at or above the p99 spent in each phase: the answer to "which steps make the tail".
The benchmark's "replanning step" is the navigator's ``Route.path_from`` around the call
(``s.`` columns); its p99 steps ("steps >= step p99") are split the same way, ``route``
being what ``path_from`` adds to the call.

    PYTHONPATH=. python3 scripts/profile_cuda_phases.py --grid 400,1000 \\
        --scenario courtyard,explore [--modes eds,dss] [--max-steps N] [--json out.json]
        [--per-call]
"""

from __future__ import annotations

import argparse
import gc
import json
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from daemon.planning.cuda import abi, planner, resident
from sim.thread_clocks import getcpu, host_clocks

STAMP_PHASES = ("take", "delta", "raise", "reset", "relax", "exits", "hops", "walk")
"""The phases between stamps 8, 0, 1, ..., 7: the loop's block 0 takes the posted delta from
host memory and publishes the call, the delta applied (round 0), the raise rounds, the reset
round (or the cut-over's clearing), the relaxation, the path's tile exits, the hops, the
segments walked and the result copied. A call without a path stamps ``exits`` and ``hops``
as empty. The host's share is the call's own time less these."""
HOST_PARTS = ("pre", "wait", "post", "gc", "route")
"""The host's clock around the call: its start to the post into the loop's box, the post to
the done word seen, the done word to the call's return; the garbage collector's time inside
the call (``gc.callbacks``); and the navigator's ``Route.path_from`` around the call (its own
time less the call's): the benchmark's "replanning step" is ``path_from``'s time, so
``route`` is what the bench adds to the call's own time."""

COUNTS = (
    *("cut", "cells", "launches", "raised", "rounds", "tiles", "exit_tiles", "track"),
    *("faults", "preempted", "waited", "off_cpu_us", "moved"),
)
"""Per-call figures the summary averages over each selection of calls."""


@dataclass
class CallLog:
    """Per call of one walk: own time (ms), phase times (µs), statistics."""

    ms: list[float] = field(default_factory=list)
    stamps: list[np.ndarray] = field(default_factory=list)
    """Per call: the 9 phase stamps as the device left them (``phases_us`` reads them)."""
    cut: list[int] = field(default_factory=list)
    cells: list[int] = field(default_factory=list)
    launches: list[int] = field(default_factory=list)
    raised: list[int] = field(default_factory=list)
    rounds: list[int] = field(default_factory=list)
    tiles: list[int] = field(default_factory=list)
    exit_tiles: list[int] = field(default_factory=list)
    host_us: list[list[float]] = field(default_factory=list)
    """Per call: before the post, the post to the done word seen, after it, the time the
    interpreter's garbage collector ran inside the call, and ``path_from`` around it (µs)."""
    step_ms: list[float] = field(default_factory=list)
    """Per call: its step's ``Route.path_from`` time (ms), what the benchmark records."""
    track: list[int] = field(default_factory=list)
    """Per call: cells on the route's track (``Track.add`` scanned them at every step, ~10 µs
    on the H100's host at 400 cells; a set lookup now, whatever the length)."""
    faults: list[int] = field(default_factory=list)
    """Per call: the thread's minor page faults during its step (``getrusage``, read outside
    the step's clock)."""
    preempted: list[int] = field(default_factory=list)
    """Per call: the thread's involuntary context switches during its step: a step the OS
    (or the hypervisor's vCPU, which this does not see) took the core from."""
    waited: list[int] = field(default_factory=list)
    """Per call: the thread's voluntary context switches during its step: it blocked (the GIL
    held by another thread, a futex, a sleep), as against ``preempted``."""
    off_cpu_us: list[float] = field(default_factory=list)
    cpu: list[int] = field(default_factory=list)
    """Per call: the CPU its step started on (``sched_getcpu``, outside the step's clock)."""
    moved: list[int] = field(default_factory=list)
    """Per call: 1 when its step started on another CPU than the last step ended on, or ended
    on another than it started on: the thread was migrated, into a core's cold caches and,
    in a virtual machine, onto a vCPU that may have idled at a low clock."""
    ended_on: int = -1
    at_s: list[float] = field(default_factory=list)
    """Per call: when its step ended (``perf_counter``, s): bursts of slow steps placed in
    time, to set beside the machine's own events."""
    """Per call: its step's wall time less the thread's CPU time in it (µs): time the thread did
    not run (preempted, or the vCPU stolen where the guest accounts steal). A stalled step
    with none ran slowly on the CPU (caches, TLB) rather than not at all."""

    def add(self, planner, ms: float, cells: int, launched: int, host_us=(0.0,) * 5) -> None:
        # Inside the step the bench times: only copies here, the arithmetic in ``summary``
        # (numpy's diff and casts here put ~50 µs into the timed steps, device run 2026-11-26
        # 23:42), and what remains is subtracted from the step (``routed``).
        self.stamps.append(planner._io_host.array[abi.C_STAMP : abi.C_STAMP + 9].copy())
        self.ms.append(ms)
        self.cells.append(cells)
        self.launches.append(launched)
        self.cut.append(int(planner.cut_cells > 0))
        self.raised.append(int(planner.raised_cells or planner.cut_cells))
        self.rounds.append(int(planner._result[abi.C_ROUNDS]))
        self.tiles.append(int(planner.tiles))
        self.exit_tiles.append(int(planner.exit_tiles))
        self.host_us.append(list(host_us))
        self.step_ms.append(ms)
        self.track.append(0)
        self.faults.append(0)
        self.preempted.append(0)
        self.waited.append(0)
        self.off_cpu_us.append(0.0)
        self.cpu.append(-1)
        self.moved.append(0)
        self.at_s.append(time.perf_counter())

    def routed(
        self,
        step_ms: float,
        call_ms: float,
        track: int,
        faults: int = 0,
        preempted: int = 0,
        cpu_ms: float | None = None,
        waited: int = 0,
        cpus: tuple[int, int] = (-1, -1),
    ) -> None:
        """The last call's step: ``step_ms`` as ``Route.path_from`` timed it, less the
        recording's own time inside it; ``call_ms`` the wrapped call's wall time (its own
        time plus the combiner's return)."""
        self.step_ms[-1] = step_ms
        self.track[-1] = track
        self.host_us[-1][4] = 1e3 * (step_ms - call_ms)
        self.faults[-1], self.preempted[-1], self.waited[-1] = faults, preempted, waited
        last = self.ended_on if self.ended_on >= 0 else cpus[0]
        self.cpu[-1], self.ended_on = cpus
        self.moved[-1] = int(cpus[0] != last or cpus[1] != cpus[0])
        if cpu_ms is not None:
            self.off_cpu_us[-1] = max(0.0, 1e3 * (step_ms - cpu_ms))

    def per_call(self) -> dict[str, list]:
        """Every call's figures (``--per-call``): which calls make a tail, not only its mean."""
        return {
            "ms": self.ms,
            "step_ms": self.step_ms,
            "phases_us": self.phases_us().round(2).tolist(),
            "host_us": np.round(np.asarray(self.host_us, np.float64), 2).tolist(),
            **{k: getattr(self, k) for k in ("cells", "cut", "rounds", "tiles", "track")},
            "faults": self.faults,
            "preempted": self.preempted,
            "waited": self.waited,
            "off_cpu_us": np.round(self.off_cpu_us, 2).tolist(),
            "cpu": self.cpu,
            "moved": self.moved,
            "at_ms": np.round(1e3 * (np.asarray(self.at_s) - self.at_s[0]), 3).tolist(),
        }

    def phases_us(self) -> np.ndarray:
        """(calls, 8) µs between the stamps 8, 0, 1, ..., 7 of each call."""
        st = np.stack(self.stamps).view(np.uint32)
        st = np.concatenate([st[:, 8:], st[:, :8]], axis=1)
        # differences of the low 32 bits of a ns timer: exact across a wrap
        return np.diff(st, axis=1).astype(np.uint32).astype(np.float64) / 1e3

    def summary(self) -> dict:
        """Median, p99, max of the own time; mean phases, host share and statistics of all
        calls and of the calls at or above the p99."""
        ms = np.asarray(self.ms)
        ph = self.phases_us()
        hs = np.asarray(self.host_us, np.float64)
        p99 = float(np.percentile(ms, 99))
        steps = np.asarray(self.step_ms)
        step_p99 = float(np.percentile(steps, 99))
        out: dict = {
            "calls": int(ms.size),
            "median": float(np.median(ms)),
            "p99": p99,
            "max": float(ms.max()),
            "walk": float(ms.sum()),
            "step_median": float(np.median(steps)),
            "step_p99": step_p99,
            "step_walk": float(steps.sum()),
        }
        selections = (
            ("all", np.ones(ms.size, bool)),
            ("tail", ms >= p99),
            ("step_tail", steps >= step_p99),  # the calls of the bench's p99 steps
        )
        for name, sel in selections:
            device_us = ph[sel].sum(axis=1)
            out[name] = {
                "calls": int(sel.sum()),
                "ms": float(ms[sel].mean()),
                "host_us": float((ms[sel] * 1e3 - device_us).mean()),
                **{f"{p}_us": float(ph[sel, i].mean()) for i, p in enumerate(STAMP_PHASES)},
                **{f"{p}_us": float(hs[sel, i].mean()) for i, p in enumerate(HOST_PARTS)},
                "gc_calls": int((hs[sel, 3] > 0).sum()),
                **{k: float(np.asarray(getattr(self, k))[sel].mean()) for k in COUNTS},
                "step_ms": float(steps[sel].mean()),
            }
        return out


def recording(log: CallLog) -> Callable[[], None]:
    """Record every ``CudaPlanner.update_and_path`` into ``log``, with the ``Route.path_from``
    around it; returns the undo."""
    from daemon.navigation.route import Route

    CudaPlanner, Loop = planner.CudaPlanner, resident.ResidentLoop
    original, post, wait = CudaPlanner.update_and_path, Loop.post, Loop.wait
    clock: dict[str, float] = {
        "post": 0.0,
        "done": 0.0,
        "gc": 0.0,
        "gc_at": 0.0,
        "call": 0.0,
        "book": 0.0,
    }

    def timed_post(self, slot, n_delta):
        clock["post"] = time.perf_counter()
        post(self, slot, n_delta)

    def timed_wait(self, io, seq, share=False):
        wait(self, io, seq, share)
        clock["done"] = time.perf_counter()

    def collector(phase: str, info: dict) -> None:
        if phase == "start":
            clock["gc_at"] = time.perf_counter()
        else:
            clock["gc"] += time.perf_counter() - clock["gc_at"]

    def update_and_path(self, cells, blocked, start):
        before = self._loop.launches if self._loop is not None else 0
        clock["gc"] = 0.0
        t0 = time.perf_counter()
        stats, path = original(self, cells, blocked, start)
        t1 = time.perf_counter()
        if self.variant == "fast":
            launched = self._loop.launches - before if self._loop is not None else 0
            parts = (clock["post"] - t0, clock["done"] - clock["post"], t1 - clock["done"])
            host = tuple(1e6 * v for v in (*parts, clock["gc"], 0.0))
            log.add(self, stats.ms, int(np.size(cells)), launched, host)
            clock["call"] = t1 - t0
            clock["book"] = time.perf_counter() - t1  # the recording's, inside the step
        return stats, path

    def path_from(self, *args, **kwargs):
        calls = len(log.ms)
        on = getcpu()
        before = resource.getrusage(resource.RUSAGE_THREAD)
        cpu0 = time.thread_time()  # inside getrusage's reads, outside the step's own clock
        out = path_from_original(self, *args, **kwargs)
        cpu = time.thread_time() - cpu0
        after = resource.getrusage(resource.RUSAGE_THREAD)
        cpus = (on, getcpu())
        if len(log.ms) == calls + 1:  # the step's call: what the bench records around it
            step_ms = self.report.plan_ms - 1e3 * clock["book"]
            faults = after.ru_minflt - before.ru_minflt
            preempted = after.ru_nivcsw - before.ru_nivcsw
            waited = after.ru_nvcsw - before.ru_nvcsw
            cpu_ms = 1e3 * cpu - 1e3 * clock["book"]
            track = len(self.track.cells)
            log.routed(step_ms, 1e3 * clock["call"], track, faults, preempted, cpu_ms, waited, cpus)
        return out

    path_from_original = Route.path_from
    CudaPlanner.update_and_path = update_and_path  # type: ignore[method-assign]
    Loop.post, Loop.wait = timed_post, timed_wait  # type: ignore[method-assign]
    Route.path_from = path_from  # type: ignore[method-assign]
    gc.callbacks.append(collector)

    def undo() -> None:
        CudaPlanner.update_and_path = original  # type: ignore[method-assign]
        Loop.post, Loop.wait = post, wait  # type: ignore[method-assign]
        Route.path_from = path_from_original  # type: ignore[method-assign]
        gc.callbacks.remove(collector)

    return undo


def walk_logged(scenario, mode: str, max_steps: int | None) -> CallLog:
    """One walk's calls. ``mode``: ``eds``, ``eds-unfocused`` (every call settles the whole
    field) or ``dss``, with ``:RATE`` for another cut-over rate (``planner.CUT_OVER``) and
    ``:RATE:AREA`` for another least limit too (``planner.CUT_OVER_AREA``)."""
    from sim.benchmark import settle_heap
    from sim.walk import walk

    name, _, limits = mode.partition(":")
    rate, _, area = limits.partition(":")
    log = CallLog()
    undo = recording(log)
    focused, cut_over, cut_area = planner.FOCUSED, planner.CUT_OVER, planner.CUT_OVER_AREA
    planner.FOCUSED = name != "eds-unfocused"
    planner.CUT_OVER = float(rate) if rate else cut_over
    planner.CUT_OVER_AREA = float(area) if area else cut_area
    try:
        settle_heap()
        walk(scenario, backend="cuda", mode=name.split("-")[0], max_steps=max_steps)
    finally:
        undo()
        planner.FOCUSED, planner.CUT_OVER, planner.CUT_OVER_AREA = focused, cut_over, cut_area
    return log


def main(argv: list[str] | None = None) -> None:
    from sim.benchmark import warm_up
    from sim.scenarios import make_scenario

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="400")
    ap.add_argument("--scenario", default="courtyard")
    ap.add_argument("--unknown", default="0.4")
    ap.add_argument("--modes", default="eds,dss", help="eds, eds-unfocused, dss; :RATE cut-over")
    ap.add_argument("--max-steps", type=int, default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--per-call", action="store_true", help="every call's figures in the JSON")
    args = ap.parse_args(argv)
    modes = args.modes.split(",")
    warm_up("cuda", "fast", sorted({m.split("-")[0].split(":")[0] for m in modes}))
    rows = []
    cols = ("median", "p99", "max", "walk", "step_median", "step_p99", "step_walk")
    tail = (
        "ms",
        "host_us",
        *(f"{p}_us" for p in STAMP_PHASES),
        *(f"{p}_us" for p in HOST_PARTS),
        "gc_calls",
        *COUNTS,
    )
    names = " ".join(f"{c.removesuffix('_us')[:7]:>7}" for c in tail)
    heads = " ".join(f"{c.replace('step_', 's.')[:7]:>7}" for c in cols)
    print(f"{'walk':30} {'calls':>5} {heads} | {names}")
    for name in args.scenario.split(","):
        for grid in (int(v) for v in args.grid.split(",")):
            for unknown in (float(v) for v in args.unknown.split(",")):
                scenario = make_scenario(name, grid, unknown, 0)
                for mode in modes:
                    before, usage = host_clocks(), resource.getrusage(resource.RUSAGE_THREAD)
                    log = walk_logged(scenario, mode, args.max_steps)
                    after, used = host_clocks(), resource.getrusage(resource.RUSAGE_THREAD)
                    ran = {k: round(v - before.get(k, 0.0), 1) for k, v in after.items()}
                    s = {
                        "scenario": name,
                        "grid": grid,
                        "unknown": unknown,
                        "mode": mode,
                        **log.summary(),
                        "threads_ms": {k: v for k, v in ran.items() if v > 0 or k == "steal"},
                        # the stepping thread over the whole walk, between steps too
                        "walk_switches": {
                            "waited": used.ru_nvcsw - usage.ru_nvcsw,
                            "preempted": used.ru_nivcsw - usage.ru_nivcsw,
                            "cpus": sorted(set(log.cpu)),
                        },
                    }
                    if args.per_call:
                        s["per_call"] = log.per_call()
                    rows.append(s)
                    head = " ".join(f"{s[c]:7.3f}" for c in cols)
                    for part, label in (
                        ("all", f"{name} {grid} {unknown:g} {mode}"),
                        ("tail", "  calls >= p99"),
                        ("step_tail", "  steps >= step p99"),
                    ):
                        lead = f"{s['calls']:5d} {head}" if part == "all" else " " * 61
                        row = " ".join(f"{s[part][c]:7.{3 if c == 'ms' else 1}f}" for c in tail)
                        print(f"{label:30} {lead} | {row}")
                    print(f"{'  threads ms':30} {s['threads_ms']} {s['walk_switches']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
