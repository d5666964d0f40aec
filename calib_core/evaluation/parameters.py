"""Each fitted parameter with its standard deviation: the square root of the
diagonal of the model parameters' covariance (``uncertainty.model_covariance``:
the sandwich ``σ² H⁻¹ JᵀJ H⁻¹`` with the board poses marginalised, σ from the
residuals), from the calibration and the corners it was fitted to (the calibration
file alone holds no covariance).

Parameters a fit holds (a hybrid's core coefficients) are listed as held, with no
deviation. A B-spline field's control values (hundreds) are summarised in one row:
how many, and the median and largest deviation among them.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration import Calibration
from ..models import BSplineModel, FisheyeModel, HybridModel, OpenCVModel
from ..models.base import CameraModel
from ..models.residual_field import ResidualFieldModel
from ..observations import Observations

OPENCV_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty")
FIELD = "field"  # the name given to a B-spline field's control values


def parameter_names(model: CameraModel) -> list[str]:
    """One name per entry of ``model.params()``; a field's control values are all ``FIELD``."""
    if isinstance(model, HybridModel):
        return parameter_names(model.core) + [FIELD] * (model.n_params - model.core.n_params)
    if isinstance(model, BSplineModel):
        return ["fx", "fy", "cx", "cy", "skew"] + [FIELD] * (model.n_params - 5)
    if isinstance(model, ResidualFieldModel):  # MLS, TPS: the field is interpolated, not fitted by LM
        return parameter_names(model.parametric)
    if isinstance(model, FisheyeModel):
        return ["fx", "fy", "cx", "cy"] + [f"k{i + 1}" for i in range(len(model.coefficients))]
    if isinstance(model, OpenCVModel):
        return ["fx", "fy", "cx", "cy"] + list(OPENCV_NAMES[: len(model.coefficients)])
    return ["fx", "fy", "cx", "cy"] + [f"p{i}" for i in range(model.n_params - 4)]


def parameter_table(cal: Calibration, obs: Observations | None) -> dict[str, Any]:
    """``{"rows": [{name, value, std, units, held}], "field": {...} or None, "sigma", "dof", "note"}``;
    without ``obs`` every ``std`` is None (nothing to estimate it from)."""
    from .uncertainty import inlier_data, model_covariance

    model = cal.model
    names, values = parameter_names(model), model.params()
    free = model.free_mask()
    free = np.ones(model.n_params, dtype=bool) if free is None else free
    std = np.full(model.n_params, np.nan)
    sigma = dof = None
    if obs is not None:
        data, poses = inlier_data(cal, obs)
        cov, sigma, dof = model_covariance(model, poses, data)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    is_field = np.array([n == FIELD for n in names])
    rows = [{"name": names[i], "value": float(values[i]), "std": None if not free[i] or np.isnan(std[i]) else float(std[i]),
             "units": "px" if names[i] in ("fx", "fy", "cx", "cy", "skew") else "", "held": not free[i]}
            for i in np.flatnonzero(~is_field)]
    field = None
    if is_field.any():
        s = std[is_field & free]
        field = {"n_values": int(is_field.sum()), "held": bool(not free[is_field].any()),
                 "std_median": None if not s.size or np.isnan(s).all() else float(np.nanmedian(s)),
                 "std_max": None if not s.size or np.isnan(s).all() else float(np.nanmax(s)), "units": "px"}
    return {"rows": rows, "field": field, "sigma": sigma, "dof": dof,
            "note": "standard deviation if the corners were measured again with the same noise (σ per axis, from "
                    "the residuals), the board poses refitted; held: not moved by the fit"}
