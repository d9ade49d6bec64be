"""A worker process of the daemon (``supervisor.py`` starts it):
``python -m daemon.service.worker_main INDEX COUNT REPORT_FD PARENT_PID``, the config as one
JSON line on stdin."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import sys

from .workers import WorkerRole, die_with


def main() -> None:
    index, count, report_fd, parent = (int(a) for a in sys.argv[1:5])
    die_with(parent)
    import uvloop

    from .config import DaemonConfig
    from .daemon import Daemon
    from .logs import setup_logging

    config = DaemonConfig(**json.loads(sys.stdin.buffer.readline()))
    setup_logging(config.log_level, config.log_format)
    daemon = Daemon(config, worker=WorkerRole(index, count, report_fd))
    with contextlib.suppress(asyncio.CancelledError):
        uvloop.run(daemon.run())
    logging.shutdown()
    sys.stderr.flush()
    os._exit(0)  # as ``guidebelt run``: the compiled planner's runtime is slow to unload


if __name__ == "__main__":
    main()
