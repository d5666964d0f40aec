"""/api/health and /api/methods: is the service up, are workers alive, what can it run."""
from __future__ import annotations

from fastapi import APIRouter

from calib_core.methods import METHODS

from ..deps import ContextDep, QueueDep
from ..schemas import Health, MethodsPublic
from ..services import health as assessment
from ..services.jobs import compare_available

router = APIRouter(prefix="/api", tags=["service"])
VERSION = assessment.VERSION


@router.get("/health", response_model=Health)
def health(ctx: ContextDep, queue: QueueDep) -> Health:
    """"ok", or "degraded" with the problems in plain words (workers missing, queue stuck, data directory full
    or read-only); answers 200 either way, so a service that answers is never restarted for a missing worker."""
    return assessment.assess(ctx, queue)


@router.get("/methods", response_model=MethodsPublic)
def methods() -> MethodsPublic:
    return MethodsPublic(methods=sorted(METHODS), compare=compare_available())
