"""/api/viewer: where the page finds the 3D view (the /viewer proxy), and which job a newly opened view shows."""
from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from pydantic import BaseModel, Field

from ..bounded_json import BoundedJSONRoute
from ..deps import ContextDep
from ..errors import ApiError
from ..schemas import Message
from ..services import jobs as job_service

router = APIRouter(prefix="/api/viewer", tags=["viewer"], route_class=BoundedJSONRoute)  # depth-bounded JSON


class ViewerPublic(BaseModel):
    enabled: bool
    url: str | None = Field(None, description="the 3D view's page, on this server (/viewer/: needs the token "
                                              "like /api; its websocket is /viewer?token=...)")
    focus: str | None = Field(None, description="the job a newly opened view shows first")
    clients: list[dict[str, Any]] = Field(default_factory=list,
                                          description="open views: job shown and scene nodes (for tests)")


class ViewerOpen(BaseModel):
    job_id: str


def _public(request: Request) -> ViewerPublic:
    viewer = getattr(request.app.state, "viewer", None)
    if viewer is None:
        return ViewerPublic(enabled=False)
    # the proxy on this port, never viser's own: that one is loopback only and checks no token
    return ViewerPublic(enabled=True, url="/viewer/", focus=viewer.focus, clients=viewer.describe())


@router.get("", response_model=ViewerPublic)
def read_viewer(request: Request) -> ViewerPublic:
    """Whether the 3D view runs, and its URL."""
    return _public(request)


@router.post("", response_model=ViewerPublic, responses={404: {"model": Message}, 409: {"model": Message},
                                                         503: {"model": Message}})
def open_viewer(request: Request, ctx: ContextDep, body: ViewerOpen) -> ViewerPublic:
    """Make the next opened 3D view start on this done job (its controls switch later)."""
    viewer = getattr(request.app.state, "viewer", None)
    if viewer is None:
        raise ApiError(503, "the 3D view is off on this server (FREECAL_VIEWER=0); start it with FREECAL_VIEWER=1")
    job = job_service.get(ctx, body.job_id)
    if job["state"] != "done" or job["kind"] != "calibrate":
        raise ApiError(409, f"job {body.job_id} is a {job['kind']} job in state {job['state']}: "
                            "the 3D view shows done calibration jobs")
    viewer.focus = body.job_id
    return _public(request)
