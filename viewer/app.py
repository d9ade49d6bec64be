"""The web side of the view: a Starlette app, a WebSocket of frames, the map as a PNG.

The page (``static/index.html`` + ``static/view.js``, hand-written, no build step, nothing
fetched from elsewhere) opens ``/ws`` and gets every user's state ``hz`` times a second as
JSON; the map, larger and rarer, is an image at ``/map/<user>.png?v=<version>`` that the
page fetches again only when the frame says its version changed.
"""

from __future__ import annotations

import asyncio
import json
import struct
import zlib
from importlib import resources

import numpy as np
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from .state import ViewState

GREY = np.array([255, 24, 200], dtype=np.uint8)
"""Free (white), occupied (near black), unknown (light grey): occupancy 0, 1, 2."""


def png_of(occupancy: np.ndarray) -> bytes:
    """An 8-bit greyscale PNG of an occupancy grid, row 0 at the top (north), as on the map."""
    grey = GREY[np.clip(occupancy, 0, 2)]
    h, w = grey.shape
    # Each scanline starts with filter type 0 (none).
    raw = np.hstack([np.zeros((h, 1), np.uint8), grey]).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    return b"".join(
        (b"\x89PNG\r\n\x1a\n", chunk(b"IHDR", header), chunk(b"IDAT", zlib.compress(raw, 6)),
         chunk(b"IEND", b""))
    )  # fmt: skip


def _static(name: str) -> bytes:
    return resources.files("viewer").joinpath("static").joinpath(name).read_bytes()


def make_app(state: ViewState, hz: float = 10.0) -> Starlette:
    """The app serving ``state``; each WebSocket client gets a frame every ``1 / hz`` s."""
    page, script = _static("index.html"), _static("view.js")
    period = 1.0 / hz

    async def index(_request: Request) -> Response:
        return Response(page, media_type="text/html; charset=utf-8")

    async def view_js(_request: Request) -> Response:
        return Response(script, media_type="text/javascript; charset=utf-8")

    async def frame(_request: Request) -> Response:
        return JSONResponse(state.frame())

    async def map_png(request: Request) -> Response:
        got = state.map_of(request.path_params["user"])
        if got is None:
            return Response(b"no map yet", status_code=404, media_type="text/plain")
        occupancy, version = got
        png = await asyncio.to_thread(png_of, occupancy)
        headers = {"Cache-Control": "no-store", "X-Map-Version": str(version)}
        return Response(png, media_type="image/png", headers=headers)

    async def frames(ws: WebSocket) -> None:
        await ws.accept()
        loop = asyncio.get_running_loop()
        next_at = loop.time()
        try:
            while True:
                await ws.send_text(json.dumps(state.frame(), separators=(",", ":")))
                # On a fixed schedule, not "period after the send": the rate holds at 10 Hz
                # even when a frame takes a few milliseconds to build.
                next_at = max(next_at + period, loop.time())
                await asyncio.sleep(next_at - loop.time())
        except (WebSocketDisconnect, RuntimeError, OSError):
            return

    return Starlette(
        routes=[
            Route("/", index),
            Route("/view.js", view_js),
            Route("/state", frame),
            Route("/map/{user}.png", map_png),
            WebSocketRoute("/ws", frames),
        ]
    )
