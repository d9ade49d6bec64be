"""Where the interpreter's garbage collector runs during a benchmark walk: inside a
replanning step, inside the rest of the navigator's step, or between steps.

A ``gc.callbacks`` recorder notes each collection's generation and duration and which call
it fell in: the replanning step (``Route.path_from``, the window of the bench's ``step_ms``)
and the navigator's whole step (``Navigator.step``, ``nav_ms``). The walks are the bench's
own (``sim.walk.walk`` after ``settle_heap``), so the collector runs under whatever policy
the daemon's step loop runs (``daemon.runtime.gc_policy`` through ``closed_loop``).

    PYTHONPATH=. python -m sim.bench_gc --grid 400 --scenario courtyard,explore
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from daemon.navigation.navigator import Navigator
from daemon.navigation.route import Route

from .benchmark import settle_heap, warm_up
from .scenarios import make_scenario
from .walk import walk


@dataclass
class Collection:
    generation: int
    ms: float
    cpu_ms: float
    """The collecting thread's CPU time (what the load on the machine does not stretch)."""
    plan_call: int
    """Index of the replanning step it ran inside; -1 outside every one."""
    in_step: bool
    """Inside the navigator's step (the replanning step included)."""


@dataclass
class GcRecorder:
    """Each collection and each replanning step while installed (``install`` returns the undo)."""

    collections: list[Collection] = field(default_factory=list)
    plan_ms: list[float] = field(default_factory=list)
    plan_cpu_ms: list[float] = field(default_factory=list)
    """Each replanning step's thread CPU time."""
    plan_gc_ms: list[float] = field(default_factory=list)
    rss_mb: list[float] = field(default_factory=list)
    """The process's resident memory every ``rss_every`` navigator steps."""
    rss_every: int = 50
    _plan: int = -1
    _in_step: bool = False
    _steps: int = 0
    _gc_at: float = 0.0
    _gc_cpu_at: float = 0.0

    def install(self) -> Callable[[], None]:
        path_from, step = Route.path_from, Navigator.step
        rec = self

        def timed_path(route, *args, **kwargs):
            rec._plan = len(rec.plan_ms)
            rec.plan_ms.append(0.0)
            rec.plan_cpu_ms.append(0.0)
            rec.plan_gc_ms.append(0.0)
            t0, c0 = time.perf_counter(), time.thread_time()
            try:
                return path_from(route, *args, **kwargs)
            finally:
                rec.plan_ms[rec._plan] = (time.perf_counter() - t0) * 1e3
                rec.plan_cpu_ms[rec._plan] = (time.thread_time() - c0) * 1e3
                rec._plan = -1

        def timed_step(nav, *args, **kwargs):
            rec._in_step = True
            try:
                return step(nav, *args, **kwargs)
            finally:
                rec._in_step = False
                if rec._steps % rec.rss_every == 0:
                    rec.rss_mb.append(rss_mb())
                rec._steps += 1

        def callback(phase: str, info: dict) -> None:
            if phase == "start":
                rec._gc_at, rec._gc_cpu_at = time.perf_counter(), time.thread_time()
                return
            ms = (time.perf_counter() - rec._gc_at) * 1e3
            cpu = (time.thread_time() - rec._gc_cpu_at) * 1e3
            rec.collections.append(Collection(info["generation"], ms, cpu, rec._plan, rec._in_step))
            if rec._plan >= 0:
                rec.plan_gc_ms[rec._plan] += ms

        Route.path_from, Navigator.step = timed_path, timed_step  # type: ignore[method-assign]
        gc.callbacks.append(callback)

        def undo() -> None:
            Route.path_from, Navigator.step = path_from, step  # type: ignore[method-assign]
            gc.callbacks.remove(callback)

        return undo

    def summary(self) -> dict:
        """Collections by where they ran, and how many of the slowest steps hold one."""
        ms, gc_ms = np.array(self.plan_ms), np.array(self.plan_gc_ms)
        p99 = float(np.percentile(ms, 99)) if ms.size else 0.0
        tail = ms >= p99
        out: dict = {"calls": int(ms.size), "ms_median": float(np.median(ms)) if ms.size else 0.0,
                     "ms_p99": p99, "ms_max": float(ms.max(initial=0.0)),
                     "walk_ms": float(ms.sum()), "tail_calls": int(tail.sum()),
                     "tail_with_gc": int((gc_ms[tail] > 0).sum()),
                     "tail_gc_ms_mean": float(gc_ms[tail].mean()) if tail.any() else 0.0,
                     "max_call_gc_ms": float(gc_ms[ms.argmax()]) if ms.size else 0.0}  # fmt: skip
        places = {
            "in_plan": [c for c in self.collections if c.plan_call >= 0],
            "in_step": [c for c in self.collections if c.in_step and c.plan_call < 0],
            "between": [c for c in self.collections if not c.in_step],
        }
        for place, found in places.items():
            out[place] = {
                "n": len(found),
                "by_gen": [sum(c.generation == g for c in found) for g in range(3)],
                "ms_total": sum(c.ms for c in found),
                "ms_max": max((c.ms for c in found), default=0.0),
                "cpu_ms_total": sum(c.cpu_ms for c in found),
                "cpu_ms_max": max((c.cpu_ms for c in found), default=0.0),
            }
        cpu = np.array(self.plan_cpu_ms)
        if cpu.size:
            out |= {"cpu_ms_median": float(np.median(cpu)),
                    "cpu_ms_p99": float(np.percentile(cpu, 99)),
                    "cpu_ms_max": float(cpu.max()), "cpu_walk_ms": float(cpu.sum())}  # fmt: skip
        out["rss_mb"] = [round(v, 1) for v in self.rss_mb]
        return out


def line(r: dict) -> str:
    """One walk's row as one line: the replanning step's wall and CPU ms (median / p99 / max,
    walk), the p99 steps holding a collection, and the collections by place (count, by
    generation, CPU ms in all), the process's CPU and RSS."""
    where = " | ".join(
        f"{p} {r[p]['n']} {r[p]['by_gen']} {r[p]['cpu_ms_total']:.2f} ms"
        for p in ("in_plan", "in_step", "between")
    )
    return (f"{r['scenario']} {r['grid']} {r['planner']} {r['backend']}: wall {r['ms_median']:.3f}"
            f" / {r['ms_p99']:.3f} / {r['ms_max']:.3f}, {r['walk_ms']:.1f} | cpu "
            f"{r.get('cpu_ms_median', 0):.3f} / {r.get('cpu_ms_p99', 0):.3f} / "
            f"{r.get('cpu_ms_max', 0):.3f}, {r.get('cpu_walk_ms', 0):.1f} | p99 steps with gc "
            f"{r['tail_with_gc']}/{r['tail_calls']} | {where} | process {r['walk_cpu_s']:.2f} s "
            f"cpu, {r['walk_wall_s']:.2f} s wall, load {r['load1']:.1f} | rss "
            f"{r['rss_mb'][0] if r['rss_mb'] else 0:.1f} -> "
            f"{r['rss_mb'][-1] if r['rss_mb'] else 0:.1f} MB")  # fmt: skip


def rss_mb() -> float:
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m sim.bench_gc", description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="400")
    ap.add_argument("--scenario", default="courtyard,explore")
    ap.add_argument("--unknown", type=float, default=0.4)
    ap.add_argument("--planner", default="eds")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    warm_up(a.backend, "fast", [a.planner])
    rows = []
    for name in a.scenario.split(","):
        for grid in (int(g) for g in a.grid.split(",")):
            scenario = make_scenario(name, grid, a.unknown, 0)
            rec = GcRecorder()
            settle_heap()
            undo = rec.install()
            cpu0, wall0 = time.process_time(), time.perf_counter()
            try:
                walk(scenario, backend=a.backend, mode=a.planner)
            finally:
                undo()
            cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
            row = {"scenario": name, "grid": grid, "unknown": a.unknown, "planner": a.planner,
                   "backend": a.backend, "walk_cpu_s": cpu, "walk_wall_s": wall,
                   "load1": os.getloadavg()[0], **rec.summary()}  # fmt: skip
            rows.append(row)
            print(line(row), flush=True)
    if a.json is not None:
        a.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
