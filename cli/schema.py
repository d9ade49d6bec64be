"""``guidebelt schema DIR``: the JSON Schema of every message, for clients in other languages."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def schema(
    out: Annotated[Path, typer.Argument(help="folder to write <Message>.schema.json into")] = Path(
        "out/schema"
    ),
) -> None:
    """Write one JSON Schema file per wire message, and the topic table (topics.md)."""
    from protocol.schema import write_schemas

    for path in write_schemas(out):
        typer.echo(str(path))


def register(app: typer.Typer) -> None:
    app.command("schema")(schema)
