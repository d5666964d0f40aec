"""/api/jobs: create a calibration or rig job, read its progress, cancel, delete, download results.

A rig (several cameras, one set each) is a job like a calibration: created by the same POST with
``"kind": "rig"``, then read, listed, cancelled, deleted and downloaded at the same paths."""
from __future__ import annotations

from typing import Any, Literal

from fastapi import APIRouter, Request, Response, status
from fastapi.responses import FileResponse

from ...base.repository import jobs as job_rows
from ..bounded_json import BoundedJSONRoute
from ..deps import ContextDep, QueueDep
from ..errors import ApiError
from ..presenters import job_public
from ..schemas import AnyJobCreate, JobCreate, JobPublic, JobsPublic, Message
from ..security import QuotaDep, client_of
from ..services import jobs as service
from ..services import rigs

# BoundedJSONRoute: the JSON body (inline observations: up to 64 MiB) is parsed off the event loop, depth bounded
router = APIRouter(prefix="/api/jobs", tags=["jobs"], route_class=BoundedJSONRoute)
ERRORS: dict[int | str, dict[str, Any]] = {404: {"model": Message}, 409: {"model": Message}, 503: {"model": Message}, 422: {"model": Message},
          429: {"model": Message}}

# result file → content type; the download is named freecal-job-ID-NAME
MEDIA = {".json": "application/json", ".csv": "text/csv; charset=utf-8", ".yaml": "application/x-yaml"}


@router.post("", status_code=status.HTTP_201_CREATED, response_model=JobPublic, responses=ERRORS)
def create_job(ctx: ContextDep, queue: QueueDep, quota: QuotaDep, request: Request, body: AnyJobCreate) -> JobPublic:
    """Queue a calibration of a ready set (or of corners given inline) with one method or 'compare'; or, with
    "kind": "rig", several cameras calibrated together from one ready set each (set_ids)."""
    with quota.place(ctx, client_of(request)) as made:  # 429 past FREECAL_MAX_JOBS_PER_CLIENT
        job_id = service.create(ctx, queue, body) if isinstance(body, JobCreate) else rigs.create(ctx, queue, body)
        made(job_id)
    return job_public(service.get(ctx, job_id))


@router.get("", response_model=JobsPublic)
def list_jobs(ctx: ContextDep, set_id: str | None = None,
              kind: Literal["calibrate", "detect", "rig", "all"] = "calibrate") -> JobsPublic:
    rows = job_rows.list_all(ctx.db, kind=None if kind == "all" else kind, set_id=set_id)
    return JobsPublic(jobs=[job_public(r) for r in rows], count=len(rows))


@router.get("/{job_id}", response_model=JobPublic, responses=ERRORS)
def read_job(ctx: ContextDep, job_id: str) -> JobPublic:
    """State, stage, progress (0-100 %), timings and, when it failed, why."""
    return job_public(service.get(ctx, job_id))


@router.post("/{job_id}/cancel", response_model=JobPublic, responses=ERRORS)
def cancel_job(ctx: ContextDep, job_id: str) -> JobPublic:
    """A queued job is cancelled at once; a running one stops at its next progress step."""
    return job_public(service.cancel(ctx, job_id))


@router.delete("/{job_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def delete_job(ctx: ContextDep, job_id: str) -> Response:
    service.delete(ctx, job_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/{job_id}/{name}", response_class=FileResponse, responses=ERRORS)
def download(ctx: ContextDep, job_id: str, name: str) -> FileResponse:
    """A result file: calibration.json, comparison.json/.csv, view_residuals.json/.csv,
    corner_residuals.json/.csv, heatmap.json, knots.json, distortion_field.json, opencv.yaml; of a rig:
    rig.json (freecal.rig/1), camchain.yaml (Kalibr), stereo.yaml (OpenCV, a pair)."""
    job = service.get(ctx, job_id)
    if job["state"] != "done":
        raise ApiError(409, f"job {job_id} is {job['state']}: results exist once it is done"
                       + (f" (it failed: {job['error']})" if job["state"] == "failed" else ""))
    why = (job["summary"].get("exports_unavailable") or {}).get(name)
    if name not in job["artefacts"] and why:
        raise ApiError(404, f"job {job_id} has no {name!r}: {why}")
    if name not in job["artefacts"]:
        raise ApiError(404, f"job {job_id} has no {name!r}; it has: {', '.join(job['artefacts'])}")
    path = ctx.storage.job_dir(job_id) / name
    if not path.is_file():  # a detection's corners are its set's file; FileResponse would fail with a 500
        where = f": its set's corners are at /api/sets/{job['set_id']}/{name}" if job["kind"] == "detect" else ""
        raise ApiError(404, f"job {job_id} has no {name!r} to download{where}")
    suffix = name[name.rfind("."):]
    return FileResponse(path, media_type=MEDIA.get(suffix, "application/octet-stream"),
                        filename=f"freecal-job-{job_id}-{name}")
