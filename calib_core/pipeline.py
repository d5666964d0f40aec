"""calibrate(observations, method, **settings) → Calibration: the pipeline around every method.

The same steps for every method around its fit: set aside misplaced corners (far
beyond the image, or contradicted by their board neighbours), choose the usable
views, fit, reject outliers (robust, per residual component) and refit, then measure.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull, QhullError
from threadpoolctl import threadpool_limits

from . import ranges
from .calibration import Calibration, ViewResult
from .errors import DataError, SettingsError
from .fit_report import Diagnostics, ExcludedPoints, FitMetrics, SolverReport
from .fitting import metrics, view_set
from .fitting.misplaced import misplaced_corners
from .fitting.solve import Data, SolveSettings, levenberg_marquardt
from .methods import METHODS
from .methods.auto import AutoSettings
from .methods.common import Progress, no_progress, settings_from
from .observations import Observations, View
from .provenance import provenance

MIN_VIEWS = 3
MIN_POINTS_PER_VIEW = 6
OUTLIER_ROUNDS = 3


def to_data(obs: Observations) -> tuple[Data, list[str], np.ndarray]:
    """Flat arrays of the views, their names, and each point's index in its view."""
    names = [v.name for v in obs.views]
    obj = np.concatenate([v.object_points for v in obs.views])
    img = np.concatenate([v.image_points for v in obs.views])
    vi = np.concatenate([np.full(len(v), k) for k, v in enumerate(obs.views)])
    local = np.concatenate([np.arange(len(v)) for v in obs.views])
    return Data(obj, img, vi, len(obs.views)), names, local


def without_misplaced(obs: Observations) -> tuple[Observations, dict[str, np.ndarray]]:
    """The observations without misplaced corners (far beyond the image, or contradicted
    by their board neighbours: ``fitting.misplaced``), and those corners' indices in each
    view they left."""
    data, _, _ = to_data(obs)
    flags = misplaced_corners(data.object_points, data.image_points, data.view_index, obs.image_size)
    if not flags.any():
        return obs, {}
    views, removed = [], {}
    for k, v in enumerate(obs.views):
        off = flags[data.view_index == k]
        if off.any():
            removed[v.name] = np.flatnonzero(off)
            v = View(v.name, v.object_points[~off], v.image_points[~off], None if v.ids is None else v.ids[~off],
                     v.frame)
        views.append(v)
    return Observations(obs.image_size, views, obs.board, dict(obs.extra)), removed


def usable_views(obs: Observations, set_aside: dict[str, np.ndarray] | None = None,
                 ) -> tuple[Observations, list[dict[str, str]]]:
    """The views a calibration can use, and each other one with the reason (``set_aside``:
    the misplaced corners ``without_misplaced`` took from each view, named in its reason)."""
    keep, dropped = [], []
    for v in obs.views:
        if len(v) < MIN_POINTS_PER_VIEW:
            reason = f"too few corners ({len(v)}, need at least {MIN_POINTS_PER_VIEW})"
        elif on_one_line(v.object_points):
            reason = "its corners all lie on one line of the board, which cannot fix the board's pose"
        else:
            keep.append(v)
            continue
        if set_aside and v.name in set_aside:
            reason += (f" once {len(set_aside[v.name])} of its corners were set aside as misplaced (beyond the "
                       "image, or not where their board neighbours put them: wrong ids?)")
        dropped.append({"name": v.name, "reason": reason})
    if len(keep) < MIN_VIEWS:
        why = "".join(f"; {d['name']!r}: {d['reason']}" for d in dropped[:3])
        more = f" (and {len(dropped) - 3} more views)" if len(dropped) > 3 else ""
        raise DataError(
            f"only {len(keep)} usable view(s) of {len(obs.views)}; a calibration needs at least {MIN_VIEWS} views "
            f"of the board at different angles{why}{more}"
        )
    return Observations(obs.image_size, keep, obs.board, dict(obs.extra)), dropped


def on_one_line(object_points: np.ndarray) -> bool:
    """Are the points (N, 3) collinear (one row of a board, say)?"""
    centred = object_points - object_points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    return bool(sv[1] <= 1e-6 * max(sv[0], 1e-300))


def robust_outliers(res: np.ndarray, threshold: float) -> np.ndarray:
    """Points with a residual component beyond ``threshold`` robust σ (1.4826·MAD)."""
    sigma = 1.4826 * np.median(np.abs(res - np.median(res, axis=0)))
    limit = max(threshold * sigma, 1e-6)
    return np.any(np.abs(res) > limit, axis=1)


OUTLIER_SIGMA = 5.0  # the default: residuals beyond 5 robust sigmas are outliers


def calibrate(
    observations: Observations,
    method: str = "auto",
    progress: Progress | None = None,
    outlier_sigma: float = OUTLIER_SIGMA,
    **settings: Any,
) -> Calibration:
    """Calibrate with ``method`` (see ``methods.METHODS``); ``settings`` are the
    method's (e.g. ``knots="uniform"``, ``lambda_smooth=1e-2``).

    ``progress(stage, fraction)`` is called as the work goes on; it may raise
    ``solve.Cancelled``. ``outlier_sigma`` = 0 keeps every point.
    """
    # One BLAS thread: the matrices here are small, so threads cost more than
    # they give (measured 4x slower on 2 cores), and results then do not
    # depend on the machine's thread count.
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(observations, method, progress, outlier_sigma, **settings)


MAX_OUTLIER_SIGMA = 100.0  # residuals past 100 sigma: a threshold this high rejects nothing


def check_outlier_sigma(value) -> float:
    return ranges.number("outlier_sigma (0: keep every point)", value, 0, MAX_OUTLIER_SIGMA)


def _calibrate(observations, method, progress, outlier_sigma, **settings) -> Calibration:
    if method not in METHODS:
        raise SettingsError(f"unknown method {method!r}; available: {sorted(METHODS)}")
    check_outlier_sigma(outlier_sigma)
    fit_fn, settings_cls = METHODS[method]
    s = settings_from(settings_cls, settings)
    if isinstance(s, AutoSettings) and s.image_circle is None:
        s.image_circle = observations.image_circle  # where the lens forms an image: the models must map it all
    progress = progress or no_progress
    t0 = time.perf_counter()
    # Gross errors first: one corner thrown far off spoils the first camera every method
    # starts from, and the outlier rounds below then judge a wrong camera's residuals.
    cleaned, misplaced = without_misplaced(observations) if outlier_sigma > 0 else (observations, {})
    obs, dropped = usable_views(cleaned, misplaced)
    view_set.check_views(obs)  # duplicates, all face-on: fail before the solver, saying what to shoot
    data, names, local = to_data(obs)

    fit = fit_fn(data, obs.image_size, s, progress)
    res = fit.result
    view_set.check_fitted_tilts(res.poses[:, :3], planar=bool(np.all(data.object_points[:, 2] == 0)))
    used = ~fit.excluded
    outlier = np.zeros(data.n_points, dtype=bool)
    solve_settings = fit.solve_settings or SolveSettings(getattr(s, "max_iterations", 500), getattr(s, "ftol", 1e-6))
    for _ in range(OUTLIER_ROUNDS if outlier_sigma > 0 else 0):
        full = _residuals(res, data)
        new = used & ~outlier & robust_outliers(np.where(used[:, None], full, 0.0), outlier_sigma)
        new &= used
        if not new.any():
            break
        outlier |= new
        keep = used & ~outlier
        sub = data.points(keep)
        if fit.refit is not None:
            res = fit.refit(sub, res)
        else:
            res = levenberg_marquardt(res.model, res.poses, sub, solve_settings)

    progress("metrics", 0.97)
    full = _residuals(res, data)
    inlier = used & ~outlier
    views = []
    for k, name in enumerate(names):
        m = data.view_index == k
        r = full[m & inlier]
        set_aside = misplaced.get(name, np.zeros(0, dtype=int))
        original = np.delete(np.arange(int(m.sum()) + len(set_aside)), set_aside)  # the view's own indices
        views.append(ViewResult(
            name, res.poses[k, :3].copy(), res.poses[k, 3:].copy(), metrics.rmse(r), metrics.rmse_axis(r),
            int(len(r)), sorted(int(i) for i in np.concatenate([original[local[m & ~inlier]], set_aside])),
        ))
    n_misplaced = sum(len(misplaced.get(name, ())) for name in names)  # in the views used
    fit_metrics = FitMetrics.of(full[inlier], data.image_points[inlier], obs.image_size)
    solver = SolverReport(res.iterations, res.status, res.message, res.cost, res.model.n_params + 6 * data.n_views,
                          time.perf_counter() - t0)
    diagnostics = Diagnostics(
        extra=dict(fit.diagnostics), restart=fit.restart, model_choice=fit.model_choice, solver=solver,
        coverage_hull=coverage_hull(data.image_points[inlier]),
        excluded_points=ExcludedPoints(int(outlier.sum()) + n_misplaced, int(fit.excluded.sum()), fit.excluded_reason,
                                       n_misplaced))
    settings_out = {"method": method, "outlier_sigma": outlier_sigma, **fit.settings}
    progress("done", 1.0)
    return Calibration(res.model, obs.image_size, method, views, dropped, fit_metrics, settings_out, diagnostics,
                       provenance(observations))


def coverage_hull(pixels: np.ndarray) -> list[list[float]]:
    """The convex hull (M, 2) of the corners used: where the calibration has
    data, so that what is derived from it (lean-model exports) stays there."""
    try:
        hull = ConvexHull(pixels)
    except (QhullError, ValueError):
        return []
    return np.round(pixels[hull.vertices], 2).tolist()


def _residuals(res, data: Data) -> np.ndarray:
    from .fitting.solve import residuals

    return residuals(res.model, res.poses, data)
