"""The view under load: frames a second and its memory, 4 users walking, for minutes.

    .venv/bin/python scripts/measure_view.py --users 4 --minutes 10 --json view.json

This process runs the daemon (embedded, cpu) and the simulated users (``sim.live``: each walks
its own courtyard again and again, a step every ``--pace`` s). ``guidebelt view`` runs as a
child process, the real command, connected to the daemon and listening for the users' poses
and map deltas. A WebSocket client here reads the page's frames, as a browser would: frames
a second in 10-s windows, and how many of them brought a new pose. The view's RSS is read
from /proc every 10 s; "flat" means the last minute's RSS against the second minute's (the
first minute holds start-up: imports, first maps).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--users", type=int, default=4)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--pace", type=float, default=0.1)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()

    from websockets.sync.client import connect

    from daemon.service.embedded import DaemonThread, free_port
    from daemon.service.logs import setup_logging
    from sim.courtyard import USER_RADIUS_M
    from sim.live import LiveWalks

    setup_logging("ERROR")
    users = [f"user{i}" for i in range(args.users)]
    with DaemonThread(backend="cpu", cell_m=0.1, user_radius_m=USER_RADIUS_M) as daemon:
        zport, hport = free_port(), free_port()
        view = subprocess.Popen(
            [sys.executable, "-m", "cli.app", "view", "--port", str(hport), "--hz", str(args.hz),
             "--connect", f"tcp/127.0.0.1:{daemon.port}", "--listen", f"tcp/127.0.0.1:{zport}"],
            cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            time.sleep(4.0)  # the view's imports and zenoh session
            with LiveWalks(daemon.port, users, observers=[zport], pace_s=args.pace, rounds=0,
                           timeout_s=600) as walks:  # fmt: skip
                result = measure(connect, hport, view.pid, args, users)
                walks.stop()
            result["walks"] = {u: len(r) for u, r in walks.results.items()}
            result["arrived"] = sum(x.arrived for r in walks.results.values() for x in r)
        finally:
            view.terminate()
            view.wait(10)
    result.update(
        machine=f"{platform.node()} {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores", date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        users=args.users, minutes=args.minutes, pace_s=args.pace, hz=args.hz,
    )  # fmt: skip
    print(json.dumps({k: v for k, v in result.items() if k not in ("windows", "rss")}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


def measure(connect, hport: int, pid: int, args, users: list[str]) -> dict:
    windows: list[dict] = []
    rss: list[tuple[float, float]] = []
    end = time.monotonic() + args.minutes * 60
    with connect(f"ws://127.0.0.1:{hport}/ws", max_size=2**24) as ws:
        t0 = time.monotonic()
        while time.monotonic() < end:
            w_end = time.monotonic() + 10.0
            frames = fresh = 0
            seen_users: set[str] = set()
            last = None
            while time.monotonic() < w_end:
                frame = json.loads(ws.recv(timeout=5.0))
                frames += 1
                poses = tuple((u["pose"] or {}).get("stamp") for u in frame["users"].values())
                fresh += poses != last
                last = poses
                seen_users |= set(frame["users"])
            windows.append({"t_s": round(time.monotonic() - t0, 1), "frames_per_s": frames / 10,
                            "new_pose_frames_per_s": fresh / 10,
                            "users": len(seen_users & set(users))})  # fmt: skip
            rss.append((round(time.monotonic() - t0, 1), round(rss_mb(pid), 1)))
            print(windows[-1], "rss", rss[-1][1], "MB", flush=True)
    fps = np.array([w["frames_per_s"] for w in windows])
    mb = np.array([r[1] for r in rss])
    per_min = max(1, len(rss) // max(1, int(args.minutes)))
    second_minute = mb[per_min : 2 * per_min] if len(mb) >= 2 * per_min else mb[:1]
    return {
        "frames_per_s": {"median": float(np.median(fps)), "min": float(fps.min()),
                         "max": float(fps.max())},
        "new_pose_frames_per_s_median": float(
            np.median([w["new_pose_frames_per_s"] for w in windows])),
        "users_in_every_window": all(w["users"] == len(users) for w in windows),
        "rss_mb": {"first": float(mb[0]), "second_minute_median": float(np.median(second_minute)),
                   "last_minute_median": float(np.median(mb[-per_min:])), "max": float(mb.max())},
        "windows": windows,
        "rss": rss,
    }  # fmt: skip


if __name__ == "__main__":
    main()
