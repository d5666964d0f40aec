"""/api/jobs/{id}/rectified/{image}, /maps.npz and /figures/quality: a done
job's calibration applied to its photos (issue: use the calibration)."""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from fastapi import APIRouter
from fastapi.responses import FileResponse, Response
from starlette.concurrency import run_in_threadpool

from ...base import storage
from .. import rectified
from ..deps import ContextDep
from ..errors import ApiError
from ..schemas import Message
from ..security import PRIVATE_IMAGE
from ..services import jobs as service
from ..services import sets as sets_service

router = APIRouter(prefix="/api/jobs", tags=["jobs"])
ERRORS: dict[int | str, dict[str, Any]] = {404: {"model": Message}, 409: {"model": Message}, 413: {"model": Message}}


def _done(ctx, job_id: str) -> dict:
    job = service.get(ctx, job_id)
    if job["state"] != "done" or "calibration.json" not in job["artefacts"]:
        raise ApiError(409, f"job {job_id} is {job['state']}: its calibration exists once it is done")
    return job


@router.get("/{job_id}/rectified/{name}", response_class=Response,
            responses={**ERRORS, 200: {"content": {"image/jpeg": {}}}})
async def read_rectified(ctx: ContextDep, job_id: str, name: str) -> Response:
    """One photo of the job's set rectified by its calibration (JPEG, 640 px, valid pixels only)."""
    job = _done(ctx, job_id)
    if not job["set_id"]:
        raise ApiError(404, f"job {job_id} was run on corners alone: it has no photos to rectify")
    images = {im["name"] for im in sets_service.get(ctx, job["set_id"]).get("images") or []}
    if name not in images:
        raise ApiError(404, f"the set of job {job_id} has no image {name!r}")
    jpeg = await run_in_threadpool(rectified.preview, ctx.storage.job_dir(job_id),
                                   ctx.storage.images_dir(job["set_id"]) / storage.safe_name(name),
                                   ctx.settings.max_image_pixels)
    if jpeg is None:
        raise ApiError(404, f"image {name!r} cannot be read")
    return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": PRIVATE_IMAGE})


@router.get("/{job_id}/maps.npz", response_class=FileResponse, responses=ERRORS)
async def read_maps(ctx: ContextDep, job_id: str) -> FileResponse:
    """Undistortion maps for cv2.remap (float32 map_x, map_y, camera_matrix, size)."""
    _done(ctx, job_id)
    path = await run_in_threadpool(rectified.maps_npz, ctx.storage.job_dir(job_id))
    return FileResponse(path, media_type="application/octet-stream", filename=f"freecal-job-{job_id}-maps.npz")


@router.get("/{job_id}/figures/quality", responses=ERRORS)
async def read_quality(ctx: ContextDep, job_id: str) -> dict[str, Any]:
    """Geometric quality of the rectified boards (the paper's Table 7), calibrated and raw."""
    job = _done(ctx, job_id)
    inline = ctx.storage.job_dir(job_id) / "input.json"
    obs = inline if inline.exists() else ctx.storage.observations_path(job["set_id"] or "")
    if not obs.exists():
        raise ApiError(404, f"job {job_id}: its corners are gone (set deleted)")
    return await run_in_threadpool(_quality, str(ctx.storage.job_dir(job_id)), str(obs), job["finished_at"])


@functools.lru_cache(maxsize=16)
def _quality(job_dir: str, observations: str, finished_at: float) -> dict[str, Any]:
    return rectified.quality(Path(job_dir), Path(observations))
