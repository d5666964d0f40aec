"""Refuse oversized request bodies (413) before the app holds them.

Pure ASGI middleware, in front of every route: FastAPI parses a body (a
multipart upload, spooled to disk; a JSON document, into memory) before any
handler or dependency runs. A declared Content-Length over the limit is
refused before reading a byte; a body without one (``Transfer-Encoding:
chunked``) is counted as it arrives and refused the moment it passes the limit,
so at most the limit is ever read, spooled or parsed. A body that stalls is
answered 408 after ``idle_seconds`` of silence (FREECAL_BODY_IDLE_SECONDS), and so is
one that trickles in slower than ``min_rate`` on average (FREECAL_BODY_MIN_RATE).

Each path has its limit: uploads (POST /api/sets) take FREECAL_MAX_UPLOAD_BYTES,
every other body (JSON: a job with inline observations) FREECAL_MAX_OBSERVATIONS_BYTES.
"""
from __future__ import annotations

import asyncio
import json
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

Scope = dict[str, Any]
Message = dict[str, Any]
ASGIApp = Callable[[Scope, Callable, Callable], Awaitable[None]]


@dataclass(frozen=True)
class Limit:
    max_bytes: int      # the setting's value, as the message says it
    advice: str         # what to do instead, naming the setting
    slack: int = 0      # bytes allowed past max_bytes: the multipart framing around the files

    @property
    def bytes_allowed(self) -> int:
        return self.max_bytes + self.slack


class _TooLarge(Exception):
    """The body went past its limit (or stopped arriving) while being read."""


class BodyLimit:
    """``idle_seconds``: a body that stops arriving for this long is answered 408 and its connection
    closed: uvicorn itself waits for a stalled body forever (slowloris). Counted per read, so a slow
    upload that moves is fine, unless it moves slower than ``min_rate`` bytes a second on average:
    after ``idle_seconds`` of grace, each byte in buys 1 / ``min_rate`` seconds more (Apache's
    mod_reqtimeout rule), so a byte every few seconds cannot hold a connection for days."""

    def __init__(self, app: ASGIApp, default: Limit, paths: dict[str, Limit], idle_seconds: float,
                 min_rate: float):
        self.app, self.default, self.paths = app, default, paths
        self.idle_seconds, self.min_rate = idle_seconds, min_rate

    async def __call__(self, scope: Scope, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.paths.get(scope["path"], self.default)
        length = dict(scope["headers"]).get(b"content-length", b"")
        if length.isdigit() and int(length) > limit.bytes_allowed:
            await _refuse(send, limit, f"request body of {int(length)} bytes")
            return
        received, refused, started, stalled, slow, whole = 0, False, False, False, False, False
        loop = asyncio.get_running_loop()
        begun = loop.time()

        async def counted() -> Message:
            nonlocal received, refused, stalled, slow, whole
            if whole:  # the body is in: later reads wait for a disconnect (streamed answers), unbounded
                return await receive()
            wait = self.idle_seconds
            if self.min_rate > 0:
                left = begun + self.idle_seconds + received / self.min_rate - loop.time()
                slow = left < wait
                wait = max(left, 0.0)
            try:
                message = await asyncio.wait_for(receive(), wait)
            except TimeoutError:
                stalled = refused = True
                raise _TooLarge from None
            if message["type"] == "http.request":
                whole = not message.get("more_body", False)
                received += len(message.get("body", b""))
                if received > limit.bytes_allowed:
                    refused = True
                    raise _TooLarge
            return message

        async def guarded(message: Message) -> None:
            nonlocal started
            if refused:  # the app's own answer to a body cut short (FastAPI's: 400) gives way to the 413
                return
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counted, guarded)
        except Exception:
            if not refused:
                raise
        if stalled and not started and slow:
            await _answer(send, 408, f"the request body arrived too slowly ({received} bytes in "
                                     f"{loop.time() - begun:.0f} s, under {self.min_rate:g} bytes a second on average, "
                                     "the server's FREECAL_BODY_MIN_RATE): upload from a faster connection, or fewer "
                                     "files at a time")
        elif stalled and not started:
            await _answer(send, 408, f"the request body stopped arriving (nothing for {self.idle_seconds:g} s, "
                                     f"{received} bytes in): send the whole body at once, then retry")
        elif refused and not started:
            await _refuse(send, limit, f"request body of more than {limit.bytes_allowed} bytes")


async def _refuse(send: Callable, limit: Limit, what: str) -> None:
    await _answer(send, 413, f"{what} is over the limit of {limit.max_bytes} bytes: {limit.advice}")


async def _answer(send: Callable, status: int, detail: str) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")]})  # the rest of the body is never read
    await send({"type": "http.response.body", "body": body})
