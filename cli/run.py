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
    record: Annotated[
        Path | None,
        typer.Option(
            help="Record every user's messages, as the daemon hears and sends them, "
            "to this MCAP file (rotated: .001.mcap, …)."
        ),
    ] = None,
    record_max_mb: Annotated[
        float, typer.Option(help="With --record: rotate past this many MiB per file.")
    ] = 256.0,
) -> None:
    """Serve goals, poses and map deltas over zenoh until SIGTERM."""
    import uvloop

    from daemon.service.config import load_config
    from daemon.service.daemon import serve
    from daemon.service.logs import setup_logging

    cfg = _config_or_exit(load_config, config, planner)
    setup_logging(cfg.log_level, cfg.log_format)
    observers = []
    if record is not None:
        from recording.recorder import Recorder

        max_bytes = int(record_max_mb * 2**20)
        observers.append(lambda session: Recorder(session, record, None, max_bytes).start())
    if cfg.workers:
        from daemon.service.supervisor import supervise

        uvloop.run(supervise(cfg, observers))
    else:
        uvloop.run(serve(cfg, observers))
    # Everything the daemon owns is closed by now. Skip the interpreter's teardown: the
    # compiled planner's runtime takes ~0.7 s to unload, and systemd (and the user waiting
    # for the belt to go quiet) get a stop well inside one second.
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _config_or_exit(load, path: Path | None, planner: str | None):
    """The config, or one line on stderr and exit status 2: what systemd's journal shows for
    a unit that cannot start is that line, not a traceback."""
    import tomllib

    from pydantic import ValidationError

    try:
        cfg = load(path, **({"planner": planner} if planner else {}))
        # The certificates are read when zenoh opens, deep in its start: say here which
        # file is missing, in the same one line.
        missing = cfg.zenoh.problems()
        if not missing:
            return cfg
        reason = "; ".join(missing)
    except ValidationError as exc:
        problems = []
        for err in exc.errors():
            where = ".".join(str(p) for p in err["loc"]) or "config"
            got = f" (got {err['input']!r})" if "input" in err and err["type"] != "missing" else ""
            problems.append(f"{where}: {err['msg']}{got}")
        reason = "; ".join(problems)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        reason = str(exc)
    typer.echo(f"guidebelt run: bad config: {reason}", err=True)
    raise typer.Exit(2)


def register(app: typer.Typer) -> None:
    app.command("run")(run)
