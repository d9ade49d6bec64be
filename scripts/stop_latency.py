"""STOP latency in the zenoh loop: a depth frame showing an obstacle 0.4 m ahead → STOP felt.

Usage: PYTHONPATH=. python scripts/stop_latency.py [--trials 100] [--json F]
The daemon (``DaemonThread``), a mapper node and a belt listener each on their own zenoh
session over 127.0.0.1. Each trial feeds a clear frame, waits, then a frame with a box 0.4 m
ahead; the time runs from the call that hands that frame to the mapper (the frame "arrives")
to the STOP pattern arriving at the belt's subscriber: mapping, proximity, zenoh, the daemon's
step, zenoh again. Frames are rendered beforehand (rendering is the camera's time, not ours).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from daemon.service.embedded import DaemonThread
from mapper.node import MapperNode
from mapper.occupancy_mapper import MapperSettings, OccupancyMapper
from protocol import codec
from protocol import session as wire
from protocol import topics as T
from protocol.messages import BeltPattern
from sim.camera import RgbdCamera
from sim.scene3d import BOX, empty_scene


def scenes():
    clear = empty_scene((60, 60), 0.1)
    near = empty_scene((60, 60), 0.1)
    near.put((slice(40, 45), slice(27, 35)), BOX, 0.0, 0.9)  # face 0.45 m ahead of (3.05, 1.05)
    return clear, near


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    cam = RgbdCamera()
    pose = cam.pose(3.05, 1.05, math.pi / 2)
    rng = np.random.default_rng(0)
    clear, near = (cam.render(s, pose, 1.0, rng) for s in scenes())
    user, got, arrived = "lat", threading.Event(), [0.0]

    def on_belt(sample) -> None:
        if codec.decode(BeltPattern, sample.payload.to_bytes()).kind == "stop":
            arrived[0] = time.perf_counter()
            got.set()

    ms = []
    with DaemonThread(backend="cpu") as daemon:
        mapping, belt = daemon.peer(), daemon.peer()
        sub = wire.declare_subscriber(belt, T.BELT, on_belt, user)
        node = MapperNode(mapping, user, OccupancyMapper(MapperSettings(shape=(60, 60))))
        node.start()
        time.sleep(0.3)
        try:
            for i in range(args.trials + 3):  # the first three warm up
                node.feed(dataclasses.replace(clear, stamp=time.time()))
                time.sleep(0.6)  # longer than the STOP hold: the next STOP is a new one
                got.clear()
                t0 = time.perf_counter()
                node.feed(dataclasses.replace(near, stamp=time.time()))
                if got.wait(2.0) and i >= 3:
                    ms.append((arrived[0] - t0) * 1e3)
                time.sleep(0.1)
        finally:
            sub.undeclare()
            node.close()
            mapping.close()
            belt.close()
    a = np.array(ms)
    row = {"trials": len(a), "median_ms": round(float(np.median(a)), 2),
           "p99_ms": round(float(np.percentile(a, 99)), 2), "max_ms": round(float(a.max()), 2),
           "missed": args.trials - len(a)}  # fmt: skip
    print(json.dumps(row))
    if args.json:
        args.json.write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
