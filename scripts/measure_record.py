"""The recorder at the daemon's full rate: every message counted, none dropped?

    .venv/bin/python scripts/measure_record.py --users 4 --rounds 3 --out /tmp/full.mcap

The daemon (embedded, cpu) records on its own session (``guidebelt run --record``), while
``--users`` simulated users walk the courtyard with no pause between steps (``pace 0``: each
step as soon as the daemon answers the last, the daemon's full rate), ``--rounds`` walks each.
Reports what the recorder heard, wrote, dropped and refused, the rate, the writer's largest
backlog and the file's size; then reads the file back and counts its messages.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--users", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("/tmp/guidebelt-full-rate.mcap"))
    ap.add_argument("--check", action="store_true", help="then replay --check the file")
    args = ap.parse_args()

    from mcap.reader import make_reader

    from daemon.service.embedded import DaemonThread
    from daemon.service.logs import setup_logging
    from recording.recorder import Recorder
    from sim.courtyard import USER_RADIUS_M
    from sim.live import LiveWalks

    setup_logging("ERROR")
    recorders: list[Recorder] = []
    backlog = [0]
    done = threading.Event()

    def observe(session):
        recorders.append(Recorder(session, args.out).start())
        return recorders[-1]

    def watch() -> None:
        while not done.wait(0.01):
            if recorders:
                backlog[0] = max(backlog[0], recorders[0].backlog())

    watcher = threading.Thread(target=watch)
    watcher.start()
    t0 = time.perf_counter()
    with DaemonThread(
        observers=[observe], backend="cpu", cell_m=0.1, user_radius_m=USER_RADIUS_M
    ) as daemon:
        walks = LiveWalks(daemon.port, [f"user{i}" for i in range(args.users)], pace_s=0.0,
                          rounds=args.rounds).start()  # fmt: skip
        walks.join()
    took = time.perf_counter() - t0
    done.set()
    watcher.join()
    counts = recorders[0].counts
    with args.out.open("rb") as f:
        stats = make_reader(f).get_summary().statistics
    result = {
        "heard": counts.heard, "written": counts.written, "dropped": counts.dropped,
        "invalid": counts.invalid, "messages_per_s": round(counts.heard / took, 1),
        "seconds": round(took, 1), "max_backlog": backlog[0],
        "file_mb": round(args.out.stat().st_size / 2**20, 2),
        "messages_in_file": stats.message_count,
        "walks": sum(len(r) for r in walks.results.values()),
        "arrived": sum(x.arrived for r in walks.results.values() for x in r),
        "machine": f"{platform.node()} {platform.machine()}, {os.cpu_count()} cores",
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
    }  # fmt: skip
    if args.check:
        from recording.check import check
        from recording.replay import read

        with DaemonThread(backend="cpu", cell_m=0.1, user_radius_m=USER_RADIUS_M) as fresh:
            session = fresh.peer()
            report = check(session, list(read(args.out)))
            session.close()
        result["check"] = {
            "inputs": report.inputs, "unanswered": report.unanswered,
            "steps_compared": report.steps_compared,
            "statuses_compared": report.statuses_compared,
            "differences": [str(d) for d in report.differences],
        }  # fmt: skip
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
