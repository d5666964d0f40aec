"""JSON from clients, parsed within bounds: at most ``MAX_DEPTH`` levels of nesting,
checked before any code walks the document, and (for request bodies) parsed in a
worker thread, so a large body never stalls the event loop (/api/health stays fast).

The body's size is bounded before this, as it arrives (limits.py). Python's
parser refuses nesting past its recursion limit itself (RecursionError, caught
here); every walk after it (validation, the NaN check, error messages that
quote a value) sees at most ``MAX_DEPTH`` levels.
"""
from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable
from typing import Any

from fastapi import HTTPException, Request
from fastapi.routing import APIRoute
from starlette.concurrency import run_in_threadpool

from calib_core.observations import MAX_DEPTH, SURROGATE_ESCAPE, depth_within, not_unicode

from .errors import ApiError

# The core's lone-surrogate escape, searched for in a body's bytes: a large body is walked only if it may hold one
SURROGATE_ESCAPE_BYTES = re.compile(SURROGATE_ESCAPE.pattern.encode())


def parse(raw: bytes | str, what: str) -> Any:
    """The JSON value in ``raw``, or ApiError 422 naming ``what`` when it is not JSON, nests too deep
    or holds text that is not valid Unicode."""
    try:
        doc = json.loads(raw, object_pairs_hook=_object)
    except RecursionError:
        pass
    except (ValueError, UnicodeDecodeError) as exc:
        reason = str(exc)
        if "int_max_str_digits" in reason:  # Python's own advice (sys.set_int_max_str_digits) means nothing here
            reason = f"a number has more than {sys.get_int_max_str_digits()} digits"
        raise ApiError(422, f"{what} is not valid JSON ({reason}): send a JSON document (see /docs)") from None
    else:
        if depth_within(doc, MAX_DEPTH):
            may = SURROGATE_ESCAPE.search(raw) if isinstance(raw, str) else SURROGATE_ESCAPE_BYTES.search(raw)
            bad = not_unicode(doc) if may else None
            if bad is not None:
                # "\ud800" is valid JSON but no character: it cannot be stored, shown or answered (UTF-8)
                raise ApiError(422, f"{what}: {bad or 'the document'} holds text that is not valid Unicode (a lone "
                                    "surrogate escape such as \\ud800): send the text as UTF-8")
            return doc
    raise ApiError(422, f"{what} nests arrays and objects more than {MAX_DEPTH} levels deep: "
                        "no freecal document needs that many; send the document itself")


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # A hook in Python, not C: the parser runs a line of Python after each object, where the
    # interpreter can hand the GIL to the event loop. Without it one C call holds the GIL for
    # the whole body (a second per 20 MB), and a thread would not keep /api/health fast.
    return dict(pairs)


class BoundedJSONRoute(APIRoute):
    """A route whose JSON body is parsed by ``parse``, in a worker thread (``APIRouter(route_class=...)``)."""

    def get_route_handler(self) -> Callable:
        handler = super().get_route_handler()

        async def bounded(request: Request):
            return await handler(_BoundedJSONRequest(request.scope, request.receive))

        return bounded


class _BoundedJSONRequest(Request):
    async def json(self) -> Any:  # what FastAPI calls to read a JSON body
        if not hasattr(self, "_json"):
            raw = await self.body()
            try:
                self._json = await run_in_threadpool(parse, raw, "the request body")
            except ApiError as exc:  # FastAPI passes an HTTPException on as it is, and makes anything else a bare 400
                raise HTTPException(exc.status, f"invalid request: {exc.detail}") from None  # as errors.py words 422s
        return self._json
