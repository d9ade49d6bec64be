"""Mapper speed: a 640 x 480 depth frame to a published ``MapDelta``, per frame.

Usage: PYTHONPATH=. python scripts/mapper_bench.py [--backend cpu|cuda] [--frames 200]
       [--json out/mapper_bench.json]
Frames are rendered first (the simulated RGB-D camera walking the courtyard's route, with
noise and missing pixels), then each is timed from the call that takes it to the delta
encoded and put on a zenoh publisher (loopback session): floor fit, the per-pixel pass,
ray clearing, merge, proximity, encoding, put. Seed 000's mapper: 7.56 fps on the TX2.
"""

from __future__ import annotations

import argparse
import json
import math
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
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    t0 = time.perf_counter()
    frames = route_frames(args.frames)
    render_s = time.perf_counter() - t0
    try:  # the published delta: encoded and put on zenoh, where zenoh is installed
        from mapper.node import MapperNode
        from protocol.session import ZenohSettings, open_session

        session = open_session(ZenohSettings(connect=[], multicast_scouting=False))
    except ImportError:
        session = None
    mapper = OccupancyMapper(MapperSettings(backend=args.backend))
    node = MapperNode(session, "bench", mapper) if session is not None else None
    feed = node.feed if node is not None else mapper.process
    for f in frames[:3]:  # compile / warm the device, then start over
        feed(f)
    mapper = OccupancyMapper(MapperSettings(backend=args.backend))
    if node is not None:
        node.mapper = mapper
    feed = node.feed if node is not None else mapper.process
    ms, parts = [], {}
    for i, f in enumerate(frames):
        import dataclasses

        f = dataclasses.replace(f, stamp=2000.0 + 0.1 * i)
        t = time.perf_counter()
        r = feed(f)
        ms.append((time.perf_counter() - t) * 1e3)
        res = r if r is not None else None
        if res is not None:
            for k, v in res.ms.items():
                parts.setdefault(k, []).append(v)
    ms = np.array(ms)
    row = {
        "backend": mapper.backend, "frames": len(ms), "size": "640x480",
        "published": node is not None,
        "median_ms": round(float(np.median(ms)), 3),
        "p99_ms": round(float(np.percentile(ms, 99)), 3), "max_ms": round(float(ms.max()), 3),
        "fps_median": round(1e3 / float(np.median(ms)), 1),
        "parts_median_ms": {k: round(float(np.median(v)), 3) for k, v in parts.items()},
        "render_s": round(render_s, 1),
    }  # fmt: skip
    print(json.dumps(row))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(row, indent=1) + "\n")
    if node is not None:
        node.close()
        session.close()


if __name__ == "__main__":
    main()
