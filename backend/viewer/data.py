"""What the 3D view needs of a finished job, read from the data directory.

Everything comes from files the worker already wrote (calibration.json,
corner_residuals.json) and the set's observations, so building a scene costs
no calibration work, only a few projections.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib_core import Calibration, Observations

from ..base.context import Context
from ..base.repository import jobs as job_rows
from ..base.repository import sets as set_rows


@dataclass
class BoardView:
    """One board pose: its corners in the board frame and their residuals."""

    name: str
    rvec: np.ndarray            # (3,) Rodrigues, board → camera
    tvec: np.ndarray            # (3,) board units
    object_points: np.ndarray   # (N, 3) board frame, board units
    image_points: np.ndarray    # (N, 2) observed pixels
    residuals: np.ndarray       # (N, 2) observed − projected, pixels (NaN where unknown)


@dataclass
class JobResult:
    """A done calibration job, as the scene builder reads it."""

    job_id: str
    method: str
    calibration: Calibration
    boards: list[BoardView] = field(default_factory=list)
    units: str = "mm"

    @property
    def image_size(self) -> tuple[int, int]:
        return self.calibration.image_size


def from_calibration(job_id: str, cal: Calibration, obs: Observations | None) -> JobResult:
    """Pair the calibration's views with their observations (by name) and compute residuals."""
    boards = []
    for v in cal.views:
        try:
            ov = obs.view(v.name) if obs is not None else None
        except KeyError:
            ov = None
        if ov is None:
            continue
        proj = cal.project(ov.object_points, v.rvec, v.tvec)
        boards.append(BoardView(v.name, np.asarray(v.rvec, float), np.asarray(v.tvec, float),
                                np.asarray(ov.object_points, float), np.asarray(ov.image_points, float),
                                ov.image_points - proj))
    units = (obs.board or {}).get("units", "mm") if obs is not None else "mm"
    return JobResult(job_id, cal.method, cal, boards, units or "mm")


def load(ctx: Context, job_id: str) -> JobResult | None:
    """The job's result, or None when it is not a done calibration with a calibration.json."""
    job = job_rows.get(ctx.db, job_id)
    if job is None or job["kind"] != "calibrate" or job["state"] != "done":
        return None
    path = ctx.storage.job_dir(job_id) / "calibration.json"
    if not path.exists():
        return None
    cal = Calibration.from_json(json.loads(path.read_text()))
    obs = _observations(ctx, job)
    result = from_calibration(job_id, cal, obs)
    result.method = job["method"] if job["method"] != "compare" else f"compare → {cal.method}"
    return result


def done_jobs(ctx: Context) -> list[dict[str, Any]]:
    """Done calibration jobs that have a calibration, newest first."""
    return [j for j in job_rows.list_all(ctx.db, kind="calibrate", state="done")
            if "calibration.json" in j["artefacts"]]


def set_names(ctx: Context) -> dict[str, str]:
    """Set id → the set's name ("24 images"), for naming jobs as the page does."""
    return {s["id"]: s["name"] for s in set_rows.list_all(ctx.db)}


def _observations(ctx: Context, job: dict[str, Any]) -> Observations | None:
    for path in (ctx.storage.job_dir(job["id"]) / "input.json",
                 ctx.storage.observations_path(job["set_id"] or "")):
        if path.exists():
            return Observations.load(path)
    return None
