"""A B-spline field over a parametric core (formats.md ``hybrid``):
``uv = p + Δ(p)`` with ``p`` the core's pixel.

The core (Kannala–Brandt, or OpenCV's 5-coefficient or rational model) carries what a lens
shares with the textbook models; the field, regularised towards zero, models
only what the core misses. On a lens the core describes exactly the field
stays near zero and the estimate keeps the core's low variance; on a freeform
lens the field takes the rest. Its knots live in pixel coordinates of ``p``,
so its domain is essentially the image rectangle, whatever the field of view.

Parameters: ``[core parameters, control_x (flat), control_y (flat)]``.
Gauge: as for the pure spline, the field's value and gradient vanish at a
fixed pixel (the initial principal point), so the core keeps the affine part.

``field_held``: the field is zero and not fitted, the core is (all of it):
what the B-spline method returns when the corners give the field nothing to
model (``methods/bspline_auto.py``, the model choice).
"""
from __future__ import annotations

import copy
from typing import Any, Self

import numpy as np
import scipy.sparse as sp

from ..errors import FormatError
from . import bspline_kernel
from .base import CameraModel, ParametricModel, Prior, core_inverse_start
from .bspline import GAUGE_WEIGHT, field_prior_rows, recorded_regularisation
from .bspline_basis import BSplineField
from .fisheye import FisheyeModel
from .opencv import OpenCVModel


class HybridModel(CameraModel):
    kind = "hybrid"

    def __init__(self, core: ParametricModel, field: BSplineField, lambda_reg: float = 1e-3,
                 lambda_smooth: float = 1.0, gauge_point: tuple[float, float] | None = None,
                 field_held: bool = False):
        self.core = core
        self.intrinsics = core.intrinsics  # the core's own array: with_params keeps them the same
        self.field = field
        self.base = core.base
        self.lambda_reg = float(lambda_reg)
        self.lambda_smooth = float(lambda_smooth)
        self.gauge_point = gauge_point
        self.field_held = bool(field_held)
        self._prior_matrix: sp.csr_matrix | None = None  # built on first use, kept by with_params

    @property
    def n_params(self) -> int:
        return self.core.n_params + 2 * self.field.n_controls

    def params(self) -> np.ndarray:
        c = self.field.control
        return np.concatenate([self.core.params(), c[..., 0].ravel(), c[..., 1].ravel()])

    def free_mask(self) -> np.ndarray:
        """The core's distortion coefficients stay where its own calibration put
        them; [fx, fy, cx, cy] and the field move. Left free, the coefficients
        trade places with the field along a near-flat valley, and the rational
        core's denominators then bend wildly outside the corners (measured:
        hold-out errors 1.5-2x larger at the image corners, 3-10x more iterations)."""
        free = np.ones(self.n_params, dtype=bool)
        if self.field_held:
            free[self.core.n_params :] = False
        else:
            free[4 : self.core.n_params] = False
        return free

    def with_params(self, x: np.ndarray) -> Self:
        k, nc = self.core.n_params, self.field.n_controls
        new = copy.copy(self)  # the settings, and the prior rows cached for these knots
        new.core = self.core.with_params(x[:k])
        new.intrinsics = new.core.intrinsics
        new.field = self.field.with_control(np.stack([x[k : k + nc], x[k + nc :]], axis=-1))
        return new

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        if not jacobian:
            p = self.core.pixel_of(xn)
            return p + self.field(p)
        p, d_xn, cols, vals = self.core.pixel_of(xn, jacobian=True)
        offset, grad, design = self.field.evaluate(p)
        a = grad + np.eye(2)
        # ∂(p + Δ(p))/∂θ = A ∂p/∂θ: each row mixes both rows of the core's
        # Jacobian, so both rows' columns appear in each.
        out_cols, out_vals = bspline_kernel.hybrid_rows(
            np.ascontiguousarray(cols, dtype=np.int64), np.ascontiguousarray(vals, dtype=np.float64),
            np.ascontiguousarray(a), design.cols, design.w, self.core.n_params, self.field.n_controls)
        return p + offset, a @ d_xn, out_cols, out_vals

    def newton_start(self, uv: np.ndarray) -> np.ndarray:
        return core_inverse_start(self, self.core, uv, self.field(uv))

    def prior(self) -> Prior:
        if self._prior_matrix is None:
            rows = field_prior_rows(self.field, self.lambda_reg, self.lambda_smooth, self.gauge_point)
            self._prior_matrix = sp.hstack([sp.csr_matrix((rows.shape[0], self.core.n_params)), rows]).tocsr()
        return self._prior_matrix @ self.params(), self._prior_matrix

    @property
    def bspline_field(self) -> BSplineField:
        return self.field

    def exact_parametric(self) -> ParametricModel | None:
        """The core, when the field is held at zero (the B-spline method's
        choice on a lens a textbook model fits)."""
        return self.core if self.field_held else None

    def base_json(self) -> str:
        return self.core.base_json()

    def distortion_json(self) -> dict[str, Any]:
        return {"type": "hybrid", "core": self.core.distortion_json(), "field": self.field.to_json()}

    def settings_json(self) -> dict[str, Any]:
        return {
            "core": self.core.kind,
            "lambda_reg": self.lambda_reg,
            "lambda_smooth": self.lambda_smooth,
            "gauge": {"type": "field value and gradient zero at a fixed pixel",
                      "point": list(self.gauge_point) if self.gauge_point else None},
            "field_held": self.field_held,
        }

    def restored(self, settings: dict[str, Any]) -> HybridModel:
        lambda_reg, lambda_smooth, gauge_point = recorded_regularisation(settings, (self.lambda_reg, self.lambda_smooth))
        return HybridModel(self.core, self.field, lambda_reg, lambda_smooth, gauge_point,
                           settings.get("field_held") is True)

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        core_doc, field_doc = distortion.get("core"), distortion.get("field")
        if not isinstance(core_doc, dict) or core_doc.get("type") not in ("opencv", "fisheye"):
            raise FormatError("distortion.core: expected an 'opencv' or 'fisheye' distortion object")
        if not isinstance(field_doc, dict) or field_doc.get("type") != "bspline":
            raise FormatError("distortion.field: expected a 'bspline' distortion object")
        core_type = OpenCVModel if core_doc["type"] == "opencv" else FisheyeModel
        core = core_type.from_json(intrinsics, core_doc, base)
        return cls(core, BSplineField.from_json(field_doc, "distortion.field"))


__all__ = ["HybridModel", "GAUGE_WEIGHT"]
