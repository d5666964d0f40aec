"""Image sets: upload, read, delete."""
from __future__ import annotations

import json
from typing import Any

from ...base import storage
from ...base.context import Context
from ...base.repository import jobs, sets
from ...queue.tasks import Queue
from .. import bounded_json, uploads
from ..errors import ApiError, not_found
from ..schemas import SetState
from .enqueue import enqueue_or_undo
from .ids import new_id

SET_STATE: dict[str, SetState] = {"queued": "queued", "running": "detecting", "done": "ready", "failed": "failed",
             "cancelled": "cancelled"}


BOARD_NEEDED = ("images need a board spec in the form field 'board', e.g. chessboard:9x6:25mm "
                "(inner corners and square size)")


def create(ctx: Context, queue: Queue, files: list[uploads.Upload], board_spec: str | None,
           name: str | None) -> str:
    board = _board(board_spec)
    only_json = bool(files) and all(f.name.lower().endswith(".json") for f in files)
    if board is None and files and not only_json:
        raise ApiError(422, BOARD_NEEDED)
    set_id = new_id()
    try:
        got = uploads.receive(files, ctx.storage.images_dir(set_id), ctx.settings)
        title = name or (files[0].name if len(files) == 1 else f"{len(files)} files")
        if got.kind == "observations":
            obs = got.observations if got.corners_file is None else _corners_vnl(got, board, ctx)
            assert obs is not None  # uploads.receive: a corners upload carries its observations
            _keep_skipped(ctx, set_id, got.skipped)
            if board is not None:
                obs.board = board.to_json()
            storage.write_json(ctx.storage.observations_path(set_id), obs.to_json())
            _insert(ctx, set_id, title, "observations", obs.board, [], list(obs.image_size), len(obs.views))
            return set_id
        if board is None:
            raise ApiError(422, BOARD_NEEDED)
        _keep_skipped(ctx, set_id, got.skipped)
        _insert(ctx, set_id, title, "images", board.to_json(), got.names)
    except BaseException:
        ctx.storage.remove_set(set_id)
        raise
    start_detection(ctx, queue, set_id, board, undo_set=True)
    return set_id


def check_room(ctx: Context) -> None:
    """507 once the server holds FREECAL_MAX_SETS sets: uploads stop before the disk fills, with
    what to do. Asked before an upload is read; ``_insert`` asks again as the set is written."""
    n = sets.count(ctx.db)
    if n >= ctx.settings.max_sets:
        raise _full(n, ctx.settings.max_sets)


def _insert(ctx: Context, set_id: str, name: str, source: str, board: dict | None, image_names: list[str],
            image_size: list[int] | None = None, n_views: int = 0) -> None:
    try:
        sets.create(ctx.db, set_id, name, source, board, image_names, image_size, n_views, limit=ctx.settings.max_sets)
    except sets.Full as full:  # uploads that passed check_room together: the last ones stop here
        raise _full(full.held, ctx.settings.max_sets) from None


def _full(held: int, limit: int) -> ApiError:
    return ApiError(507, f"the server holds {held} sets, its limit (FREECAL_MAX_SETS={limit}): delete sets you no "
                         "longer need (DELETE /api/sets/{id}, or from the page) and upload again")


def start_detection(ctx: Context, queue: Queue, set_id: str, board: Any, undo_set: bool = False) -> str:
    """Queue a detection of the set's images with ``board``; the set's state follows its latest detection."""
    job_id = new_id()
    jobs.create(ctx.db, job_id, "detect", set_id, None, {"board": board.to_spec()})

    def undo() -> None:
        if undo_set:
            sets.delete(ctx.db, set_id)
            ctx.storage.remove_set(set_id)
        else:
            jobs.delete(ctx.db, job_id)

    enqueue_or_undo(ctx, queue, job_id, undo)
    return job_id


def curation(ctx: Context, row: dict[str, Any]) -> dict[str, Any]:
    """What a read of one set adds for the page: the files skipped at upload, the board size the photos suggest."""
    out: dict[str, Any] = {}
    path = ctx.storage.skipped_path(row["id"])
    if path.exists():
        out["skipped"] = json.loads(path.read_text())
    suggestion = ctx.storage.board_suggestion_path(row["id"])
    if suggestion.exists():
        out["board_suggestion"] = json.loads(suggestion.read_text())
    return out


def _keep_skipped(ctx: Context, set_id: str, items: list[dict[str, str]]) -> None:
    if items:
        storage.write_json(ctx.storage.skipped_path(set_id), items)


def _corners_vnl(got: uploads.Received, board: Any, ctx: Context):
    """mrcal's corners.vnl, on the board of the form (the file gives no geometry); FormatError → 422."""
    from calib_core.imports.mrcal_corners import read_corners_vnl

    up = got.corners_file
    assert up is not None and got.image_size is not None  # uploads.receive: a corners.vnl comes with its size
    raw = up.stream.read(ctx.settings.max_observations_bytes + 1)
    if len(raw) > ctx.settings.max_observations_bytes:
        raise ApiError(413, f"{up.name!r} is over the limit of {ctx.settings.max_observations_bytes} bytes")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ApiError(422, f"{up.name!r} is not text: mrcal's corners.vnl is a text table") from None
    obs, none_found = read_corners_vnl(text, board, got.image_size, up.name)
    if len(obs.views) > ctx.settings.max_files:
        raise ApiError(413, f"{up.name!r} holds {len(obs.views)} views, over the limit of "
                            f"{ctx.settings.max_files} per set")
    got.skipped += [{"name": n, "reason": why} for n, why in none_found]
    return obs


def detect_again(ctx: Context, queue: Queue, set_id: str, board_spec: str) -> str:
    """A new detection of an image set with another board; the id of its job."""
    row = get(ctx, set_id)
    if row["source"] != "images":
        raise ApiError(409, f"set {row['name']!r} was uploaded as corners: there are no photos to detect again")
    board = _board(board_spec)
    if board is None:
        raise ApiError(422, "board: give the board to detect, e.g. chessboard:15x9:26mm")
    latest = jobs.latest_detection(ctx.db, set_id)
    if latest is not None and latest["state"] in jobs.ACTIVE:
        raise ApiError(409, f"set {row['name']!r} is still being detected: wait until it ends (or cancel it), "
                            "then detect again")
    sets.set_board(ctx.db, set_id, board.to_json())
    ctx.storage.observations_path(set_id).unlink(missing_ok=True)   # the old board's corners
    ctx.storage.board_suggestion_path(set_id).unlink(missing_ok=True)
    return start_detection(ctx, queue, set_id, board)


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


def state(ctx: Context, row: dict[str, Any]) -> tuple[SetState, float, str | None, str | None]:
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
