"""Image sets: upload, read, delete."""
from __future__ import annotations

from typing import Any

from ...base import storage
from ...base.context import Context
from ...base.repository import jobs, sets
from ...queue.tasks import Queue
from .. import bounded_json, uploads
from ..errors import ApiError, not_found
from .enqueue import enqueue_or_undo
from .ids import new_id

SET_STATE = {"queued": "queued", "running": "detecting", "done": "ready", "failed": "failed",
             "cancelled": "cancelled"}


def create(ctx: Context, queue: Queue, files: list[uploads.Upload], board_spec: str | None,
           name: str | None) -> str:
    board = _board(board_spec)
    if board is None and not (len(files) == 1 and files[0].name.lower().endswith(".json")) and files:
        raise ApiError(422, "images need a board spec in the form field 'board', e.g. "
                            "chessboard:9x6:25mm (inner corners and square size)")
    set_id = new_id()
    try:
        got = uploads.receive(files, ctx.storage.images_dir(set_id), ctx.settings)
        title = name or (files[0].name if len(files) == 1 else f"{len(files)} images")
        if got.kind == "observations":
            obs = got.observations
            if board is not None:
                obs.board = board.to_json()
            storage.write_json(ctx.storage.observations_path(set_id), obs.to_json())
            sets.create(ctx.db, set_id, title, "observations", obs.board, [], list(obs.image_size), len(obs.views))
            return set_id
        if board is None:
            raise ApiError(422, "images need a board spec in the form field 'board', e.g. "
                                "chessboard:9x6:25mm (inner corners and square size)")
        sets.create(ctx.db, set_id, title, "images", board.to_json(), got.names)
    except BaseException:
        ctx.storage.remove_set(set_id)
        raise
    job_id = new_id()
    jobs.create(ctx.db, job_id, "detect", set_id, None, {"board": board.to_spec()})

    def undo() -> None:
        sets.delete(ctx.db, set_id)
        ctx.storage.remove_set(set_id)

    enqueue_or_undo(ctx, queue, job_id, undo)
    return set_id


def _board(spec: str | None) -> Any:
    if spec is None or not spec.strip():
        return None
    try:
        from calib_core.board import BoardSpec
    except ImportError:  # detection not in this build: corners JSON still works
        raise ApiError(422, "image sets are not supported by this version (no corner detection): "
                            "upload a freecal.observations/1 JSON instead") from None
    text = spec.strip()
    if text.startswith("{"):  # a board object as in formats.md §1
        try:
            doc = bounded_json.parse(text, "board")
        except ApiError as exc:
            raise ApiError(exc.status, f"{exc.detail}; or give a spec string like chessboard:9x6:25mm") from None
        return BoardSpec.from_json(doc)  # FormatError → 422
    return BoardSpec.parse(text)  # SettingsError → 422 with its message


def state(ctx: Context, row: dict[str, Any]) -> tuple[str, float, str | None, str | None]:
    """(state, progress, error, detection job id) of a set, from its latest detection job."""
    if row["source"] == "observations":
        return "ready", 100.0, None, None
    job = jobs.latest_detection(ctx.db, row["id"])
    if job is None:
        return "failed", 0.0, "no detection job (the server stopped while creating it): upload again", None
    return SET_STATE[job["state"]], job["progress"], job["error"], job["id"]


def get(ctx: Context, set_id: str) -> dict[str, Any]:
    row = sets.get(ctx.db, set_id)
    if row is None:
        raise not_found("set", set_id)
    return row


def delete(ctx: Context, set_id: str) -> None:
    get(ctx, set_id)
    running = [j["id"] for j in jobs.list_all(ctx.db, set_id=set_id, state="running")]
    if running:
        for job_id in running:
            jobs.request_cancel(ctx.db, job_id)
        raise ApiError(409, f"job(s) {', '.join(running)} of this set are running: cancellation was requested; "
                            "delete the set again once they have stopped")
    for job in jobs.list_all(ctx.db, set_id=set_id):
        ctx.storage.remove_job(job["id"])
    sets.delete(ctx.db, set_id)
    ctx.storage.remove_set(set_id)
