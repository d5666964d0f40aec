"""What the 3D view needs of a finished job, read from the data directory.

Everything comes from files the worker already wrote (calibration.json,
corner_residuals.json; a rig job's rig.json and its cameras' corners,
camera-K.json) and the set's observations, so building a scene costs no
calibration work, only a few projections. ``load`` reads either kind: a
calibration (``JobResult``) or a rig (``RigResult``).
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib_core import Calibration, Observations
from calib_core.rig import Rig, frame_of

from ..base.context import Context
from ..base.repository import jobs as job_rows
from ..base.repository import sets as set_rows
from ..base.repository.jobs import split_rig
from ..base.storage import RIG_FILE


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


@dataclass
class RigResult:
    """A done rig job, as the rig's scene builder (``rig_scene.py``) reads it: the rig, and the board at each
    of its frames, posed in the reference camera's frame (``BoardView.rvec, tvec``: board → reference camera)."""

    job_id: str
    method: str
    rig: Rig
    boards: list[BoardView] = field(default_factory=list)
    units: str = "mm"


VIEWABLE = ("calibrate", "rig")   # the kinds of done job the 3D view draws


def from_rig(job_id: str, rig: Rig, cameras: dict[str, Observations]) -> RigResult:
    """The rig's frames as boards, their corners taken from a camera that saw them (the reference first),
    with that camera's residuals in the rig; a frame no camera's corners show is left out."""
    order = sorted(cameras, key=lambda name: name != rig.reference)
    seen = {name: {frame_of(v): v for v in cameras[name].views} for name in order if _in_rig(rig, name)}
    boards = []
    for f in rig.frames:
        name = next((n for n in seen if f.frame in seen[n]), None)
        if name is None:
            continue
        v = seen[name][f.frame]
        proj = rig.project(name, v.object_points, f.rvec, f.tvec)
        boards.append(BoardView(f"frame {f.frame}", np.asarray(f.rvec, float), np.asarray(f.tvec, float),
                                np.asarray(v.object_points, float), np.asarray(v.image_points, float),
                                v.image_points - proj))
    # the board's units as its corners give them ("mm"); the calibration's provenance may only describe them
    given = [(o.board or {}).get("units") for o in cameras.values()]
    given.append(rig.cameras[0].calibration.provenance.get("tvec_units"))
    units = next((str(u) for u in given if isinstance(u, str) and re.fullmatch(r"[A-Za-zµ]{1,3}", u)), "board units")
    return RigResult(job_id, rig.cameras[0].calibration.method, rig, boards, units)


def load(ctx: Context, job_id: str) -> JobResult | RigResult | None:
    """The job's result, or None when it is not a done calibration (with a calibration.json) or a done rig
    (with a rig.json)."""
    job = job_rows.get(ctx.db, job_id)
    if job is None or job["kind"] not in VIEWABLE or job["state"] != "done":
        return None
    if job["kind"] == "rig":
        return _load_rig(ctx, job)
    path = ctx.storage.job_dir(job_id) / "calibration.json"
    if not path.exists():
        return None
    cal = Calibration.from_json(json.loads(path.read_text()))
    obs = _observations(ctx, job)
    result = from_calibration(job_id, cal, obs)
    result.method = job["method"] if job["method"] != "compare" else f"compare → {cal.method}"
    return result


def done_jobs(ctx: Context) -> list[dict[str, Any]]:
    """Done calibration jobs that have a calibration and done rig jobs that have a rig, newest first."""
    wanted = {"calibrate": "calibration.json", "rig": RIG_FILE}
    return [j for j in job_rows.list_all(ctx.db, state="done")
            if j["kind"] in wanted and wanted[j["kind"]] in j["artefacts"]]


def set_names(ctx: Context) -> dict[str, str]:
    """Set id → the set's name ("24 images"), for naming jobs as the page does."""
    return {s["id"]: s["name"] for s in set_rows.list_all(ctx.db)}


def _observations(ctx: Context, job: dict[str, Any]) -> Observations | None:
    for path in (ctx.storage.job_dir(job["id"]) / "input.json",
                 ctx.storage.observations_path(job["set_id"] or "")):
        if path.exists():
            return Observations.load(path)
    return None


def _load_rig(ctx: Context, job: dict[str, Any]) -> RigResult | None:
    out = ctx.storage.job_dir(job["id"])
    if not (out / RIG_FILE).exists():
        return None
    rig = Rig.load(out / RIG_FILE)
    spec = split_rig(job["settings"])[1] or {}
    cameras = {}
    for k, name in enumerate(spec.get("names", [])):
        path = ctx.storage.rig_camera_path(job["id"], k)
        if path.exists():
            cameras[name] = Observations.load(path)
    result = from_rig(job["id"], rig, cameras)
    result.method = job["method"] or result.method
    return result


def _in_rig(rig: Rig, name: str) -> bool:
    return any(c.name == name for c in rig.cameras)
