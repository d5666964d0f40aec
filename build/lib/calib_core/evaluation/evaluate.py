"""Hold-out evaluation: the model is held fixed, only each view's pose is refit."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration import Calibration
from ..errors import DataError
from ..fitting import metrics
from ..fitting.init import poses_from_rays
from ..fitting.solve import Data, SolveSettings, levenberg_marquardt
from ..observations import Observations
from ..pipeline import to_data


def validation_residuals(cal: Calibration, obs: Observations) -> tuple[np.ndarray, Data, list[str]]:
    """Residuals (N, 2) of ``obs`` under ``cal``'s model held fixed, each
    view's pose refit (the hold-out protocol of ``evaluate``, ``compare`` and
    the model choice's tests), the flat data they belong to and its view names."""
    data, names, _ = to_data(obs)
    poses = poses_from_rays(cal.model, data)
    if poses is None:
        raise DataError("could not find a board pose for every validation view "
                        "(too few corners the model can unproject)")
    res = levenberg_marquardt(cal.model, poses, data, SolveSettings(max_iterations=200, fix_model=True))
    return res.residuals, data, names


def evaluate(cal: Calibration, obs: Observations) -> dict[str, Any]:
    """Per-view and overall errors of ``cal`` on ``obs`` after a pose-only refit."""
    if tuple(obs.image_size) != tuple(cal.image_size):
        raise DataError(f"image_size {list(obs.image_size)} differs from the calibration's {list(cal.image_size)}")
    r, data, names = validation_residuals(cal, obs)
    views = []
    for k, name in enumerate(names):
        m = data.view_index == k
        views.append({"name": name, "rmse": metrics.rmse(r[m]), "rmse_axis": metrics.rmse_axis(r[m]),
                      "n_points": int(m.sum()), "max_error": float(np.max(np.linalg.norm(r[m], axis=1)))})
    out: dict[str, Any] = metrics.summary(r, data.image_points, obs.image_size)
    out["max_error"] = float(np.max(np.linalg.norm(r, axis=1)))
    out["views"] = views
    return out
