"""A rig job: one copy of corners per camera in, the rig and its exports out.

A thin wrapper, as ``calibrate_job`` is: ``calib_core.rig.calibrate_rig`` with the
job's progress (which raises ``Cancelled`` when asked to stop), then
``artefacts.write_rig``. The settings are those of ``freecal rig`` (the
pipeline's defaults, ``outlier_sigma`` among them), so the job's rig.json is what
the command writes for the same corners.
"""
from __future__ import annotations

from typing import Any

from calib_core import Observations
from calib_core.errors import DataError
from calib_core.rig import calibrate_rig

from ..base.context import Context
from ..base.repository.jobs import split_rig
from . import artefacts
from .lease import JobRun


def run(ctx: Context, job: dict[str, Any], run: JobRun) -> dict[str, Any]:
    run.progress("load", 0.0)
    settings, spec = split_rig(job["settings"])
    if spec is None:
        raise DataError("this rig job names no cameras; create it again")
    cameras = {}
    for k, name in enumerate(spec["names"]):
        path = ctx.storage.rig_camera_path(job["id"], k)  # the corners as they were at creation
        if not path.exists():
            raise DataError(f"camera {name!r}: its corners are missing from the job's folder; create the job again")
        cameras[name] = Observations.load(path)
    rig = calibrate_rig(cameras, job["method"], spec["reference"], lambda s, f: run.progress(s, f, 0.0, 0.85),
                        refine_models=not spec["hold_models"], **settings)
    names, unavailable = artefacts.write_rig(ctx.storage.job_dir(job["id"]), rig,
                                             lambda s, f: run.progress(s, f, 0.85, 1.0))
    return {"artefacts": names, "summary": artefacts.rig_summary(rig, unavailable)}
