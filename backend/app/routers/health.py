"""/api/health and /api/methods: is the service up, are workers alive, what can it run."""
from __future__ import annotations

from fastapi import APIRouter

from calib_core.methods import METHODS

from ..deps import ContextDep, QueueDep
from ..repository import jobs, workers
from ..schemas import Health, MethodsPublic
from ..services.jobs import compare_available

router = APIRouter(prefix="/api", tags=["service"])
VERSION = "0.1.0"


@router.get("/health", response_model=Health)
def health(ctx: ContextDep, queue: QueueDep) -> Health:
    live = workers.live(ctx.db, ctx.settings.lease_seconds)
    problem = queue.problem()
    return Health(status="ok", version=VERSION, queue=ctx.settings.queue, workers=len(live),
                  jobs=jobs.count_by_state(ctx.db), queue_available=problem is None,
                  queue_error=None if problem is None else
                  f"the job queue ({ctx.settings.redis_url}) is unreachable ({problem}): new jobs answer 503 "
                  "until it is back; reads work")


@router.get("/methods", response_model=MethodsPublic)
def methods() -> MethodsPublic:
    return MethodsPublic(methods=sorted(METHODS), compare=compare_available())
