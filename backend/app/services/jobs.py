"""Calibration jobs: create (validating method and settings first), read, cancel, delete."""
from __future__ import annotations

import math
from typing import Any

from calib_core import ranges
from calib_core.errors import SettingsError
from calib_core.evaluation.compare import SETTINGS as COMPARE_SETTINGS
from calib_core.methods import METHODS
from calib_core.methods.common import settings_from
from calib_core.pipeline import check_outlier_sigma

from ...base import storage
from ...base.context import Context
from ...base.repository import jobs, sets
from ...queue.tasks import Queue
from .. import uploads
from ..errors import ApiError, not_found
from ..schemas import JobCreate
from . import exclusion
from . import sets as set_service
from .enqueue import enqueue_job
from .ids import new_id

COMPARE = "compare"
PIPELINE_KEYS = ("outlier_sigma",)     # settings of calibrate() itself, not of a method
MAX_SPLITS = 20                        # folds over the views: each is a calibration of every method


def compare_available() -> bool:
    try:
        from calib_core.evaluation.compare import compare  # noqa: F401
    except ImportError:
        return False
    return True


def validate(method: str, settings: dict[str, Any]) -> None:
    """Refuse at once what would fail in the worker: unknown method, unknown or bad settings."""
    where = _non_finite(settings, "settings")
    if where:  # JSON has no NaN/Infinity, but Python's parser reads them: refuse before the solver sees one
        raise ApiError(422, f"{where}: not a finite number (NaN or Infinity); give a finite value")
    if method == COMPARE:
        if not compare_available():
            raise ApiError(422, "method 'compare' is not available in this version; choose one of "
                                f"{sorted(METHODS)}")
        unknown = sorted(set(settings) - set(COMPARE_SETTINGS))
        if unknown:
            raise ApiError(422, f"unknown compare setting(s) {unknown}; known: {list(COMPARE_SETTINGS)}")
        splits = settings.get("splits", 5)
        if splits != 0:
            ranges.whole("splits", splits, 2, MAX_SPLITS, alternative="0 (no cross-validation)")
        chosen = settings.get("methods")
        if chosen is not None and not (isinstance(chosen, list) and all(isinstance(m, str) for m in chosen)):
            raise ApiError(422, "settings.methods: expected a list of method names, e.g. [\"zhang\", \"bspline\"]")
        bad = [m for m in chosen or [] if m not in METHODS]
        if bad:
            raise ApiError(422, f"unknown method(s) {bad} in settings.methods; available: {sorted(METHODS)}")
        return
    if method not in METHODS:
        raise ApiError(422, f"unknown method {method!r}; available: {sorted(METHODS)} or 'compare'")
    check_outlier_sigma(settings.get("outlier_sigma", 0.0))
    _, cls = METHODS[method]
    try:
        settings_from(cls, {k: v for k, v in settings.items() if k not in PIPELINE_KEYS})
    except SettingsError:
        raise
    except (TypeError, ValueError) as exc:
        raise ApiError(422, f"settings of {method}: a value has the wrong type ({exc})") from None


def _non_finite(value: Any, where: str) -> str | None:
    if isinstance(value, float) and not math.isfinite(value):
        return where
    if isinstance(value, dict):
        return next((w for k, v in value.items() if (w := _non_finite(v, f"{where}.{k}"))), None)
    if isinstance(value, list):
        return next((w for i, v in enumerate(value) if (w := _non_finite(v, f"{where}[{i}]"))), None)
    return None


def create(ctx: Context, queue: Queue, body: JobCreate) -> str:
    validate(body.method, body.settings)
    job_id = new_id()
    stage = "queued"
    if body.observations is not None:
        obs = uploads.observations_within(body.observations, "the inline observations", ctx.settings)
        exclude = exclusion.check(ctx, body.exclude, None, obs)
        storage.write_json(ctx.storage.job_dir(job_id) / "input.json", obs.to_json())
    else:
        assert body.set_id is not None  # JobCreate: exactly one of the two inputs
        row = sets.get(ctx.db, body.set_id)
        if row is None:
            raise not_found("set", body.set_id)
        state, _, error, _ = set_service.state(ctx, row)
        if state in ("failed", "cancelled"):
            raise ApiError(409, f"set {row['name']!r} has no corners: its detection {state}"
                           + (f" ({error})" if error else "") + "; run its detection again with the right board")
        if state != "ready":  # queued now, run by the worker once the detection is done (execute.py)
            stage = jobs.WAITING_FOR_DETECTION
        exclude = exclusion.check(ctx, body.exclude, row, None)
    settings = {**body.settings, jobs.EXCLUDE_KEY: exclude} if exclude else body.settings
    jobs.create(ctx.db, job_id, "calibrate", body.set_id, body.method, settings, stage)
    enqueue_job(ctx, queue, job_id)
    return job_id


def get(ctx: Context, job_id: str) -> dict[str, Any]:
    job = jobs.get(ctx.db, job_id)
    if job is None:
        raise not_found("job", job_id)
    return job


def cancel(ctx: Context, job_id: str) -> dict[str, Any]:
    if jobs.request_cancel(ctx.db, job_id) is None:
        raise not_found("job", job_id)
    return get(ctx, job_id)


def delete(ctx: Context, job_id: str) -> None:
    job = get(ctx, job_id)
    if job["state"] == "running":
        jobs.request_cancel(ctx.db, job_id)
        raise ApiError(409, f"job {job_id} is running: cancellation was requested; delete it once its "
                            "state is cancelled")
    if job["kind"] == "detect":
        raise ApiError(409, "a detection job belongs to its set: delete the set instead")
    jobs.delete(ctx.db, job_id)
    ctx.storage.remove_job(job_id)
