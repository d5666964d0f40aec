"""/api/jobs/{id}/figures/...: figures computed on request from a done job's files (for the page)."""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query
from starlette.concurrency import run_in_threadpool

from calib_core.evaluation.diff import DEFAULT_GRID

from ..deps import ContextDep
from ..errors import ApiError
from ..figures import knot_cells, projection_diff, uncertainty
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


MAX_DIFF_GRID = 200   # samples across the image: 200 x 150 cells is a 1 MB answer


@router.get("/{job_id}/figures/diff/{other_id}", responses={404: {"model": Message}, 409: {"model": Message},
                                                           422: {"model": Message}})
async def read_projection_diff(ctx: ContextDep, job_id: str, other_id: str,
                               grid: Annotated[int, Query(ge=2, le=MAX_DIFF_GRID)] = DEFAULT_GRID,
                               fit_region: Literal["covered", "centre", "none"] = "covered") -> dict[str, Any]:
    """The projection difference from this job's calibration to another's of the same camera: each pixel's
    direction under this one, turned by the rotation between the two camera frames, projected by the other
    (``freecal diff``; mrcal-show-projection-diff's question), as a map and its summary."""
    dirs = []
    for ident in (job_id, other_id):
        job = service.get(ctx, ident)
        if job["state"] != "done":
            raise ApiError(409, f"job {ident} is {job['state']}: it can be compared once its calibration is done")
        if "calibration.json" not in job["artefacts"]:
            raise ApiError(409, f"job {ident} has no calibration to compare (no method could fit its corners)")
        dirs.append((str(ctx.storage.job_dir(ident)), job["finished_at"]))
    return await run_in_threadpool(_diff, *dirs[0], *dirs[1], grid, fit_region)


@functools.lru_cache(maxsize=16)
def _diff(job_dir: str, finished: float, other_dir: str, other_finished: float, grid: int,
          fit_region: str) -> dict[str, Any]:
    return projection_diff(Path(job_dir), Path(other_dir), grid, fit_region)
