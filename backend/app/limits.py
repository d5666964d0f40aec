"""Reject oversized request bodies from their Content-Length before reading them.

Pure ASGI middleware: FastAPI parses a multipart body before any handler or
dependency runs, so the declared size is the first (and cheapest) check.
Bodies without a length are still bounded while being copied (uploads.py).
"""
from __future__ import annotations

import json
from typing import Any, Awaitable, Callable

Scope = dict[str, Any]
ASGIApp = Callable[[Scope, Callable, Callable], Awaitable[None]]


class BodyLimit:
    def __init__(self, app: ASGIApp, max_bytes: int):
        self.app, self.max_bytes = app, max_bytes

    async def __call__(self, scope: Scope, receive: Callable, send: Callable) -> None:
        if scope["type"] == "http" and scope["method"] in ("POST", "PUT", "PATCH"):
            length = dict(scope["headers"]).get(b"content-length")
            if length is not None and length.isdigit() and int(length) > self.max_bytes:
                body = json.dumps({"detail": f"request body of {int(length)} bytes is over the limit of "
                                             f"{self.max_bytes} bytes: upload fewer or smaller files "
                                             "(the server's FREECAL_MAX_UPLOAD_BYTES)"}).encode()
                await send({"type": "http.response.start", "status": 413,
                            "headers": [(b"content-type", b"application/json"),
                                        (b"content-length", str(len(body)).encode()),
                                        (b"connection", b"close")]})
                await send({"type": "http.response.body", "body": body})
                return
        await self.app(scope, receive, send)
