"""The app factory: ``create_app(settings)`` → FastAPI app with routers, error
handlers, the body-size limit, and a lifespan that opens the store and the
queue, re-sends queued jobs and runs the periodic recovery of stale ones.

The app never runs jobs itself: workers do (``freecal serve`` starts one
beside it, ``freecal worker`` starts more). Static pages (frontend/) and the
3D viewer can be mounted on this app later without touching /api.
"""
from __future__ import annotations

import json
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.responses import JSONResponse

from ..base.context import Context
from ..base.settings import Settings
from ..queue.recovery import Periodic, recover_stale, requeue_pending, resend_stuck
from ..queue.tasks import QueueUnavailable, build_queue
from . import allow, errors, frontend
from .header_limit import HeaderLimit
from .headers import SecurityHeaders
from .limits import BodyLimit, Limit
from .openapi import install_schema
from .origins import Allowed, OriginGuard
from .routers import figures, health, images, jobs, rectified, sets, viewer
from .security import ClientQuota, TokenDep, check_viewer_exposure, install_cors, install_docs

log = logging.getLogger("freecal.api")


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    check_viewer_exposure(settings)  # a token with viser on a public interface: refuse, never expose

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        ctx = Context.open(settings)
        system_tmp = spool_in(ctx.storage.tmp_dir())
        queue = build_queue(ctx)
        app.state.ctx, app.state.queue = ctx, queue
        try:
            n = requeue_pending(ctx, queue)
            if n:
                log.info("re-sent %d queued job(s) to the queue", n)
            recover_stale(ctx, queue)
        except QueueUnavailable as exc:  # serve anyway: reads work, and recovery runs again periodically
            log.warning("the queue is unavailable at start-up: %s", exc)
        sent: dict[str, float] = {}

        def recover() -> None:
            recover_stale(ctx, queue)
            resend_stuck(ctx, queue, sent)

        reaper = Periodic(settings.heartbeat_seconds, recover, "recovery")
        reaper.start()
        app.state.viewer = start_viewer(ctx) if settings.viewer else None
        try:
            yield
        finally:
            reaper.stop()
            if app.state.viewer is not None:
                app.state.viewer.stop()
            spool_in(system_tmp)

    app = FastAPI(
        title="freecal",
        version=health.VERSION,
        description="Camera calibration as a service: upload image sets, run calibration jobs on a queue, "
                    "download results. Errors answer 4xx with a message saying what to do.",
        lifespan=lifespan,
        docs_url=None, redoc_url=None,  # /docs is served locally by install_docs (no CDN)
        default_response_class=SafeJSONResponse,
    )
    app.state.settings = settings
    app.state.quota = ClientQuota(settings.max_jobs_per_client)
    errors.install(app)
    allow.install(app)  # 405: the methods the path takes
    app.add_middleware(BodyLimit, **body_limits(settings))
    install_cors(app, settings.cors_origins)
    app.add_middleware(OriginGuard, allowed=Allowed.of(settings))  # outside CORS: a refused Host never gets in
    app.add_middleware(HeaderLimit)  # 431 before anything reads a header
    app.add_middleware(SecurityHeaders)  # outermost: every answer, refusals included
    for module in (sets, images, rectified, jobs, figures, viewer, health):  # rectified before jobs: its maps.npz beats /{file}
        app.include_router(module.router, dependencies=[TokenDep])  # FREECAL_TOKEN, when set
    install_docs(app)
    install_schema(app)  # the errors as they are answered ({"detail": "..."}), in /openapi.json
    from . import viewer_proxy as proxy

    proxy.install(app)  # /viewer: the 3D view behind the same token
    frontend.mount(app)  # last: the page at / never shadows /api or /docs
    return app


class SafeJSONResponse(JSONResponse):
    """JSON whose text is escaped (\\ud800) when it cannot be UTF-8: a string stored before input was checked
    for lone surrogates must never make a read or a listing fail for everyone."""

    def render(self, content) -> bytes:
        try:
            return super().render(content)
        except UnicodeEncodeError:
            return json.dumps(content, ensure_ascii=True, allow_nan=False, separators=(",", ":")).encode()


def body_limits(settings: Settings) -> dict:
    """Uploads (POST /api/sets) take FREECAL_MAX_UPLOAD_BYTES; every other body (JSON: a job's
    inline observations) FREECAL_MAX_OBSERVATIONS_BYTES."""
    upload = Limit(settings.max_upload_bytes, "upload fewer or smaller files (the server's FREECAL_MAX_UPLOAD_BYTES)",
                   slack=1024 * 1024)  # multipart framing and the form fields around the files
    json_body = Limit(settings.max_observations_bytes, "send fewer views or points inline, or upload them as a set "
                      "first (the server's FREECAL_MAX_OBSERVATIONS_BYTES)", slack=64 * 1024)  # the job's other fields
    return {"default": json_body, "paths": {"/api/sets": upload}, "idle_seconds": settings.body_idle_seconds,
            "min_rate": settings.body_min_rate}


def spool_in(directory) -> str | None:
    """Make ``directory`` the process's temp folder; returns the previous one (to restore).

    Multipart uploads are spooled (Starlette: SpooledTemporaryFile, past 1 MB) to the
    temp folder before a handler sees them. Inside the data directory they count
    against its disk, never fill the system's /tmp (often RAM), and stay anonymous:
    the spool is unlinked at once, so nothing is left behind, even after a kill."""
    import tempfile

    previous = tempfile.tempdir
    tempfile.tempdir = None if directory is None else str(directory)
    return previous


def start_viewer(ctx: Context):
    """The 3D view (viser) on FREECAL_VIEWER_HOST (loopback), or None if it cannot start: the API serves anyway."""
    try:
        from ..viewer.server import Viewer

        view = Viewer(ctx, host=ctx.settings.viewer_host, port=ctx.settings.viewer_port)
        log.info("3D view on http://%s (browsers use /viewer/ on the API's port)", view.address)
        return view
    except Exception:  # an optional part: log why, keep serving
        log.exception("the 3D view could not start")
        return None
