"""Headers every answer carries, and HEAD wherever GET is: pure ASGI middleware.

- ``X-Content-Type-Options: nosniff`` everywhere: a browser never runs an uploaded
  image or a result file as a script or a page, whatever bytes it holds.
- ``Content-Security-Policy`` on the page (``frontend/``): its scripts, styles and
  fetches come from this server only, nothing else may run (no inline script, no
  plugin), and only this server may frame it (``frame-ancestors 'self'``, against
  clickjacking). /docs (Swagger's inline start-up script) and /viewer (viser's page,
  framed by ours) get ``frame-ancestors 'self'`` alone.
- ``Referrer-Policy: same-origin``: links carrying ``?token=`` never leak it to
  another site.
- ``HEAD``: answered as GET without the body (FastAPI routes take GET only), so a
  client can check a result's size and type before downloading it.
"""
from __future__ import annotations

from .asgi import ASGIApp, Scope, Send

PAGE_CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
            "connect-src 'self'; frame-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
            "frame-ancestors 'self'")
FRAME_CSP = "frame-ancestors 'self'"
NOT_THE_PAGE = ("/api/", "/docs", "/viewer", "/openapi.json")


class SecurityHeaders:
    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        head = scope["method"] == "HEAD"
        csp = FRAME_CSP if scope["path"].startswith(NOT_THE_PAGE) else PAGE_CSP

        async def send_with_headers(message: dict) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []),
                                                  (b"x-content-type-options", b"nosniff"),
                                                  (b"content-security-policy", csp.encode()),
                                                  (b"referrer-policy", b"same-origin")]}
            elif message["type"] == "http.response.body" and head:
                message = {**message, "body": b""}   # the headers (Content-Length too) are GET's
            await send(message)

        await self.app({**scope, "method": "GET"} if head else scope, receive, send_with_headers)
