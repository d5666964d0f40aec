"""Rig jobs: several ready sets, one per camera, calibrated together (docs/rigs.md).

Everything that would fail in the worker for a reason the request already shows is
refused here, in words, before a job exists: too few or too many cameras, a set that
is unknown or not ready, names that are repeated or not one per set, a reference that
is no camera, cameras that saw different boards, and cameras whose views share no frame (a frame is a view's ``"frame"``,
else the last run of digits in its name: formats.md §4). The job then reads a copy of
each set's corners taken now, so a set deleted or detected again later changes nothing.
"""
from __future__ import annotations

from pathlib import PurePath
from typing import Any

from calib_core import Observations
from calib_core.errors import DataError
from calib_core.json_fields import CAMERA_NAME_RULE, is_camera_name
from calib_core.rig.calibrate import check_boards
from calib_core.rig.frames import frames_of, padding_hint, unlinked

from ...base import storage
from ...base.context import Context
from ...base.repository import jobs, sets
from ...queue.tasks import Queue
from ..errors import ApiError
from ..schemas import RigJobCreate
from . import jobs as job_service
from . import sets as set_service
from .enqueue import enqueue_job
from .ids import new_id

FRAMES_HOW = ("views of different cameras are matched by frame: a view's \"frame\" in the observations, else the "
              "last run of digits in its name (left07.jpg and right07.jpg are frame 07)")


def create(ctx: Context, queue: Queue, body: RigJobCreate) -> str:
    n = len(body.set_ids)
    if n < 2:
        raise ApiError(422, f"set_ids: a rig needs two or more cameras, got {n} set(s): give one ready set per camera")
    limit = ctx.settings.max_rig_cameras
    if n > limit:
        raise ApiError(422, f"set_ids: {n} cameras is over this server's limit of {limit} (FREECAL_MAX_RIG_CAMERAS): "
                            "calibrate fewer cameras together, or ask the administrator for a higher limit")
    twice = sorted({s for s in body.set_ids if body.set_ids.count(s) > 1})
    if twice:
        raise ApiError(422, f"set_ids: set {twice[0]!r} is given more than once; each camera needs a set of its own")
    if body.method == job_service.COMPARE:
        raise ApiError(422, "method 'compare' is not for a rig: a rig calibrates each camera with one method; "
                            "choose one (e.g. 'auto'), or compare the methods on each set alone first")
    job_service.validate(body.method, body.settings)
    rows = [_ready_set(ctx, set_id) for set_id in body.set_ids]
    names = _names(body, rows)
    reference = names[0] if body.reference is None else body.reference
    if reference not in names:
        raise ApiError(422, f"reference: {reference!r} is not one of the cameras {names}; give one of them "
                            "(or leave it out for the first)")
    cameras = {name: Observations.load(ctx.storage.observations_path(row["id"])) for name, row in zip(names, rows, strict=True)}
    _check_frames(cameras, rows, reference)
    try:
        check_boards(cameras, reference)
    except DataError as exc:
        raise ApiError(422, f"set_ids: {exc}") from None

    job_id = new_id()
    try:
        for k, row in enumerate(rows):
            storage.write_bytes(ctx.storage.rig_camera_path(job_id, k), ctx.storage.observations_path(row["id"]).read_bytes())
        spec = {"set_ids": list(body.set_ids), "names": names, "reference": reference, "hold_models": body.hold_models}
        jobs.create(ctx.db, job_id, "rig", None, body.method, {**body.settings, jobs.RIG_KEY: spec})
    except BaseException:
        ctx.storage.remove_job(job_id)
        raise
    enqueue_job(ctx, queue, job_id)
    return job_id


def _ready_set(ctx: Context, set_id: str) -> dict[str, Any]:
    row = sets.get(ctx.db, set_id)
    if row is None:
        raise ApiError(422, f"set_ids: there is no set with id {set_id!r}: list the sets at /api/sets, or upload "
                            "the camera's photos or corners first")
    state, _, error, _ = set_service.state(ctx, row)
    if state != "ready" or not ctx.storage.observations_path(set_id).exists():
        why = f" ({error})" if error else ""
        then = ("wait until its detection is done, then create the rig" if state in ("queued", "detecting")
                else "run its detection again with the right board, or upload its corners")
        raise ApiError(422, f"set_ids: set {row['name']!r} ({set_id}) is {state}{why}, not ready: a rig starts from "
                            f"sets whose corners are known; {then}")
    return row


def _names(body: RigJobCreate, rows: list[dict[str, Any]]) -> list[str]:
    if body.names is None:  # the sets' names without their extension, when they make distinct camera names
        stems = [PurePath(row["name"]).stem for row in rows]
        if len(set(stems)) == len(stems) and all(is_camera_name(s) for s in stems):
            return stems
        return [f"cam{k}" for k in range(len(rows))]
    names = list(body.names)
    if len(names) != len(rows):
        raise ApiError(422, f"names: {len(names)} name(s) for {len(rows)} sets; give one name per set, in the "
                            "order of set_ids (or leave names out)")
    bad = next((n for n in names if not is_camera_name(n)), None)
    if bad is not None:
        raise ApiError(422, f"names: {bad[:70]!r} is not a camera name: {CAMERA_NAME_RULE}")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ApiError(422, f"names: {twice[0]!r} is given to more than one camera; give each camera its own name")
    return names


def _check_frames(cameras: dict[str, Observations], rows: list[dict[str, Any]], reference: str) -> None:
    """Each camera sees each frame once, and every camera is linked to the reference by shared frames
    (directly, or through other cameras)."""
    frames: dict[str, set[str]] = {}
    for (name, obs), row in zip(cameras.items(), rows, strict=True):
        try:
            frames[name] = set(frames_of(name, obs.views))
        except DataError as exc:
            raise ApiError(422, f"set {row['name']!r} ({row['id']}): {exc}") from None
    lonely = unlinked(frames, reference)
    if lonely:
        which = ", ".join(f"{name!r} (set {row['name']!r})" for (name, row) in zip(cameras, rows, strict=True)
                          if name in lonely)
        raise ApiError(422, f"camera(s) {which} share no frame with the reference camera {reference!r} or any camera "
                            f"linked to it; {FRAMES_HOW}. Give the views of one moment the same number in every "
                            "camera's set, or set each view's \"frame\"" + padding_hint(frames, reference))
