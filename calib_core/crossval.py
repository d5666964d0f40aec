"""Cross-validation over views: how well a fitted model predicts views it has not seen.

The same protocol as ``compare`` and ``evaluate``: the model is fitted
without the validated views, then held while only their poses are refit.
Here the model's structure (its knots, smoothing, which parameters are free)
is held too and each refit starts from the full fit, so that scoring a model
costs a few solver iterations per fold, not a calibration.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .solve import Data, SolveSettings, levenberg_marquardt, select_views


def folds(n_views: int, splits: int) -> list[np.ndarray]:
    """View indices validated in each split: interleaved, each view exactly once."""
    return [np.arange(k, n_views, splits) for k in range(splits)]


def view_errors(refit: Callable[[Data, np.ndarray], Any], poses: np.ndarray, data: Data, fitted: np.ndarray,
                validated: np.ndarray, splits: int) -> np.ndarray | None:
    """(n_views,) sum of squared validation residuals (px², both axes) of each
    view over ``splits`` folds of the views: ``refit(train, train_poses)`` fits
    the model to the ``fitted`` points of the other views (starting from
    ``poses``), and the model it returns is held while each validated view's
    pose is refit to its ``validated`` points. None if a fold cannot be refit
    (too few corners for the model, say)."""
    errors = np.zeros(data.n_views)
    for held in folds(data.n_views, splits):
        train_views = np.setdiff1d(np.arange(data.n_views), held)
        try:
            model = refit(select_views(data, train_views, fitted), poses[train_views])
            check = select_views(data, held, validated)
            res = levenberg_marquardt(model, poses[held], check, SolveSettings(max_iterations=100, fix_model=True))
        except (FloatingPointError, np.linalg.LinAlgError):
            return None
        errors[held] = np.bincount(check.view_index, np.sum(res.residuals**2, axis=1), minlength=len(held))
    return errors if np.all(np.isfinite(errors)) else None
