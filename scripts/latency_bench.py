"""Daemon latency: map delta published → belt pattern received, over zenoh, three processes.

    .venv/bin/python scripts/latency_bench.py --grid 200 --deltas 1000 --backend cpu

This process is the mapper: it starts ``guidebelt run`` (the daemon) and a belt subscriber
(this script again, ``--role sub``) as child processes, joins them on 127.0.0.1, sets up one
user (a map, a goal at the top, the user standing at the bottom), then publishes deltas one
at a time, ``--gap-ms`` apart. Each delta drops or lifts a small obstacle at a random place on
the way, so every delta changes the blocked map and the path (EDS repairs a large part of the
field). The subscriber stamps each belt pattern's arrival with CLOCK_MONOTONIC, the clock the
publisher stamps each send with. Each step publishes its belt pattern and then its path,
which names the last delta the step applied (``map_seq``): delta i's latency ends at the belt
pattern of the first step that applied it (exact even when deltas are coalesced).

The daemon runs with ``tick_s`` and ``stale_pose_s`` long, so only deltas make it step.

``--tls`` runs the same over zenoh's mutual TLS with the daemon's access rules on: the
certificates (``guidebelt certs``' module) go in ``--tmp``/tls, the mapper and the belt
subscriber join as the ``sim`` identity, so every message crosses the TLS link and the ACL.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import zenoh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from daemon.service.embedded import free_port, open_peer  # noqa: E402
from protocol import codec  # noqa: E402
from protocol import session as wire  # noqa: E402
from protocol import topics as T  # noqa: E402
from protocol.messages import Goal, GoalCell, MapDelta, NavPath, NavStatus, Pose  # noqa: E402

USER = "bench"


def join(port: int, tls_dir: Path | None) -> zenoh.Session:
    """A peer of the daemon: plain TCP, or TLS with the ``sim`` certificate."""
    if tls_dir is None:
        return open_peer(port)
    from protocol.settings import load_node_settings

    settings = load_node_settings(tls_dir / "sim.toml")
    return wire.open_session(settings.model_copy(update={"connect": [tls_endpoint(port)]}))


def tls_endpoint(port: int) -> str:
    return f"tls/127.0.0.1:{port}"


def tls_env(port: int, tls_dir: Path) -> dict[str, str]:
    """The daemon's [zenoh] table as environment variables (GUIDEBELT_ZENOH__…)."""
    from protocol.deployment import certify
    from protocol.topics import Role

    daemon = certify(tls_dir, [USER], [Role.SIM])[0].settings
    assert daemon.tls is not None and daemon.access is not None
    return {
        "GUIDEBELT_ZENOH__LISTEN": json.dumps([tls_endpoint(port)]),
        "GUIDEBELT_ZENOH__TLS": daemon.tls.model_dump_json(),
        "GUIDEBELT_ZENOH__ACCESS": daemon.access.model_dump_json(),
    }


def subscriber(port: int, out: Path, tls_dir: Path | None = None) -> None:
    """Record the arrival of every belt pattern and of every path (with the map delta it
    reflects) until SIGTERM; then write them."""
    from zenoh.handlers import Callback

    belts: list[int] = []
    paths: list[tuple[int, int]] = []

    def on_belt(sample: zenoh.Sample) -> None:
        belts.append(time.perf_counter_ns())

    def on_path(sample: zenoh.Sample) -> None:
        t = time.perf_counter_ns()
        paths.append((t, codec.decode(NavPath, sample.payload.to_bytes()).map_seq))

    session = join(port, tls_dir)
    subs = [
        wire.declare_subscriber(session, T.BELT, Callback(on_belt, indirect=False), USER),
        wire.declare_subscriber(session, T.PATH, Callback(on_path, indirect=False), USER),
    ]
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    Path(str(out) + ".ready").write_text("ok")
    while not stop:
        time.sleep(0.05)
    for sub in subs:
        sub.undeclare()
    session.close()
    out.write_text(json.dumps({"belts": belts, "paths": paths}))


def wait_for(path: Path, timeout_s: float) -> None:
    end = time.monotonic() + timeout_s
    while not path.exists():
        if time.monotonic() > end:
            raise TimeoutError(f"{path} never appeared")
        time.sleep(0.05)


def blob(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """Flat cells of a size x size obstacle somewhere on the straight way up the middle."""
    r = int(rng.integers(n // 5, 4 * n // 5))
    c = int(rng.integers(n // 2 - n // 10, n // 2 + n // 10))
    rr, cc = np.mgrid[r : r + size, c : c + size]
    return (rr * n + cc).ravel()


def match(
    sends: np.ndarray, belts: np.ndarray, paths: np.ndarray, warmup: int
) -> tuple[list[float], int]:
    """Latency of each delta after the warm-up, and how many were never answered.

    The daemon publishes a step's belt pattern, then its path; the path names the last map
    delta the step applied (``map_seq``). Delta i is answered by the belt pattern of the
    first path with ``map_seq >= i``: exact even when the daemon coalesces deltas that
    arrived during one step.
    """
    lat_ms, unanswered = [], 0
    for i, sent in enumerate(sends, start=1):
        if i <= warmup:
            continue
        later = np.flatnonzero(paths[:, 1] >= i)
        if later.size == 0:
            unanswered += 1
            continue
        path_at = paths[later[0], 0]
        belt_at = belts[np.searchsorted(belts, path_at) - 1]  # the step's pattern, just before
        lat_ms.append((belt_at - sent) / 1e6)
    return lat_ms, unanswered


def run(args: argparse.Namespace) -> dict:
    n = args.grid
    cell_m = 10.0 / n  # the courtyard's 10 m side
    port = free_port()
    tmp = Path(args.tmp)
    tmp.mkdir(parents=True, exist_ok=True)
    arrivals_file = tmp / "arrivals.json"
    for f in (arrivals_file, Path(str(arrivals_file) + ".ready")):
        f.unlink(missing_ok=True)
    # The daemon keeps its state as in production, in a fresh database of its own each run:
    # never the system's /var/lib/guidebelt, nothing restored from an earlier run.
    state = tmp / "state"
    for f in state.glob("state.db*"):
        f.unlink()
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "GUIDEBELT_CONFIG": "",
        "GUIDEBELT_ZENOH__LISTEN": json.dumps([f"tcp/127.0.0.1:{port}"]),
        "GUIDEBELT_ZENOH__MULTICAST_SCOUTING": "false",
        "GUIDEBELT_BACKEND": args.backend,
        "GUIDEBELT_CELL_M": str(cell_m),
        "GUIDEBELT_TICK_S": "60",  # the config's bounds: long enough for the deltas below
        "GUIDEBELT_STALE_POSE_S": "60",
        "GUIDEBELT_LOG_LEVEL": "WARNING",
        "GUIDEBELT_STATE_DIR": str(state) if args.state else "",
    }
    tls_dir = tmp / "tls" if args.tls else None
    if tls_dir is not None:
        env.update(tls_env(port, tls_dir))
    # --daemon-fifo N runs the daemon alone at SCHED_FIFO priority N, as the systemd unit does.
    prefix = ["chrt", "-f", str(args.daemon_fifo)] if args.daemon_fifo else []
    daemon = subprocess.Popen([*prefix, sys.executable, "-m", "cli.app", "run"], cwd=ROOT, env=env)
    sub = subprocess.Popen(
        [sys.executable, __file__, "--role", "sub", "--port", str(port), "--tmp", str(tmp)]
        + (["--tls"] if args.tls else []),
        cwd=ROOT,
        # The daemon's [zenoh] variables are its own: a node's table would read them too.
        env={k: v for k, v in env.items() if not k.startswith("GUIDEBELT_ZENOH__")},
    )
    session = None
    try:
        time.sleep(1.0)
        wait_for(Path(str(arrivals_file) + ".ready"), 60)
        session = join(port, tls_dir)
        # The daemon compiles before it listens (longer on a busy machine): wait for its
        # liveliness token, or the first delta and the goal go to no one.
        end = time.monotonic() + 120
        while not any(r.ok is not None for r in wire.alive(session, T.ALIVE, timeout=1.0)):
            if time.monotonic() > end or daemon.poll() is not None:
                raise TimeoutError("the daemon never came up")
            time.sleep(0.2)
        statuses: list[NavStatus] = []
        st = wire.declare_subscriber(
            session, T.STATUS,
            lambda s: statuses.append(codec.decode(NavStatus, s.payload.to_bytes())), USER,
        )  # fmt: skip
        pub = wire.declare_publisher(session, T.MAP_DELTA, USER)
        time.sleep(0.5)
        walls = np.flatnonzero(np.pad(np.zeros((n - 2, n - 2), bool), 1, constant_values=True))
        first = MapDelta.from_arrays(0, (n, n), walls, np.ones(walls.size), time.time())
        pub.put(codec.encode(first))
        goal = Goal(target=GoalCell(row=n // 10, col=n // 2), stamp=time.time())
        wire.put(session, T.GOAL, USER, codec.encode(goal))
        x, y = (n // 2 + 0.5) * cell_m, (n // 10 + 0.5) * cell_m
        pose = Pose(x=x, y=y, heading=1.57, stamp=time.time())
        wire.put(session, T.POSE, USER, codec.encode(pose))
        end = time.monotonic() + 60
        while not any(s.state == "guiding" for s in statuses):
            if time.monotonic() > end:
                raise TimeoutError(f"daemon never started guiding: {statuses}")
            time.sleep(0.05)
        rng = np.random.default_rng(args.seed)
        sends: list[int] = []
        total = args.warmup + args.deltas
        placed: np.ndarray | None = None
        gap_s = args.gap_ms / 1e3
        next_at = time.perf_counter() + 0.2
        for i in range(total):
            if placed is None:
                placed = blob(rng, n, args.blob)
                cells, values = placed, np.ones(placed.size, np.uint8)
            else:
                cells, values, placed = placed, np.zeros(placed.size, np.uint8), None
            data = codec.encode(MapDelta.from_arrays(i + 1, (n, n), cells, values, time.time()))
            time.sleep(max(0.0, next_at - time.perf_counter() - 0.001))
            while time.perf_counter() < next_at:
                pass  # spin the last millisecond: sleep's wake-up jitter is not the daemon's
            sends.append(time.perf_counter_ns())
            pub.put(data)
            next_at += gap_s
        time.sleep(0.5)
        st.undeclare()
        pub.undeclare()
        errors = [s for s in statuses if s.state in ("error", "stale")]
    finally:
        if session is not None:
            session.close()
        sub.send_signal(signal.SIGTERM)
        sub.wait(10)
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(10)
    got = json.loads(arrivals_file.read_text())
    lat_ms, unanswered = match(
        np.array(sends, dtype=np.int64),
        np.array(got["belts"], dtype=np.int64),
        np.array(got["paths"], dtype=np.int64).reshape(-1, 2),
        args.warmup,
    )
    lat = np.array(lat_ms)
    return {
        "grid": n,
        "link": "tls+acl" if args.tls else "tcp",
        "backend": args.backend,
        "deltas": args.deltas,
        "warmup": args.warmup,
        "gap_ms": args.gap_ms,
        "blob_cells": args.blob**2,
        "state": args.state,
        "answered": int(lat.size),
        "unanswered": unanswered,
        "p50_ms": round(float(np.percentile(lat, 50)), 3),
        "p90_ms": round(float(np.percentile(lat, 90)), 3),
        "p99_ms": round(float(np.percentile(lat, 99)), 3),
        "max_ms": round(float(lat.max()), 3),
        "status_errors": len(errors),
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs",
        "python": platform.python_version(),
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--role", choices=("bench", "sub"), default="bench")
    ap.add_argument("--port", type=int, default=0)
    ap.add_argument("--tmp", default="out/latency")
    ap.add_argument("--grid", type=int, default=200)
    ap.add_argument("--deltas", type=int, default=1000)
    ap.add_argument("--warmup", type=int, default=50)
    ap.add_argument("--gap-ms", type=float, default=20.0)
    ap.add_argument(
        "--state", action=argparse.BooleanOptionalAction, default=True,
        help="the daemon keeps its state (a fresh state.db under --tmp); --no-state: none",
    )  # fmt: skip
    ap.add_argument("--blob", type=int, default=3, help="obstacle side in cells")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--daemon-fifo", type=int, default=0, help="SCHED_FIFO priority, daemon only")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default="", help="also write the result here")
    ap.add_argument("--tls", action="store_true", help="mutual TLS and the daemon's ACL")
    args = ap.parse_args()
    if args.role == "sub":
        tls_dir = Path(args.tmp) / "tls" if args.tls else None
        subscriber(args.port, Path(args.tmp) / "arrivals.json", tls_dir)
        return
    result = run(args)
    print(json.dumps(result, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
