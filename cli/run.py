"""``guidebelt run``: the navigation daemon (what systemd starts)."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import Annotated

import typer

from cli.options import PLANNER_NAMES


def run(
    config: Annotated[
        Path | None,
        typer.Option(help="TOML file; default $GUIDEBELT_CONFIG or /etc/guidebelt/guidebelt.toml"),
    ] = None,
    planner: Annotated[
        str | None,
        typer.Option(help=f"A registry planner ({PLANNER_NAMES}); overrides the config."),
    ] = None,
) -> None:
    """Serve goals, poses and map deltas over zenoh until SIGTERM."""
    import uvloop

    from daemon.service.config import load_config
    from daemon.service.daemon import serve
    from daemon.service.logs import setup_logging

    cfg = load_config(config, **({"planner": planner} if planner else {}))
    setup_logging(cfg.log_level, cfg.log_format)
    uvloop.run(serve(cfg))
    # Everything the daemon owns is closed by now. Skip the interpreter's teardown: the
    # compiled planner's runtime takes ~0.7 s to unload, and systemd (and the user waiting
    # for the belt to go quiet) get a stop well inside one second.
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def register(app: typer.Typer) -> None:
    app.command("run")(run)
