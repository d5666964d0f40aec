"""/api/viewer: where the page finds the 3D view (the /viewer proxy), which job a newly opened view shows
when its URL names none, and the view selected on a page and in its 3D view (``/api/viewer/selection``)."""
from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Query, Request
from pydantic import BaseModel, Field

from ...viewer.data import VIEWABLE
from ..bounded_json import BoundedJSONRoute
from ..deps import ContextDep
from ..errors import ApiError
from ..schemas import Message
from ..services import jobs as job_service
from ..viewer_proxy import running_viewer

router = APIRouter(prefix="/api/viewer", tags=["viewer"], route_class=BoundedJSONRoute)  # depth-bounded JSON


class ViewerPublic(BaseModel):
    enabled: bool
    url: str | None = Field(default=None, description="the 3D view's page, on this server (/viewer/: needs the token "
                                              "like /api; its websocket is /viewer?token=...)")
    focus: str | None = Field(default=None, description="the job a newly opened view shows first when its URL names none "
                                                "(the page's views name theirs: /viewer/?job=)")
    clients: list[dict[str, Any]] = Field(default_factory=list,
                                          description="open views: job shown and scene nodes (for tests)")


class ViewerOpen(BaseModel):
    job_id: str


PAIR = r"^[A-Za-z0-9_-]{8,64}$"   # the page's pairing key, as the proxy passes it on (viewer_proxy.ASKS)


class SelectionIn(BaseModel):
    pair: str = Field(..., pattern=PAIR, description="the page's pairing key, also in its 3D view's URL (?pair=)")
    view: str | None = Field(None, max_length=512, description="the view (photo name) selected; null: none")


class SelectionOut(BaseModel):
    view: str | None = Field(None, description="the view selected last, on the page or by a click in 3D")
    seq: int = Field(0, description="grows with every change: a page ignores what it has seen")
    source: str = Field("", description="who chose it: page or 3d")


def _running(request: Request) -> Any:
    return running_viewer(request.app)


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
    """Make the next opened 3D view whose URL names no job start on this done job, a calibration or a rig
    (its controls switch later)."""
    viewer = _running(request)
    job = job_service.get(ctx, body.job_id)
    if job["state"] != "done" or job["kind"] not in VIEWABLE:
        raise ApiError(409, f"job {body.job_id} is a {job['kind']} job in state {job['state']}: "
                            "the 3D view shows done calibration and rig jobs")
    viewer.focus = body.job_id
    return _public(request)


@router.get("/selection", response_model=SelectionOut, responses={503: {"model": Message}})
def read_selection(request: Request, pair: str = Query(..., pattern=PAIR)) -> SelectionOut:
    """The view selected last by the page ``pair`` or in its 3D view (a board clicked there)."""
    chosen = _running(request).selections.get(pair)
    return SelectionOut(view=chosen.view, seq=chosen.seq, source=chosen.source)


@router.post("/selection", response_model=SelectionOut, responses={503: {"model": Message}})
def select_view(request: Request, body: SelectionIn) -> SelectionOut:
    """The page selected a view (a row of its per-view table): its 3D view highlights that board."""
    chosen = _running(request).select(body.pair, body.view)
    return SelectionOut(view=chosen.view, seq=chosen.seq, source=chosen.source)
