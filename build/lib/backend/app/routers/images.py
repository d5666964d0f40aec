"""/api/sets/{id}/images/{name}/thumbnail: a small JPEG of one uploaded image (for the page)."""
from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query
from fastapi.responses import Response
from starlette.concurrency import run_in_threadpool

from ..deps import ContextDep
from ..errors import ApiError
from ..schemas import Message
from ..security import PRIVATE_IMAGE
from ..services import sets as service
from ..thumbnails import SIZES, thumbnail

router = APIRouter(prefix="/api/sets", tags=["sets"])


@router.get("/{set_id}/images/{name}/thumbnail", response_class=Response,
            responses={200: {"content": {"image/jpeg": {}}}, 404: {"model": Message}, 413: {"model": Message},
                       422: {"model": Message}})
async def read_thumbnail(ctx: ContextDep, set_id: str, name: str,
                         size: Annotated[int, Query(json_schema_extra={"enum": list(SIZES)})] = SIZES[0]) -> Response:
    """The image scaled down to ``size`` pixels on its longest side (160 or 640), JPEG, cached."""
    if size not in SIZES:
        raise ApiError(422, f"size must be one of {', '.join(map(str, SIZES))} (pixels on the longest side)")
    row = service.get(ctx, set_id)
    if name not in {im["name"] for im in row.get("images") or []}:
        raise ApiError(404, f"set {set_id} has no image {name!r}")
    jpeg = await run_in_threadpool(thumbnail, ctx.storage.images_dir(set_id), ctx.storage.set_dir(set_id) / "thumbs",
                                   name, size, ctx.settings.max_image_pixels)
    if jpeg is None:
        raise ApiError(404, f"image {name!r} of set {set_id} cannot be read")
    return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": PRIVATE_IMAGE})
