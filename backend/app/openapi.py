"""/openapi.json as the service answers: every error is ``{"detail": "<string>"}`` (``Message``).

FastAPI documents its own validation answer (``HTTPValidationError``, a list of
objects) for every operation that takes input, but ``errors.py`` answers 422 with
one sentence; and some answers come from middleware, before any route runs. This
puts each in the schema where it can be returned:

- 422 on every operation that takes input, as ``Message``;
- 400 (a malformed body, or a Host this server does not answer to) and 431 (headers too large) on every
  operation, 401 too (the token, when ``FREECAL_TOKEN`` is set);
- 403 (a page of another site) on POST/PUT/PATCH/DELETE, 413 (body too large) on
  the operations with a body.
"""
from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

EVERYWHERE = {"400": "a malformed request (a body that is not the JSON or multipart it says), or a Host header "
                     "that is not a name of this server (FREECAL_ALLOWED_HOSTS)",
              "401": "FREECAL_TOKEN is set and the request does not carry it",
              "431": "the request's headers are too large"}
WRITES = {"403": "the request comes from a page of another site (FREECAL_CORS_ORIGINS)"}
WITH_BODY = {"413": "the request body is over the server's limit",
             "422": "the request is invalid: the message says which field and why"}
MESSAGE = {"$ref": "#/components/schemas/Message"}


def install_schema(app: FastAPI) -> None:
    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = get_openapi(title=app.title, version=app.version, description=app.description,
                                 routes=app.routes)
            app.openapi_schema = with_errors(schema)
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]  # FastAPI's documented way to extend the schema


def with_errors(schema: dict[str, Any]) -> dict[str, Any]:
    for path in schema.get("paths", {}).values():
        for method, operation in path.items():
            responses = operation.setdefault("responses", {})
            takes_input = "422" in responses or "requestBody" in operation or operation.get("parameters")
            wanted = {**EVERYWHERE, **(WRITES if method in ("post", "put", "patch", "delete") else {}),
                      **(WITH_BODY if "requestBody" in operation else {}),
                      **({"422": WITH_BODY["422"]} if takes_input else {})}
            for status, description in wanted.items():
                answer = responses.setdefault(status, {"description": description})
                answer["content"] = {"application/json": {"schema": MESSAGE}}
    schemas = schema.get("components", {}).get("schemas", {})
    for unused in ("HTTPValidationError", "ValidationError"):
        schemas.pop(unused, None)
    return schema
