"""The app factory: ``create_app(settings)`` → FastAPI app with routers, error
handlers, the body-size limit, and a lifespan that opens the store and the
queue, re-sends queued jobs and runs the periodic recovery of stale ones.

The app never runs jobs itself: workers do (``freecal serve`` starts one
beside it, ``freecal worker`` starts more). Static pages (frontend/) and the
3D viewer can be mounted on this app later without touching /api.
"""
from __future__ import annotations

import logging
from contextlib import asynccontextmanager
from typing import AsyncIterator

from fastapi import FastAPI

from ..queue.recovery import Periodic, recover_stale, requeue_pending, resend_stuck
from ..queue.tasks import QueueUnavailable, build_queue
from . import errors
from .context import Context
from .limits import BodyLimit
from . import frontend
from .security import ClientQuota, TokenDep, check_viewer_exposure, install_cors, install_docs
from .routers import figures, health, images, jobs, rectified, sets, viewer
from .settings import Settings

log = logging.getLogger("freecal.api")


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings.from_env()
    check_viewer_exposure(settings)  # a token with viser on a public interface: refuse, never expose

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        ctx = Context.open(settings)
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

    app = FastAPI(
        title="freecal",
        version=health.VERSION,
        description="Camera calibration as a service: upload image sets, run calibration jobs on a queue, "
                    "download results. Errors answer 4xx with a message saying what to do.",
        lifespan=lifespan,
        docs_url=None, redoc_url=None,  # /docs is served locally by install_docs (no CDN)
    )
    app.state.settings = settings
    app.state.quota = ClientQuota(settings.max_jobs_per_client)
    errors.install(app)
    app.add_middleware(BodyLimit, max_bytes=settings.max_upload_bytes + 1024 * 1024)  # + multipart overhead
    install_cors(app, settings.cors_origins)
    for module in (sets, images, rectified, jobs, figures, viewer, health):  # rectified before jobs: its maps.npz beats /{file}
        app.include_router(module.router, dependencies=[TokenDep])  # FREECAL_TOKEN, when set
    install_docs(app)
    from ..viewer import proxy

    proxy.install(app)  # /viewer: the 3D view behind the same token
    frontend.mount(app)  # last: the page at / never shadows /api or /docs
    return app


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
