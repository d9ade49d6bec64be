"""The ``guidebelt`` command: registers one small module per sub-command.

Command modules import only typer and the standard library at the top; their heavy
imports (zenoh, pydantic, matplotlib, cupy) happen inside the command, so
``python -m cli.app bench`` runs on the GPU machine, which lacks zenoh.
"""

from __future__ import annotations

import importlib

import typer

app = typer.Typer(
    name="guidebelt",
    help="Real-time navigation for blind pedestrians: planner, daemon, drivers, simulation.",
    no_args_is_help=True,
    add_completion=False,
)

# Each module defines ``register(app: typer.Typer) -> None``.
COMMAND_MODULES = [
    "cli.bench",
    "cli.compare",
    "cli.render",
    "cli.demo",
    "cli.walks",
    "cli.voice",
    "cli.voice_goal",
    "cli.rfid",
    "cli.mapper",
    "cli.belt",
    "cli.run",
    "cli.goal",
    "cli.status",
    "cli.settings",
    "cli.sim",
    "cli.schema",
    "cli.certs",
    "cli.load",
    "cli.view",
    "cli.record",
    "cli.replay",
]

for _name in COMMAND_MODULES:
    importlib.import_module(_name).register(app)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
