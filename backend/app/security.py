"""What guards the API when it faces a network: the optional token, CORS, the
per-client job quota and the local /docs page.

- ``require_token``: a FastAPI dependency on every /api router and on the 3D
  view's proxy (/viewer). With ``FREECAL_TOKEN`` set, a request needs
  ``Authorization: Bearer <token>`` or ``?token=<token>`` (for <img src>,
  download links and websockets, which cannot send headers), else 401. The page
  (frontend/) and /docs stay public: they hold no data and must load to ask.
- ``check_viewer_exposure``: viser cannot check a token itself (its port takes only
  the proxy's key: viewer/gate.py), so with a token set its own port must also stay
  on loopback (reached only through /viewer).
- CORS is closed unless ``FREECAL_CORS_ORIGINS`` lists origins. Host and Origin
  checks (DNS rebinding, cross-site writes): origins.py.
- ``ClientQuota``: at most ``FREECAL_MAX_JOBS_PER_CLIENT`` queued or running
  jobs per client IP (429 with advice beyond).
- /docs: Swagger UI from the ``swagger-ui-bundle`` package, served from this
  server (no CDN); without that package, a plain local page that links
  /openapi.json.
"""
from __future__ import annotations

import hmac
import threading
from collections import Counter
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import asynccontextmanager, contextmanager
from typing import Annotated

from fastapi import Depends, FastAPI, Request
from fastapi.responses import HTMLResponse
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection

from calib_core.errors import SettingsError

from ..base.repository import jobs as job_rows
from .errors import ApiError

TOKEN_NEEDED = ("this server needs a token: send the header 'Authorization: Bearer <token>' "
                "(or ?token=<token> in a link); ask its administrator for FREECAL_TOKEN")
LOOPBACK = ("127.0.0.1", "localhost", "::1")
# A set's images are someone's photos, served behind the token when one is set: the browser may keep
# them an hour (a stored image never changes), a cache shared between users (a proxy) may not.
PRIVATE_IMAGE = "private, max-age=3600"


def token_ok(conn: HTTPConnection) -> bool:
    """True without FREECAL_TOKEN, or when the request (HTTP or websocket) carries it."""
    expected = conn.app.state.settings.token
    if not expected:
        return True
    header = conn.headers.get("authorization", "")
    given = header[7:].strip() if header[:7].lower() == "bearer " else conn.query_params.get("token", "")
    return hmac.compare_digest(given.encode(), expected.encode())


async def require_token(request: Request) -> None:  # async: no thread hop per request (see deps.py)
    if not token_ok(request):
        raise ApiError(401, TOKEN_NEEDED)


TokenDep = Depends(require_token)


def check_viewer_exposure(settings) -> None:
    """Refuse to serve (SettingsError) when a token is set but viser would listen beyond loopback:
    viser has no hook to check a token on its own port, so that port would show every job to anyone."""
    if settings.token and settings.viewer and settings.viewer_host not in LOOPBACK:
        raise SettingsError(
            f"FREECAL_VIEWER_HOST={settings.viewer_host} with FREECAL_TOKEN set: the 3D view (viser) cannot check "
            "the token on its own port, so it would show every calibration to anyone who reaches it. Leave "
            "FREECAL_VIEWER_HOST at 127.0.0.1 (the page reaches the 3D view through /viewer on the API's port, "
            "which checks the token), or turn the view off with FREECAL_VIEWER=0")


def install_cors(app: FastAPI, origins: str) -> None:
    allowed = [o.strip().rstrip("/") for o in origins.split(",") if o.strip()]
    if not allowed:
        return  # closed: browsers refuse other sites' reads of this API
    from fastapi.middleware.cors import CORSMiddleware

    app.add_middleware(CORSMiddleware, allow_origins=allowed, allow_methods=["GET", "POST", "DELETE"],
                       allow_headers=["Authorization", "Content-Type"], allow_credentials=False)


class ClientQuota:
    """Job ids per client IP, in this API process; a job stops counting once it is no longer
    queued or running (checked in the database). After a restart the count starts afresh.

    A request holds its place from the check until its job exists (``place``): checked and
    counted apart, requests arriving together all passed the check."""

    def __init__(self, limit: int):
        self.limit = limit
        self.lock = threading.Lock()
        self.active: dict[str, set[str]] = {}
        self.placing: Counter[str] = Counter()  # requests checked whose job is not made yet

    @contextmanager
    def place(self, ctx, client: str) -> Iterator[Callable[[str | None], None]]:
        """429 when ``client`` has its limit of jobs queued or running (or being made); else a
        place, and a function that records the job made in it (None: none was)."""
        self._claim(ctx, client)
        try:
            yield lambda job_id: self._made(client, job_id)
        finally:
            self._release(client)

    @asynccontextmanager
    async def place_async(self, ctx, client: str) -> AsyncIterator[Callable[[str | None], None]]:
        """``place``, its check (the database) on a worker thread."""
        await run_in_threadpool(self._claim, ctx, client)
        try:
            yield lambda job_id: self._made(client, job_id)
        finally:
            self._release(client)

    def _claim(self, ctx, client: str) -> None:
        with self.lock:
            ids = self.active.get(client, set())
            live = {i for i in ids if (job := job_rows.get(ctx.db, i)) is not None and job["state"] in job_rows.ACTIVE}
            self.active[client] = live
            held = len(live) + self.placing[client]
            if held >= self.limit:
                raise ApiError(429, f"you have {held} jobs queued or running, the limit per client is "
                                    f"{self.limit}: wait for some to finish (or cancel them) and retry")
            self.placing[client] += 1

    def _made(self, client: str, job_id: str | None) -> None:
        if job_id is not None:
            with self.lock:
                self.active.setdefault(client, set()).add(job_id)

    def _release(self, client: str) -> None:
        with self.lock:
            self.placing[client] -= 1
            if not self.placing[client]:
                del self.placing[client]


def client_of(request: Request) -> str:
    return request.client.host if request.client else "unknown"


async def get_quota(request: Request) -> ClientQuota:
    return request.app.state.quota


QuotaDep = Annotated[ClientQuota, Depends(get_quota)]


def install_docs(app: FastAPI) -> str:
    """Serve /docs without the internet; returns what it serves ("swagger" or "plain")."""
    from fastapi.openapi.docs import get_swagger_ui_html

    try:
        from swagger_ui_bundle import swagger_ui_path
    except ImportError:
        swagger_ui_path = None

    if swagger_ui_path is not None:
        from fastapi.staticfiles import StaticFiles

        app.mount("/docs/assets", StaticFiles(directory=swagger_ui_path), name="docs-assets")

        @app.get("/docs", include_in_schema=False)
        def docs() -> HTMLResponse:
            return get_swagger_ui_html(openapi_url="/openapi.json", title="freecal API",
                                       swagger_js_url="/docs/assets/swagger-ui-bundle.js",
                                       swagger_css_url="/docs/assets/swagger-ui.css",
                                       swagger_favicon_url="/docs/assets/favicon-32x32.png")
        return "swagger"

    @app.get("/docs", include_in_schema=False)
    def plain_docs() -> HTMLResponse:
        paths = [(getattr(r, "methods", None) or [], getattr(r, "path", "")) for r in app.routes]
        rows = "".join(f"<li><code>{', '.join(sorted(methods))} {path}</code></li>"
                       for methods, path in paths if path.startswith("/api"))
        return HTMLResponse(f"<!doctype html><title>freecal API</title><h1>freecal API</h1>"
                            f"<p>The schema: <a href='/openapi.json'>/openapi.json</a></p><ul>{rows}</ul>")
    return "plain"
