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
from collections.abc import Callable
from typing import Any

from fastapi import HTTPException, Request
from fastapi.routing import APIRoute
from starlette.concurrency import run_in_threadpool

from .errors import ApiError

# The deepest documents the API takes are observations (document > views > view >
# points > point: 5 levels) and job settings (body > settings > interior_knots > axis: 4).
MAX_DEPTH = 32


def parse(raw: bytes | str, what: str) -> Any:
    """The JSON value in ``raw``, or ApiError 422 naming ``what`` when it is not JSON or nests too deep."""
    try:
        doc = json.loads(raw, object_pairs_hook=_object)
    except RecursionError:
        doc = None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ApiError(422, f"{what} is not valid JSON ({exc}): send a JSON document (see /docs)") from None
    else:
        if _depth_within(doc, MAX_DEPTH):
            return doc
    raise ApiError(422, f"{what} nests arrays and objects more than {MAX_DEPTH} levels deep: "
                        "no freecal document needs that many; send the document itself")


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # A hook in Python, not C: the parser runs a line of Python after each object, where the
    # interpreter can hand the GIL to the event loop. Without it one C call holds the GIL for
    # the whole body (a second per 20 MB), and a thread would not keep /api/health fast.
    return dict(pairs)


def _depth_within(doc: Any, limit: int) -> bool:
    """Whether ``doc`` nests at most ``limit`` levels (iterative: no recursion, whatever the depth)."""
    stack = [(doc, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > limit:
            return False
        children = value.values() if isinstance(value, dict) else value
        stack.extend([(c, depth + 1) for c in children if isinstance(c, (dict, list))])
    return True


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
