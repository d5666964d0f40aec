"""Request headers are bounded: over ``MAX_HEADER_BYTES`` the answer is 431, with what to do.

Two places see them, depending on how the bytes arrive:

- uvicorn's h11 protocol stops buffering an unfinished header block past the limit
  (``h11_max_incomplete_event_size``; h11 raises with the hint 431) but answers every
  parse error with a bare 400 "Invalid HTTP request received."; ``H11With431`` answers
  that case as what it is;
- a header block that arrived whole in one read is parsed before h11 looks at its size,
  so ``HeaderLimit`` (ASGI middleware) measures the parsed headers too.
"""
from __future__ import annotations

import json
import os
import sys

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from .asgi import ASGIApp, Scope, Send, refuse

MAX_HEADER_BYTES = 16 * 1024   # h11's own default: ample for a token and cookies
TOO_LARGE = (f"the request's headers are larger than this server takes ({MAX_HEADER_BYTES // 1024} KiB): send "
             "fewer or shorter headers (cookies; a token goes in 'Authorization: Bearer <token>')")


class HeaderLimit:
    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket") and \
                sum(len(k) + len(v) + 4 for k, v in scope["headers"]) > MAX_HEADER_BYTES:
            await refuse(scope, send, 431, TOO_LARGE)
            return
        await self.app(scope, receive, send)


class H11With431(H11Protocol):
    def send_400_response(self, msg: str) -> None:
        # uvicorn calls this inside its `except h11.RemoteProtocolError` (the error is not passed in)
        error = sys.exc_info()[1]
        if getattr(error, "error_status_hint", None) != 431:
            super().send_400_response(msg)
            return
        body = json.dumps({"detail": TOO_LARGE}).encode()
        for event in (h11.Response(status_code=431, reason=b"Request Header Fields Too Large",
                                   headers=[(b"content-type", b"application/json"),
                                            (b"content-length", str(len(body)).encode()),
                                            (b"x-content-type-options", b"nosniff"), (b"connection", b"close")]),
                      h11.Data(data=body), h11.EndOfMessage()):
            self.transport.write(self.conn.send(event))
        self.transport.close()


def uvicorn_options() -> dict:
    """uvicorn.run / uvicorn.Config keyword arguments of `freecal serve` (the tests' servers use them too)."""
    # X-Forwarded-For is believed only when FORWARDED_ALLOW_IPS (uvicorn's setting) names the proxy: by
    # default uvicorn believes any loopback client, whose forged header would escape the per-client job quota
    trusted_proxy = bool(os.environ.get("FORWARDED_ALLOW_IPS", "").strip())
    return {"http": H11With431, "h11_max_incomplete_event_size": MAX_HEADER_BYTES, "log_level": "warning",
            "proxy_headers": trusted_proxy}
