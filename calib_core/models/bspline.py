"""The paper's model: a pinhole (or other base) camera whose ideal pixels are
moved by a bicubic B-spline field, ``uv = K xn + Δ(K xn)`` (``formats.md``).

Parameters: ``[fx, fy, cx, cy, skew, control_x (flat), control_y (flat)]``.

Gauge. A cubic spline reproduces any affine function of (u, v), so the
intrinsics (and a roll of every pose) can be traded against the field's affine
part. We fix this deliberately: the field's value and gradient vanish at a
fixed ideal pixel ``c0`` (by default the initial principal point). Then
fx, fy, cx, cy, skew are the camera's local pinhole at the optical axis, as in
OpenCV's models, and the six affine degrees of freedom are pinned by six
constraint rows. The remaining near-degeneracy (a common tilt of every pose
against a projective change of the field, which a principal-point shift
mimics to first order) is governed by the regularisers on the pinhole base,
where holding cx, cy was measured to cost accuracy on wide lenses (fisheye
hold-out 0.19 → 0.42 px): they stay free there. On an angular base the field
follows a turn of the whole camera almost exactly, and a free fit walks the
principal point along that valley to wherever the regularisers settle it
(BabelCalib: 60 px from the parametric camera's). There cx, cy and skew stay
where the initial camera put them (``ANGULAR_HELD``), as mrcal locks its
splined model's core (docs/model-choice.md, "Why the fixed grid crawls").

Regularisers, as prior rows of the least-squares cost
``Σ‖r‖² + λ_reg ‖P − P₀‖² + λ_smooth ‖D (P − P₀)‖²``: D approximates the
bending energy of the field (``bspline.bending_operator``), λ weighs it against
one squared residual component (pixels²). These act like a prior, so their
influence shrinks as the data grows, as a prior's should, and a value means
the same at every data-set size. ``P₀`` (``prior_control``) is the field of
the initial camera (zero if not given): the field's *departure* from it is
what is kept small and smooth, so where corners are missing the field follows
the lens's own shape instead of flattening out.
"""
from __future__ import annotations

import copy
from typing import Any, Self

import numpy as np
import scipy.sparse as sp

from ..errors import FormatError
from .base import CameraModel, Prior, intrinsics_jacobian
from .bspline_basis import BSplineField

GAUGE_WEIGHT = 1e4  # constraint rows are multiplied by this: violations ~1e-8 px
ANGULAR_HELD = {"cx": 2, "cy": 3, "skew": 4}  # held on an angular base (module text): name → parameter index


def gauge_rows(field: BSplineField, point: tuple[float, float]) -> sp.csr_matrix:
    """(6, 2 n_controls): Δx, Δy and their u, v derivatives (scaled to pixels
    over the domain) at ``point``; rows interleave x and y."""
    nc = field.n_controls
    d = field.design(np.array([point]), derivative=True)
    w_u, w_v = d.derivative_weights()
    u0, u1, v0, v1 = field.domain
    scale = 0.5 * ((u1 - u0) + (v1 - v0))
    values = np.repeat(np.stack([d.w[0], scale * w_u[0], scale * w_v[0]]), 2, axis=0)  # (6, 16)
    cols = d.cols[0] + np.array([[0], [nc]] * 3)  # x rows on the first nc columns, y rows on the others
    return sp.csr_matrix((values.ravel(), cols.ravel(), np.arange(0, 97, 16)), shape=(6, 2 * nc))


def field_prior_rows(field: BSplineField, lambda_reg: float, lambda_smooth: float,
                     gauge_point: tuple[float, float] | None) -> sp.csr_matrix:
    """Prior rows over ``[control_x, control_y]``: √λ_reg·I, √λ_smooth·D per
    component, then the 6 gauge rows (weighted) if a gauge point is given."""
    nc = field.n_controls
    blocks = []
    if lambda_reg > 0:
        blocks.append(np.sqrt(lambda_reg) * sp.identity(nc))
    if lambda_smooth > 0:
        blocks.append(np.sqrt(lambda_smooth) * field.bending())
    per_component = sp.vstack(blocks) if blocks else sp.csr_matrix((0, nc))
    rows = [sp.block_diag([per_component, per_component])]
    if gauge_point is not None:
        rows.append(GAUGE_WEIGHT * gauge_rows(field, gauge_point))
    return sp.vstack(rows).tocsr()


def recorded_regularisation(settings: dict[str, Any], defaults: tuple[float, float]
                            ) -> tuple[float, float, tuple[float, float] | None]:
    """(λ_reg, λ_smooth, gauge point or None) as a calibration's ``settings``
    record them; ``defaults`` where they are missing or not numbers."""
    def number(value: Any) -> float | None:
        """``value`` as a float if it is a finite JSON number (not a bool), else None."""
        if isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value):
            return float(value)
        return None

    def weight(key: str, default: float) -> float:
        value = number(settings.get(key))
        return value if value is not None and value >= 0 else default

    gauge = settings.get("gauge")
    recorded = gauge.get("point") if isinstance(gauge, dict) else None
    coordinates = [number(c) for c in recorded] if isinstance(recorded, list) and len(recorded) == 2 else []
    point = None
    if len(coordinates) == 2 and coordinates[0] is not None and coordinates[1] is not None:
        point = (coordinates[0], coordinates[1])
    return weight("lambda_reg", defaults[0]), weight("lambda_smooth", defaults[1]), point


class BSplineModel(CameraModel):
    kind = "bspline"

    def __init__(
        self,
        intrinsics,
        field: BSplineField,
        base: str = "pinhole",
        lambda_reg: float = 1e-3,
        lambda_smooth: float = 1e-3,
        gauge_point: tuple[float, float] | None = None,
        prior_control: np.ndarray | None = None,
        hold_centre: bool | None = None,
    ):
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64)
        self.field = field
        self.base = base
        self.lambda_reg = float(lambda_reg)
        self.lambda_smooth = float(lambda_smooth)
        self.gauge_point = None if gauge_point is None else (float(gauge_point[0]), float(gauge_point[1]))
        self.prior_control = prior_control  # (n_u, n_v, 2) or None
        # cx, cy, skew held (ANGULAR_HELD): on an angular base unless told (a file from before the hold: free)
        self.hold_centre = base != "pinhole" if hold_centre is None else bool(hold_centre)
        self._prior_rows: tuple[sp.csr_matrix, np.ndarray] | None = None  # built on first use, kept by with_params

    @property
    def n_params(self) -> int:
        return 5 + 2 * self.field.n_controls

    def free_mask(self) -> np.ndarray | None:
        if not self.hold_centre:
            return None
        free = np.ones(self.n_params, dtype=bool)
        free[list(ANGULAR_HELD.values())] = False
        return free

    def params(self) -> np.ndarray:
        c = self.field.control
        return np.concatenate([self.intrinsics, c[..., 0].ravel(), c[..., 1].ravel()])

    def with_params(self, x: np.ndarray) -> Self:
        nc = self.field.n_controls
        control = np.stack([x[5 : 5 + nc], x[5 + nc :]], axis=-1)
        new = copy.copy(self)  # the settings, and the prior rows cached for these knots
        new.intrinsics = np.asarray(x[:5], dtype=np.float64).copy()
        new.field = self.field.with_control(control)
        return new

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        ideal = self.ideal_pixel(xn)
        if not jacobian:
            return ideal + self.field(ideal)
        offset, grad, design = self.field.evaluate(ideal)
        a = grad + np.eye(2)  # ∂uv/∂ideal
        fx, fy, _, _, s = self.intrinsics
        d_xn = a @ np.array([[fx, s], [0.0, fy]])
        n, nc = len(xn), self.field.n_controls
        cols = np.empty((n, 2, 21), dtype=np.int64)
        vals = np.empty((n, 2, 21))
        cols[:, :, :5] = np.arange(5)
        vals[:, :, :5] = intrinsics_jacobian(xn, a)
        cols[:, 0, 5:] = 5 + design.cols
        cols[:, 1, 5:] = 5 + nc + design.cols
        vals[:, 0, 5:] = design.w
        vals[:, 1, 5:] = design.w
        return ideal + offset, d_xn, cols, vals

    # ---- prior rows: regularisers and gauge ----------------------------------
    def prior(self) -> Prior:
        if self._prior_rows is None:
            self._prior_rows = self._build_prior()
        matrix, offset = self._prior_rows
        return matrix @ self.params() - offset, matrix

    def _build_prior(self) -> tuple[sp.csr_matrix, np.ndarray]:
        controls = field_prior_rows(self.field, self.lambda_reg, self.lambda_smooth, self.gauge_point)
        offset = np.zeros(controls.shape[0])
        if self.prior_control is not None:
            p0 = self.prior_control
            # The regulariser rows act on P − P₀; the gauge rows (last 6) on P.
            offset = controls @ np.concatenate([p0[..., 0].ravel(), p0[..., 1].ravel()])
            if self.gauge_point is not None:
                offset[-6:] = 0.0
        matrix = sp.hstack([sp.csr_matrix((controls.shape[0], 5)), controls]).tocsr()
        return matrix, offset

    @property
    def bspline_field(self) -> BSplineField:
        return self.field

    def restored(self, settings: dict[str, Any]) -> BSplineModel:
        # P₀ (the initial camera's field) is not recorded: the prior rows, and
        # so the covariance, do not depend on it.
        lambda_reg, lambda_smooth, gauge_point = recorded_regularisation(settings, (self.lambda_reg, self.lambda_smooth))
        gauge = settings.get("gauge")
        held = gauge.get("held") if isinstance(gauge, dict) else None
        return BSplineModel(self.intrinsics, self.field, self.base, lambda_reg, lambda_smooth, gauge_point,
                            hold_centre=bool(held) if isinstance(held, list) else False)

    # ---- JSON ------------------------------------------------------------------
    def distortion_json(self) -> dict[str, Any]:
        return self.field.to_json()

    def settings_json(self) -> dict[str, Any]:
        return {
            "lambda_reg": self.lambda_reg,
            "lambda_smooth": self.lambda_smooth,
            "gauge": {
                "type": "field value and gradient zero at a fixed ideal pixel",
                "point": list(self.gauge_point) if self.gauge_point else None,
                "held": list(ANGULAR_HELD) if self.hold_centre else [],
            },
            "prior_field": "initial Kannala-Brandt camera" if self.prior_control is not None else "zero",
        }

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        if distortion.get("type") != "bspline":
            raise FormatError("distortion.type: expected 'bspline'")
        return cls(intrinsics, BSplineField.from_json(distortion), base=base)
