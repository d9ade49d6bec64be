"""The view served: zenoh node + web app under uvicorn, in the foreground or on a thread.

Bound to 127.0.0.1 unless told otherwise: the page shows where a person is walking. With a
certificate and key (those of the access-control work, where it is set up) it is served
over TLS only.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path

import uvicorn
import zenoh

from .app import make_app
from .node import ViewNode
from .state import ViewState


@dataclass(frozen=True)
class ServeSettings:
    host: str = "127.0.0.1"
    port: int = 8765
    hz: float = 10.0
    certfile: Path | None = None
    keyfile: Path | None = None

    def __post_init__(self) -> None:
        if (self.certfile is None) != (self.keyfile is None):
            raise ValueError("TLS needs both a certificate and its key")
        if not 1.0 <= self.hz <= 60.0:
            raise ValueError(f"hz {self.hz} outside 1..60")

    @property
    def scheme(self) -> str:
        return "https" if self.certfile else "http"

    def url(self) -> str:
        return f"{self.scheme}://{self.host}:{self.port}/"


def uvicorn_config(state: ViewState, settings: ServeSettings) -> uvicorn.Config:
    tls = {}
    if settings.certfile is not None:
        tls = {"ssl_certfile": str(settings.certfile), "ssl_keyfile": str(settings.keyfile)}
    return uvicorn.Config(
        make_app(state, settings.hz),
        host=settings.host,
        port=settings.port,
        log_level="warning",
        ws="websockets-sansio",
        lifespan="off",
        **tls,
    )


class ViewThread:
    """``with ViewThread(session, settings) as v:`` serves the view until the block ends
    (for the tests, the demo and the measurement; ``guidebelt view`` runs it in front)."""

    def __init__(self, session: zenoh.Session, settings: ServeSettings) -> None:
        self.settings = settings
        self.state = ViewState()
        self.node = ViewNode(session, self.state)
        self.server = uvicorn.Server(uvicorn_config(self.state, settings))
        self._thread = threading.Thread(target=self.server.run, name="view-http", daemon=True)

    def __enter__(self) -> ViewThread:
        self.node.start()
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self.server.started and self._thread.is_alive():
            if time.monotonic() > deadline:
                break
            time.sleep(0.02)
        if not self.server.started:
            self.close()
            raise RuntimeError(f"the view did not start on {self.settings.url()}")
        return self

    def close(self) -> None:
        self.server.should_exit = True
        self._thread.join(5.0)
        self.node.close()

    def __exit__(self, *exc: object) -> None:
        self.close()
