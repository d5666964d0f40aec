"""One place that turns failures into HTTP answers: a message, never a traceback.

``ApiError`` (raised by handlers) and calib_core's ``CalibError`` (bad data or
settings) answer 4xx with their message; request validation answers 422 with
one readable sentence; anything unexpected answers 500 with a plain sentence
and is logged with its traceback on the server.
"""
from __future__ import annotations

import logging
import sqlite3

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from calib_core.errors import CalibError

from ..base.storage import storage_failure
from .schemas import JOB_KINDS

log = logging.getLogger("freecal.api")


class ApiError(Exception):
    def __init__(self, status: int, detail: str):
        super().__init__(detail)
        self.status, self.detail = status, detail


def not_found(what: str, ident: str) -> ApiError:
    return ApiError(404, f"no {what} with id {ident!r}: list them at /api/{what}s")


def install(app: FastAPI) -> None:
    @app.exception_handler(ApiError)
    async def api_error(request: Request, exc: ApiError) -> JSONResponse:
        return JSONResponse({"detail": exc.detail}, status_code=exc.status)

    @app.exception_handler(CalibError)
    async def calib_error(request: Request, exc: CalibError) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=422)

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
        parts = []
        for err in exc.errors():
            where = ".".join(str(p) for p in err.get("loc", ()) if p not in ("body", *JOB_KINDS))  # a union's tags
            msg = str(err.get("msg"))
            if "Expected UploadFile" in msg:  # a form field where a file belongs: FastAPI names Python classes
                msg = "expected a file, got a text field: send each file as a file part (curl -F 'files=@photo.png')"
            parts.append(f"{where}: {msg}" if where else msg)
        return JSONResponse({"detail": "invalid request: " + "; ".join(parts) + " (see /docs for the schema)"},
                            status_code=422)

    @app.exception_handler(OSError)
    async def os_error(request: Request, exc: OSError) -> JSONResponse:
        answer = storage_failure(exc)
        if answer is None:
            return await unexpected(request, exc)
        log.error("%s %s: %s", request.method, request.url.path, exc)
        return JSONResponse({"detail": answer[1]}, status_code=answer[0])

    @app.exception_handler(sqlite3.OperationalError)
    async def db_error(request: Request, exc: sqlite3.OperationalError) -> JSONResponse:
        answer = storage_failure(exc)
        if answer is None:
            return await unexpected(request, exc)
        log.error("%s %s: %s", request.method, request.url.path, exc)
        return JSONResponse({"detail": answer[1]}, status_code=answer[0])

    @app.exception_handler(Exception)
    async def unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.exception("unexpected error on %s %s", request.method, request.url.path)
        return JSONResponse({"detail": "internal error (logged on the server); retry, and report it if it persists"},
                            status_code=500)
