"""Mapper speed: a 640 x 480 depth frame to a published ``MapDelta``, per frame.

Usage: PYTHONPATH=. python scripts/mapper_bench.py [--backend cpu cuda] [--floor-every 1 4]
       [--floor next path] [--fps 0 30] [--sleep chunks whole] [--split F.json] [--frames 200]
       [--json out/mapper_bench.json] [--cache frames.pickle]
Each backend x floor-refit interval (x where a due fit runs: ``next``, off the frame's path
and taken by the next frame, as shipped, or ``path``, on the frame's own path; x each
``--fps``) is one row, on the same rendered frames. ``--fps``
feeds the frames at a camera's rate (the time between frames is not counted; 0: back to
back), the loop sleeping in 2 ms pieces until the next frame is due (``--sleep chunks``), in
one sleep as ``guidebelt mapper --rate`` does (``whole``), spinning on the clock (``spin``:
the host never idles, the GPU still does), or sleeping once to 2 ms before the frame and
spinning from there (``spin2``); each such row gives how late the loop woke
(``wake_late_ms``): a frame that starts after a sleep pays the wake-up. ``--split``
adds, on cuda, the per-pixel pass's GPU time against its host time (CuPy's profiler).
Frames are rendered first (the simulated RGB-D camera walking the courtyard's route, with
noise and missing pixels; ``--cache`` keeps them in a file for the next run: rendering 300
frames takes half a minute of a device call), then each is timed from the call that takes
it to the delta encoded and put on a zenoh publisher (loopback session): floor fit, the
per-pixel pass, ray clearing, merge, proximity, encoding, put. Each row also counts the
frames the interpreter's collector ran in, and marks the five slowest frames that had one.
Seed 000's mapper: 7.56 fps on the TX2.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import math
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from sim.camera import RgbdCamera
from sim.courtyard import bfs_path, make_courtyard
from sim.scene3d import scene_from_scenario


def route_frames(n: int, seed: int = 0):
    scenario = make_courtyard(100, 0.2, seed)
    scene = scene_from_scenario(scenario, seed)
    h, w = scenario.shape
    blocked = np.ascontiguousarray(scenario.true == 1)
    path = bfs_path(blocked, scenario.start[0] * w + scenario.start[1],
                    scenario.goal[0] * w + scenario.goal[1])  # fmt: skip
    cells = [divmod(int(p), w) for p in path]
    cam = RgbdCamera()
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        k = min(len(cells) - 2, (i * (len(cells) - 2)) // max(1, n - 1))
        (r0, c0), (r1, c1) = cells[k], cells[min(k + 3, len(cells) - 1)]
        x, y = (c0 + 0.5) * 0.1, (h - r0 - 0.5) * 0.1
        heading = math.atan2(-(r1 - r0), c1 - c0) + 0.3 * math.sin(i / 5)  # looking about
        out.append(cam.render(scene, cam.pose(x, y, heading), 1000.0 + 0.1 * i, rng))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--backend", nargs="+", default=["cpu"])
    ap.add_argument("--floor-every", type=int, nargs="+", default=[1])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument(
        "--floor",
        nargs="+",
        choices=("next", "path"),
        default=["next" if MapperSettings().floor_async else "path"],
        help="A due floor fit off the path, taken by the next frame (next), or on the frame's "
        "own path (path); default: as shipped.",
    )
    ap.add_argument("--fps", type=float, nargs="+", default=[0.0], help="0: back to back.")
    ap.add_argument(
        "--sleep",
        nargs="+",
        choices=("chunks", "whole", "spin", "spin2"),
        default=["chunks"],
        help="At --fps > 0: sleep in 2 ms pieces, once (as the CLI's --rate), not at all "
        "(spin: the host never idles; the wake-up's cost is the difference), or once to 2 ms "
        "before the frame and spin from there (spin2).",
    )
    ap.add_argument(
        "--depth",
        nargs="+",
        choices=("copied", "lent"),
        default=["copied"],
        help="The frame's depth in its own array, copied into the pass's upload buffer on the "
        "frame's path (copied: a camera SDK's frame), or written into the buffer the mapper "
        "lends (OccupancyMapper.depth_buffer) by its producer before the wait for the frame, "
        "off the timed path (lent: a renderer or decoder that writes there).",
    )
    ap.add_argument("--split", type=Path, help="cuda: the pass's GPU vs host time, to this JSON.")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--cache", type=Path, help="Rendered frames: read if there, else written.")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.cache is not None and args.cache.exists():
        frames = pickle.loads(args.cache.read_bytes())[: args.frames]
    else:
        frames = route_frames(args.frames)
        if args.cache is not None:
            args.cache.write_bytes(pickle.dumps(frames, protocol=pickle.HIGHEST_PROTOCOL))
    render_s = time.perf_counter() - t0
    try:  # the published delta: encoded and put on zenoh, where zenoh is installed
        from protocol.session import ZenohSettings, open_session

        session = open_session(ZenohSettings(connect=[], multicast_scouting=False))
    except ImportError:
        session = None
    modes = [m == "next" for m in args.floor]
    rows = [bench(session, frames, b, k, a, fps, sleep, d) for b in args.backend
            for k in args.floor_every for a in modes for d in args.depth for fps in args.fps
            for sleep in (args.sleep if fps > 0 else ["-"])]  # fmt: skip
    if args.split is not None and "cuda" in args.backend:
        parts = split(frames[len(frames) // 2])
        print(json.dumps(parts))
        args.split.parent.mkdir(parents=True, exist_ok=True)
        args.split.write_text(json.dumps(parts, indent=1) + "\n")
    for row in rows:
        row["render_s"] = round(render_s, 1)
        print(json.dumps(row))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    if session is not None:
        session.close()


def bench(session, frames: list, backend: str, floor_every: int, floor_async: bool = True,
          fps: float = 0.0, sleep: str = "chunks", depth: str = "copied") -> dict:  # fmt: skip
    settings = MapperSettings(backend=backend, floor_every=floor_every, floor_async=floor_async)
    mapper = OccupancyMapper(settings)
    node = None
    if session is not None:
        from mapper.node import MapperNode

        node = MapperNode(session, "bench", mapper)
    feed = node.feed if node is not None else mapper.process
    for f in frames[:3]:  # compile / warm the device, then start over
        feed(f)
    mapper.close()
    warm, mapper = mapper, OccupancyMapper(settings)
    # The warmed pass carries over (on cuda its graph, captured on a mapper's first frame
    # of a size, a one-off at start-up): the rows time the frames that follow it.
    mapper.binner = warm.binner
    if node is not None:
        node.mapper = mapper
    feed = node.feed if node is not None else mapper.process
    ms, parts, collected = [], {}, []
    # Which frames the interpreter's collector ran in: tells a slow frame the collector took
    # from one the host took (preempted, woken late).
    runs = [0]

    def count(phase: str, info: dict) -> None:
        runs[0] += phase == "start"

    gc.callbacks.append(count)
    period = 1.0 / fps if fps > 0 else 0.0
    due = time.perf_counter()
    late = []
    started_at = time.time()  # wall clock, to match samples taken beside (GPU clocks)
    for i, f in enumerate(frames):
        f = dataclasses.replace(f, stamp=2000.0 + 0.1 * i)
        if depth == "lent":
            # Its producer writes the frame where the pass uploads it from, before the wait
            # for it (as a camera's thread would while this one sleeps): the write does not
            # warm this core for the frame.
            lent = mapper.depth_buffer(*f.depth.shape, f.depth.dtype.type)
            np.copyto(lent, f.depth)
            f = dataclasses.replace(f, depth=lent)
        if sleep in ("whole", "spin2"):
            time.sleep(max(0.0, due - (0.002 if sleep == "spin2" else 0.0) - time.perf_counter()))
        while (t := time.perf_counter()) < due:  # the camera's next frame is not here yet
            if sleep in ("chunks", "whole"):
                time.sleep(min(due - t, 0.002))
        late.append((time.perf_counter() - due) * 1e3)
        t, before = time.perf_counter(), runs[0]
        r = feed(f)
        ms.append((time.perf_counter() - t) * 1e3)
        collected.append(runs[0] > before)
        if node is None:
            mapper.fit_pending_floor()  # as the node does once the frame is out
        due = t + period
        if r is not None:
            for k, v in r.ms.items():
                parts.setdefault(k, []).append(v)
    gc.callbacks.remove(count)
    if node is not None:
        node.close()
    mapper.close()
    ms = np.array(ms)
    slowest = np.argsort(ms)[::-1][:5]
    return {
        "backend": mapper.backend, "floor_every": floor_every, "floor_async": floor_async,
        "fps": fps, "sleep": sleep, "depth": depth, "frames": len(ms),
        "size": "640x480", "published": node is not None,
        "median_ms": round(float(np.median(ms)), 3), "mean_ms": round(float(ms.mean()), 3),
        "p99_ms": round(float(np.percentile(ms, 99)), 3), "max_ms": round(float(ms.max()), 3),
        "fps_median": round(1e3 / float(np.median(ms)), 1),
        "parts_median_ms": {k: round(float(np.median(v)), 3) for k, v in parts.items()},
        "parts_p99_ms": {k: round(float(np.percentile(v, 99)), 3) for k, v in parts.items()},
        "frames_collected": int(sum(collected)),
        "started_at": round(started_at, 3), "ended_at": round(time.time(), 3),
        # How long after the frame was due the loop took it (0 back to back: never slept).
        "wake_late_ms": {"median": round(float(np.median(late[1:])), 3),
                         "p99": round(float(np.percentile(late[1:], 99)), 3)} if fps > 0 else None,
        "slowest_ms_collected": [[round(float(ms[i]), 3), collected[i]] for i in slowest],
    }  # fmt: skip


def split(frame) -> dict:
    """The cuda per-pixel pass of one frame, 200 times: host time of the whole call (staging,
    the graph's launch, the wait) against the GPU time between events around it, and the
    graph alone on the staged frame (``cupyx.profiler.benchmark``, its events on the pass's
    own stream)."""
    from cupyx.profiler import benchmark

    from mapper import cuda_binning

    s = MapperSettings(backend="cuda")
    m = OccupancyMapper(s)
    intr, pose = frame.intrinsics, frame.pose
    rot, cam = pose.world_from_optical(), np.asarray(pose.position, np.float64)
    win = m.window(cam[0], cam[1])
    args = (frame.depth, intr.depth_scale, intr, rot, cam, 0.0, win, s.min_height_m,
            s.max_height_m, s.max_range_m, s.cols_per_bin, s.stride)  # fmt: skip
    binner = cuda_binning.CudaBinner()
    graph = binner.prepare(*args)
    with graph.stream:
        whole = benchmark(binner.__call__, args, n_repeat=200, n_warmup=20)
        alone = benchmark(graph.launch, (), n_repeat=200, n_warmup=20)

    def us(x) -> dict:
        x = np.asarray(x).ravel() * 1e6
        med, p99 = float(np.median(x)), float(np.percentile(x, 99))
        return {"median_us": round(med, 1), "p99_us": round(p99, 1)}

    return {
        "split": "cuda per-pixel pass, one 640x480 frame, 200 calls",
        "call_host": us(whole.cpu_times), "call_gpu": us(whole.gpu_times),
        "graph_host": us(alone.cpu_times), "graph_gpu": us(alone.gpu_times),
    }  # fmt: skip


if __name__ == "__main__":
    main()
