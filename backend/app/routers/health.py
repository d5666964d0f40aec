"""/api/health and /api/methods: is the service up, are workers alive, what can it run."""
from __future__ import annotations

from fastapi import APIRouter

from calib_core.methods import METHODS

from ..deps import ContextDep
from ..repository import jobs, workers
from ..schemas import Health, MethodsPublic
from ..services.jobs import compare_available

router = APIRouter(prefix="/api", tags=["service"])
VERSION = "0.1.0"


@router.get("/health", response_model=Health)
def health(ctx: ContextDep) -> Health:
    live = workers.live(ctx.db, ctx.settings.lease_seconds)
    return Health(status="ok", version=VERSION, queue=ctx.settings.queue, workers=len(live),
                  jobs=jobs.count_by_state(ctx.db))


@router.get("/methods", response_model=MethodsPublic)
def methods() -> MethodsPublic:
    return MethodsPublic(methods=sorted(METHODS), compare=compare_available())
