"""A calibration job: observations in, calibration and its result files out.

A thin wrapper: ``calib_core.calibrate`` (one method) or
``calib_core.evaluation.compare.compare`` (every method), then ``artefacts.write_all``.
"""
from __future__ import annotations

from typing import Any

from calib_core import Observations, calibrate
from calib_core.errors import DataError
from calib_core.evaluation.compare import SETTINGS as COMPARE_SETTINGS

from ..base.context import Context
from ..base.repository.jobs import split_settings
from . import artefacts
from .lease import JobRun

COMPARE = "compare"


def load_input(ctx: Context, job: dict[str, Any]) -> Observations:
    inline = ctx.storage.job_dir(job["id"]) / "input.json"
    if inline.exists():
        return Observations.load(inline)
    path = ctx.storage.observations_path(job["set_id"] or "")
    if not path.exists():
        raise DataError("the image set has no corners yet (or was deleted): wait until its detection is done, "
                        "or upload an observations JSON")
    return Observations.load(path)


def without(obs: Observations, exclude: list[str]) -> Observations:
    """The observations less the views the user left out (names of images that gave no view are no matter)."""
    if not exclude:
        return obs
    gone = set(exclude)
    return obs.select([v.name for v in obs.views if v.name not in gone])


def run(ctx: Context, job: dict[str, Any], run: JobRun) -> dict[str, Any]:
    run.progress("load", 0.0)
    settings, exclude = split_settings(job["settings"])
    obs = without(load_input(ctx, job), exclude)
    out = ctx.storage.job_dir(job["id"])
    if job["method"] == COMPARE:
        from calib_core.evaluation.compare import compare

        kwargs = {k: settings[k] for k in COMPARE_SETTINGS if k in settings}
        result = compare(obs, progress=lambda s, f: run.progress(s, f, 0.0, 0.85), **kwargs)
        best = None
        if result.verdict:
            # compare() keeps only figures: fit the winner on every view for its files
            best = calibrate(obs, result.verdict, progress=lambda s, f: run.progress(s, f, 0.85, 0.97))
            best.settings["chosen_by"] = "compare"   # not asked for by name: what its camera block says
        run.progress("metrics", 0.0, 0.97, 1.0)
        names = artefacts.write_comparison(out, result, obs, best)
        return {"artefacts": names, "summary": artefacts.compare_summary(result)}
    cal = calibrate(obs, job["method"], progress=lambda s, f: run.progress(s, f, 0.0, 0.97), **settings)
    if exclude:
        cal.diagnostics.excluded_views = exclude   # in calibration.json: the views the user left out
    run.progress("metrics", 0.0, 0.97, 1.0)
    names = artefacts.write_calibration(out, cal, obs)
    return {"artefacts": names, "summary": artefacts.summary(cal, len(exclude))}
