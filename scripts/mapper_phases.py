"""Where a mapper frame's time goes, phase by phase: wall clock against the thread's CPU time.

Usage: PYTHONPATH=. python scripts/mapper_phases.py [--backend cuda] [--fps 0 30]
       [--frames 300] [--depth copied lent] [--cache frames.pickle] [--json F]
Each frame goes through ``MapperNode.feed`` as ``scripts/mapper_bench.py`` times it (one
sleep to the next frame at ``--fps``; 0: back to back), with every phase of the frame's path
timed on its own: the header check, the floor, the window, the pass's staging (parameters
and the depth's copy into the page-locked buffer), its launch and its wait (cuda), the late
checks, the merge, the delta's message and encoding, each put, the proximity's message, the
floor fit's hand-off. Per phase: median and p99 of the wall time and of the thread's CPU
time (``time.thread_time``), and per frame the context switches the thread made
(``getrusage(RUSAGE_THREAD)``). A phase whose CPU time grows as much as its wall time ran
slower (a cold core: caches, clocks); one whose wall time grows alone waited (a wake-up, the
device, another thread).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import pickle
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mapper import occupancy_mapper as om
from mapper.node import MapperNode
from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from protocol import codec

PHASES: dict[str, list[tuple[float, float]]] = {}
FRAME: dict[str, tuple[float, float]] = {}


def timed(name: str, fn):
    """``fn`` with its wall and thread-CPU time added to this frame's ``name``."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        w0, c0 = time.perf_counter(), time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            w, c = FRAME.get(name, (0.0, 0.0))
            FRAME[name] = (w + time.perf_counter() - w0, c + time.thread_time() - c0)

    return wrapper


class TimedPublisher:
    def __init__(self, name: str, pub) -> None:
        self.put = timed(name, pub.put)
        self._pub = pub

    def undeclare(self) -> None:
        self._pub.undeclare()


def instrument() -> None:
    om.check_header = timed("check_header", om.check_header)
    om.check_depth = timed("check_late", om.check_depth)
    om.merge_frame = timed("merge", om.merge_frame)
    om.proximity_of = timed("proximity", om.proximity_of)
    OccupancyMapper._floor_for = timed("floor", OccupancyMapper._floor_for)
    OccupancyMapper.window = timed("window", OccupancyMapper.window)
    OccupancyMapper.fit_pending_floor = timed("fit_handoff", OccupancyMapper.fit_pending_floor)
    MapperNode._deltas = timed("delta_msg", MapperNode._deltas)
    codec.proximity_bytes = timed("prox_bytes", codec.proximity_bytes)
    codec.encode = timed("encode", codec.encode)
    try:
        from mapper import cuda_binning as cb

        cb.FramePass.stage = timed("stage", cb.FramePass.stage)
        cb.FramePass.launch = timed("launch", cb.FramePass.launch)
        cb.FramePass.wait = timed("wait", cb.FramePass.wait)
        cb.MergeTail.result = timed("readback", cb.MergeTail.result)
    except ImportError:  # no CuPy: the cpu pass is one call
        pass


def run(session, frames: list, backend: str, fps: float, depth: str = "copied") -> dict:
    settings = MapperSettings(backend=backend, floor_every=4)
    mapper = OccupancyMapper(settings)
    node = MapperNode(session, "phases", mapper)
    node._delta = TimedPublisher("put_delta", node._delta)
    node._prox = TimedPublisher("put_prox", node._prox)
    for f in frames[:3]:
        node.feed(f)
    mapper.close()
    warm, mapper = mapper, OccupancyMapper(settings)
    mapper.binner = warm.binner
    node.mapper = mapper
    period = 1.0 / fps if fps > 0 else 0.0
    due = time.perf_counter()
    rows: list[dict[str, tuple[float, float]]] = []
    switches = []
    for i, f in enumerate(frames):
        f = dataclasses.replace(f, stamp=3000.0 + 0.1 * i)
        if depth == "lent":  # written by its producer before the wait, as the bench does
            lent = mapper.depth_buffer(*f.depth.shape, f.depth.dtype.type)
            np.copyto(lent, f.depth)
            f = dataclasses.replace(f, depth=lent)
        time.sleep(max(0.0, due - time.perf_counter()))
        while time.perf_counter() < due:
            pass
        FRAME.clear()
        r0 = resource.getrusage(resource.RUSAGE_THREAD)
        w0, c0 = time.perf_counter(), time.thread_time()
        node.feed(f)
        FRAME["frame"] = (time.perf_counter() - w0, time.thread_time() - c0)
        r1 = resource.getrusage(resource.RUSAGE_THREAD)
        switches.append((r1.ru_nvcsw - r0.ru_nvcsw, r1.ru_nivcsw - r0.ru_nivcsw))
        rows.append(dict(FRAME))
        due = w0 + period
    node.close()
    out: dict = {"backend": mapper.backend, "fps": fps, "depth": depth, "frames": len(rows)}
    for name in rows[0]:
        wall = np.array([r.get(name, (0.0, 0.0))[0] for r in rows]) * 1e3
        cpu = np.array([r.get(name, (0.0, 0.0))[1] for r in rows]) * 1e3
        out[name] = {"wall_ms": [round(float(np.median(wall)), 4),
                                 round(float(np.percentile(wall, 99)), 4)],
                     "cpu_ms": [round(float(np.median(cpu)), 4),
                                round(float(np.percentile(cpu, 99)), 4)]}  # fmt: skip
    sw = np.array(switches)
    out["switches_per_frame"] = {"voluntary": round(float(sw[:, 0].mean()), 3),
                                 "involuntary": round(float(sw[:, 1].mean()), 3)}  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--backend", default="cuda")
    ap.add_argument("--fps", type=float, nargs="+", default=[0.0, 30.0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument(
        "--depth",
        nargs="+",
        choices=("copied", "lent"),
        default=["copied"],
        help="As scripts/mapper_bench.py's --depth.",
    )
    ap.add_argument("--cache", type=Path)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if args.cache is not None and args.cache.exists():
        frames = pickle.loads(args.cache.read_bytes())[: args.frames]
    else:
        from scripts.mapper_bench import route_frames

        frames = route_frames(args.frames)
    from protocol.session import ZenohSettings, open_session

    session = open_session(ZenohSettings(connect=[], multicast_scouting=False))
    instrument()
    rows = [run(session, frames, args.backend, fps, d) for d in args.depth for fps in args.fps]
    session.close()
    for r in rows:
        print(f"fps {r['fps']:g} ({r['backend']}, depth {r['depth']}): phase wall median / p99"
              " | cpu median / p99 ms;"
              f" switches per frame {r['switches_per_frame']}")  # fmt: skip
        for k, v in r.items():
            if isinstance(v, dict) and "wall_ms" in v:
                print(f"  {k:14s} {v['wall_ms'][0]:8.4f} / {v['wall_ms'][1]:8.4f} | "
                      f"{v['cpu_ms'][0]:8.4f} / {v['cpu_ms'][1]:8.4f}")  # fmt: skip
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
