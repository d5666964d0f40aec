"""/api/jobs/{id}/figures/...: figures computed on request from a done job's files (for the page)."""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool

from ..deps import ContextDep
from ..errors import ApiError
from ..figures import knot_cells, uncertainty
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


@router.get("/{job_id}/figures/uncertainty", responses={404: {"model": Message}, 409: {"model": Message}})
async def read_uncertainty(ctx: ContextDep, job_id: str) -> dict[str, Any]:
    """Projection uncertainty over the image, px (worst direction and per-axis rms): where the lens is known."""
    job = service.get(ctx, job_id)
    if job["state"] != "done" or "calibration.json" not in job["artefacts"]:
        raise ApiError(409, f"job {job_id} is {job['state']}: the uncertainty map exists once it is done")
    inline = ctx.storage.job_dir(job_id) / "input.json"
    obs = inline if inline.exists() else ctx.storage.observations_path(job["set_id"] or "")
    result = await run_in_threadpool(_uncertainty, str(ctx.storage.job_dir(job_id)), str(obs), job["finished_at"])
    if result is None:
        raise ApiError(404, f"job {job_id}: its corners are gone (set deleted), so its uncertainty cannot be computed")
    return result


@functools.lru_cache(maxsize=8)
def _uncertainty(job_dir: str, observations: str, finished_at: float) -> dict[str, Any] | None:
    return uncertainty(Path(job_dir), Path(observations))
