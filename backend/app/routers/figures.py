"""/api/jobs/{id}/figures/...: figures computed on request from a done job's files (for the page)."""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool

from ..deps import ContextDep
from ..errors import ApiError
from ..figures import knot_cells
from ..schemas import Message
from ..services import jobs as service

router = APIRouter(prefix="/api/jobs", tags=["jobs"])


@router.get("/{job_id}/figures/knot-cells", responses={404: {"model": Message}, 409: {"model": Message}})
async def read_knot_cells(ctx: ContextDep, job_id: str) -> dict[str, Any]:
    """The knot grid with the number of corners per knot cell (B-spline methods; the paper's Figure 11)."""
    job = service.get(ctx, job_id)
    if job["state"] != "done":
        raise ApiError(409, f"job {job_id} is {job['state']}: figures exist once it is done")
    result = await run_in_threadpool(_cached, str(ctx.storage.job_dir(job_id)), job["finished_at"])
    if result is None:
        raise ApiError(404, f"job {job_id} has no knot grid: only B-spline methods have one")
    return result


@functools.lru_cache(maxsize=32)
def _cached(job_dir: str, finished_at: float) -> dict[str, Any] | None:
    # results never change once a job is done; finished_at keys a re-run of the same id
    return knot_cells(Path(job_dir))
