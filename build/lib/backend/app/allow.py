"""405 answers name the methods the path really takes.

The page's static mount at ``/`` matches every path, so a method an /api path does
not take (``OPTIONS /api/jobs``) reaches StaticFiles, which answers ``Allow: GET,
HEAD`` whatever the path. This handler reads the path's methods from the OpenAPI
schema instead (the one list of what each path takes).
"""
from __future__ import annotations

import functools
import re

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException


def install(app: FastAPI) -> None:
    @app.exception_handler(HTTPException)
    async def http_error(request: Request, exc: HTTPException) -> JSONResponse:
        if exc.status_code != 405:
            return JSONResponse({"detail": exc.detail}, status_code=exc.status_code, headers=exc.headers)
        allowed = ", ".join(methods_of(app.openapi(), request.url.path))
        return JSONResponse({"detail": f"{request.method} is not a method of {request.url.path}: it takes {allowed}"},
                            status_code=405, headers={"Allow": allowed})


def methods_of(schema: dict, path: str) -> list[str]:
    """The methods of the path's most specific template (``/api/jobs/{id}/cancel`` rather than
    ``/api/jobs/{id}/{name}``); GET alone for paths outside the schema (the page's files)."""
    matches = [t for t in schema["paths"] if _pattern(t).fullmatch(path)]
    fewest = min((t.count("{") for t in matches), default=0)
    methods = {m.upper() for t in matches if t.count("{") == fewest for m in schema["paths"][t]} or {"GET"}
    if "GET" in methods:
        methods.add("HEAD")   # headers.SecurityHeaders answers HEAD as GET
    return sorted(methods)


@functools.cache
def _pattern(template: str) -> re.Pattern:
    """``/api/jobs/{job_id}`` → a pattern matching ``/api/jobs/<one segment>``."""
    return re.compile(re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(template)))
