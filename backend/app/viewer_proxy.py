"""/viewer: the 3D view (viser) through the API's own port, behind the token.

viser serves its page and its websocket on a port of its own, on loopback, and
its websocket takes only this proxy (``gate.py``: the per-process key added
here). Browsers reach it here, where the Host and Origin (``app/origins.py``,
middleware) and ``security.token_ok`` are checked before a byte of viser's comes
back:

- ``GET /viewer/<path>`` forwards to viser's HTTP server (its client page);
- the websocket ``/viewer`` is accepted only with the token (``?token=``: a
  browser cannot put headers on a websocket) from this server's own page (or a
  ``FREECAL_CORS_ORIGINS`` one), and then relays frames both ways, the browser's
  Origin left out. Otherwise the handshake is refused (HTTP 403): no scene data.

viser's page connects to the websocket at its own address minus the trailing
slash (``/viewer/`` -> ``/viewer``); the page passes the full websocket URL in
viser's ``?websocket=`` parameter (``frontend/js/api.js``), with the token when
one is needed, the job on screen (``?job=``) and the page's pairing key
(``?pair=``). Those two go on to viser as headers (``gate.JOB_HEADER``,
``gate.PAIR_HEADER``) when they look like an id and a key, so each tab opens on
the job its page showed, not on whichever was asked for last.
"""
from __future__ import annotations

import asyncio
import re
import urllib.error
import urllib.parse
import urllib.request
from typing import Any

from fastapi import FastAPI, Request, WebSocket
from fastapi.responses import Response

from ..viewer.gate import JOB_HEADER, KEY_HEADER, PAIR_HEADER
from .errors import ApiError
from .security import TOKEN_NEEDED, TokenDep, token_ok

MAX_FRAME = 64 * 1024 * 1024  # viser itself allows 50 MB messages
# what a tab may ask for in its websocket URL, passed on as a header: a job id, the page's pairing key
ASKS = {"job": (JOB_HEADER, re.compile(r"[0-9a-f]{1,32}")), "pair": (PAIR_HEADER, re.compile(r"[A-Za-z0-9_-]{8,64}"))}


def install(app: FastAPI) -> None:
    @app.get("/viewer/{path:path}", include_in_schema=False, dependencies=[TokenDep])
    def viewer_page(path: str, request: Request) -> Response:
        viewer = running_viewer(request.app)
        headers = {"Accept-Encoding": request.headers.get("accept-encoding", "identity")}
        # the path arrives decoded ("a%20b" is "a b"): quoted again, it is a URL (urllib refuses spaces)
        url = f"http://{viewer.address}/{urllib.parse.quote(path)}"
        try:  # a plain def: FastAPI runs it in its thread pool, so this blocking read is fine
            with urllib.request.urlopen(urllib.request.Request(url, headers=headers),
                                        timeout=30) as r:
                status, body, got = r.status, r.read(), r.headers
        except urllib.error.HTTPError as e:
            status, body, got = e.code, e.read(), e.headers
        except OSError as e:
            raise ApiError(503, f"the 3D view does not answer ({e}); restart the server") from None
        keep = {k: got[k] for k in ("Content-Type", "Content-Encoding") if got.get(k)}
        return Response(body, status_code=status, headers=keep)

    @app.websocket("/viewer")
    async def viewer_socket(ws: WebSocket) -> None:
        viewer = getattr(ws.app.state, "viewer", None)
        if viewer is None or not token_ok(ws):
            # closing before accept refuses the handshake (HTTP 403): nothing of the scene is sent
            await ws.close(code=1008, reason="3D view off" if viewer is None else TOKEN_NEEDED[:120])
            return
        await relay(ws, f"ws://{viewer.address}/", {KEY_HEADER: viewer.gate.key, **asked_headers(ws)})


def asked_headers(ws: WebSocket) -> dict[str, str]:
    """The tab's ``?job=`` and ``?pair=`` as headers for viser; a value of another shape is dropped."""
    out = {}
    for param, (header, shape) in ASKS.items():
        value = ws.query_params.get(param, "")
        if shape.fullmatch(value):
            out[header] = value
    return out


def running_viewer(app: FastAPI) -> Any:
    """The app's 3D view, or a 503 saying it is off."""
    viewer = getattr(app.state, "viewer", None)
    if viewer is None:
        raise ApiError(503, "the 3D view is off on this server (FREECAL_VIEWER=0); start it with FREECAL_VIEWER=1")
    return viewer


async def relay(ws: WebSocket, upstream_url: str, headers: dict[str, str]) -> None:
    """Connect to viser with the browser's subprotocol (viser checks its version there), then copy
    frames both ways until either side closes; viser's close code (e.g. 1002, version mismatch) is passed on."""
    from websockets.asyncio.client import connect
    from websockets.exceptions import ConnectionClosed

    offered = list(ws.scope.get("subprotocols") or [])
    try:
        upstream = await connect(upstream_url, subprotocols=offered or None, additional_headers=headers,
                                 max_size=MAX_FRAME, compression=None, open_timeout=10)
    except Exception:  # viser gone, refusing or slow: tell the browser, not a traceback
        await ws.close(code=1011, reason="the 3D view does not answer")
        return
    await ws.accept(subprotocol=upstream.subprotocol)

    async def down() -> None:
        try:
            async for frame in upstream:
                await (ws.send_bytes(frame) if isinstance(frame, bytes) else ws.send_text(frame))
        except ConnectionClosed:
            pass

    async def up() -> None:
        while True:
            msg = await ws.receive()
            if msg["type"] == "websocket.disconnect":
                return
            await upstream.send(msg["bytes"] if msg.get("bytes") is not None else msg.get("text", ""))

    tasks = [asyncio.create_task(down()), asyncio.create_task(up())]
    try:
        await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    finally:
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await upstream.close()
        try:
            await ws.close(code=_sendable(upstream.close_code), reason=(upstream.close_reason or "")[:120])
        except Exception:  # the browser already left
            pass


def _sendable(code: int | None) -> int:
    """viser's close code if a close frame may carry it (1005/1006 only describe a lost connection)."""
    if code is not None and (1000 <= code <= 1003 or 1007 <= code <= 1014 or 3000 <= code <= 4999):
        return code
    return 1000
