"""``guidebelt certs``: a CA, every node's certificate and its zenoh config (mutual TLS + ACL)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

WORKER_HOST = "127.0.0.1"


def certs(
    user: Annotated[
        list[str] | None,
        typer.Option("--user", help="A user (repeatable): phone, belt, voice and RFID identities."),
    ] = None,
    service: Annotated[
        list[str] | None,
        typer.Option(
            "--service", help="mapper, sim or monitor (repeatable; default: mapper, monitor)."
        ),
    ] = None,
    out: Annotated[Path, typer.Option(help="Where to write them.")] = Path("/etc/guidebelt/tls"),
    installed_at: Annotated[
        Path | None,
        typer.Option(help="Where the nodes will read them, if not OUT (a staging folder)."),
    ] = None,
    endpoint: Annotated[
        str, typer.Option(help="The daemon's TLS endpoint: it listens there, the nodes dial it.")
    ] = "tls/127.0.0.1:7447",
    host: Annotated[
        list[str] | None,
        typer.Option("--host", help="A name or address nodes dial the daemon by (repeatable)."),
    ] = None,
    new_ca: Annotated[
        bool, typer.Option(help="Make a new CA even if OUT has one (every node must be reissued).")
    ] = False,
) -> None:
    """Certify the daemon, each user's nodes and the services, and write their configs.

    The daemon's ``daemon.toml`` holds its [zenoh] table with the access rules: put it in
    guidebelt.toml. Every other node gets ``<role>-<user>.toml`` for ``--zenoh-config`` and
    ``.json5`` for zenoh itself. Keys are written 0600: give each to its service only
    (systemd LoadCredential=, as the shipped units do)."""
    from pydantic import ValidationError

    from protocol.access import SERVICE_ROLES
    from protocol.deployment import DEFAULT_HOSTS, certify
    from protocol.topics import check_user

    known = {str(r): r for r in SERVICE_ROLES}
    try:
        users = [check_user(u) for u in user or []]
        names = service if service is not None else ["mapper", "monitor"]
        unknown = [s for s in names if s not in known]
        if unknown:
            raise ValueError(f"unknown service {unknown[0]!r}: choose from {', '.join(known)}")
        services = [known[s] for s in names]
        hosts = tuple(host) if host else DEFAULT_HOSTS
        # A worker (``workers = N``) dials the daemon's private endpoint on 127.0.0.1 and
        # checks the name there like any node: the daemon's certificate must carry it.
        hosts += () if WORKER_HOST in hosts else (WORKER_HOST,)
        nodes = certify(
            out,
            users,
            services,
            endpoint=endpoint,
            hosts=hosts,
            installed_at=installed_at,
            new_ca=new_ca,
        )
    except ValidationError as exc:  # before ValueError, which it is: its text spans lines
        typer.echo(f"guidebelt certs: {'; '.join(e['msg'] for e in exc.errors())}", err=True)
        raise typer.Exit(2) from None
    except ValueError as exc:
        typer.echo(f"guidebelt certs: {exc}", err=True)
        raise typer.Exit(2) from None
    except OSError as exc:
        typer.echo(f"guidebelt certs: {exc}", err=True)
        raise typer.Exit(2) from None
    for node in nodes:
        typer.echo(f"{node.common_name:<16} {node.pair.certificate.name:<18} {node.toml.name}")
    typer.echo(f"CA and {len(nodes)} certificates in {out}")


def register(app: typer.Typer) -> None:
    app.command("certs")(certs)
