"""/api/sets: upload images (or a zip, or corners JSON) with a board; read; delete."""
from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, File, Form, Request, Response, UploadFile, status
from fastapi.responses import FileResponse
from starlette.concurrency import run_in_threadpool

from ...base.repository import jobs as job_rows
from ...base.repository import sets as set_rows
from ..bounded_json import BoundedJSONRoute
from ..deps import ContextDep, QueueDep
from ..errors import ApiError
from ..presenters import set_public
from ..schemas import DetectionCreate, Message, SetPublic, SetsPublic
from ..security import QuotaDep, client_of
from ..services import sets as service
from ..uploads import Upload

# BoundedJSONRoute: a JSON body (detect again) is checked as /api/jobs's are; uploads are multipart, untouched
router = APIRouter(prefix="/api/sets", tags=["sets"], route_class=BoundedJSONRoute)
ERRORS: dict[int | str, dict[str, Any]] = {404: {"model": Message}, 409: {"model": Message}, 503: {"model": Message}, 413: {"model": Message},
          415: {"model": Message}, 422: {"model": Message}, 429: {"model": Message}, 507: {"model": Message}}


@router.post("", status_code=status.HTTP_201_CREATED, response_model=SetPublic, responses=ERRORS)
async def create_set(
    ctx: ContextDep, queue: QueueDep, quota: QuotaDep, request: Request,
    files: Annotated[list[UploadFile], File(min_length=1,
                                            description="images, one .zip of images, or one observations .json")],
    board: Annotated[str | None, Form(description="board spec, e.g. chessboard:9x6:25mm")] = None,
    name: Annotated[str | None, Form(description="a label for the set")] = None,
) -> SetPublic:
    """Store the files and queue corner detection (images); a corners JSON is ready at once."""
    uploads = [Upload(f.filename or "file", f.file) for f in files]
    async with quota.place_async(ctx, client_of(request)) as made:  # a set's detection is a job too
        await run_in_threadpool(service.check_room, ctx)  # 507 past FREECAL_MAX_SETS
        set_id = await run_in_threadpool(service.create, ctx, queue, uploads, board, name)
        detection = job_rows.latest_detection(ctx.db, set_id)
        made(detection["id"] if detection else None)
    return set_public(ctx, service.get(ctx, set_id), with_images=True)


@router.get("", response_model=SetsPublic)
def list_sets(ctx: ContextDep) -> SetsPublic:
    rows = set_rows.list_all(ctx.db)
    return SetsPublic(sets=[set_public(ctx, r, with_images=False) for r in rows], count=len(rows))


@router.get("/{set_id}", response_model=SetPublic, responses=ERRORS)
def read_set(ctx: ContextDep, set_id: str) -> SetPublic:
    """The set, with each image's detection status as it becomes known."""
    return set_public(ctx, service.get(ctx, set_id), with_images=True)


@router.get("/{set_id}/observations.json", response_class=FileResponse, responses=ERRORS)
def read_observations(ctx: ContextDep, set_id: str) -> FileResponse:
    """The set's corners as freecal.observations/1."""
    service.get(ctx, set_id)
    path = ctx.storage.observations_path(set_id)
    if not path.exists():
        raise ApiError(409, f"set {set_id} has no corners yet: wait until its state is ready")
    return FileResponse(path, media_type="application/json", filename=f"freecal-set-{set_id}-observations.json")


@router.post("/{set_id}/detect", status_code=status.HTTP_202_ACCEPTED, response_model=SetPublic, responses=ERRORS)
def detect_again(ctx: ContextDep, queue: QueueDep, quota: QuotaDep, request: Request, set_id: str,
                 body: DetectionCreate) -> SetPublic:
    """Detect the set's photos again with another board (e.g. the size the photos suggest): no new upload.
    Calibrations created meanwhile wait for the new corners."""
    with quota.place(ctx, client_of(request)) as made:
        job_id = service.detect_again(ctx, queue, set_id, body.board)
        made(job_id)
    return set_public(ctx, service.get(ctx, set_id), with_images=True)


@router.delete("/{set_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def delete_set(ctx: ContextDep, set_id: str) -> Response:
    """Delete the set, its files and its jobs (running jobs are asked to stop first: 409)."""
    service.delete(ctx, set_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
