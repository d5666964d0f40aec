"""Database rows → the public schemas (derived fields: set state, timings, download links)."""
from __future__ import annotations

import time
from datetime import UTC, datetime
from typing import Any

from ..base.context import Context
from ..base.repository.jobs import split_rig, split_settings
from .schemas import ImagePublic, JobPublic, RigSpec, SetPublic, Timings
from .services import sets as set_service


def _dt(ts: float | None) -> datetime | None:
    return None if ts is None else datetime.fromtimestamp(ts, tz=UTC)


def set_public(ctx: Context, row: dict[str, Any], with_images: bool) -> SetPublic:
    state, progress, error, job_id = set_service.state(ctx, row)
    images = row.get("images")
    return SetPublic(
        id=row["id"], name=row["name"], source=row["source"], board=row["board"], state=state,
        progress=progress, error=error, image_size=row["image_size"],
        n_images=len(images) if images is not None else row.get("n_images", 0),
        n_views=row["n_views"], coverage=row["coverage"], warnings=row["warnings"],
        created_at=datetime.fromtimestamp(row["created_at"], tz=UTC), detection_job=job_id,
        images=[ImagePublic(**im) for im in images] if with_images and images is not None else None,
        **(set_service.curation(ctx, row) if with_images else {}),
    )


def job_public(row: dict[str, Any]) -> JobPublic:
    start, end = row["started_at"], row["finished_at"]
    running_end = end if end is not None else (time.time() if row["state"] == "running" else None)
    timings = Timings(
        queued_seconds=None if start is None else round(start - row["created_at"], 3),
        run_seconds=None if start is None or running_end is None else round(running_end - start, 3),
        stages=row["stages"],
    )
    if row["state"] != "done":
        downloads = {}
    elif row["kind"] == "detect":  # its result belongs to the set
        downloads = {"observations.json": f"/api/sets/{row['set_id']}/observations.json"}
    else:
        downloads = {name: f"/api/jobs/{row['id']}/{name}" for name in row["artefacts"]}
    settings, exclude = split_settings(row["settings"])
    settings, rig = split_rig(settings)
    return JobPublic(
        id=row["id"], kind=row["kind"], set_id=row["set_id"], method=row["method"], settings=settings, exclude=exclude,
        rig=None if rig is None else RigSpec(**rig),
        state=row["state"], stage=row["stage"], progress=row["progress"], error=row["error"],
        attempts=row["attempts"], cancel_requested=row["cancel_requested"], worker=row["worker"],
        created_at=datetime.fromtimestamp(row["created_at"], tz=UTC), started_at=_dt(start), finished_at=_dt(end), timings=timings,
        summary=row["summary"], downloads=downloads,
    )
