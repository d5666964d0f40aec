"""Answers that pure ASGI middleware sends before the app runs: a JSON error, or a refused websocket."""
from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from typing import Any

Scope = dict[str, Any]
Send = Callable[[dict[str, Any]], Awaitable[None]]
ASGIApp = Callable[[Scope, Callable, Send], Awaitable[None]]


async def refuse(scope: Scope, send: Send, status: int, detail: str) -> None:
    """``{"detail": ...}`` with ``status`` (HTTP), or a handshake refused with HTTP 403 (websocket:
    closing before accept; the browser sees no reason, the close frame's text is for other clients)."""
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008, "reason": detail[:120]})
        return
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})
