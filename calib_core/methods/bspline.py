"""The paper's method (Wang et al. 2026), method.md §"Pipeline":

initialise → observed distortion at ideal pixels → adaptive knots → control
points by dual-regularised least squares → joint Levenberg–Marquardt over
intrinsics, every pose and every control point.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import camera, knots
from ..bspline import BSplineField, clamped_knots
from ..errors import DataError, SettingsError
from ..init import initialise
from ..metrics import design_diagnostics
from ..models.bspline import GAUGE_WEIGHT, BSplineModel
from ..solve import Data, SolveSettings, levenberg_marquardt
from .common import Fit, Progress

# A pinhole base maps a ray θ off axis to tan θ: past this angle the ideal
# image runs off to infinity and the field cannot be fitted there.
PINHOLE_MAX_ANGLE_DEG = 85.0
DOMAIN_MARGIN = 0.02  # of the domain's span, on every side


@dataclass
class BSplineSettings:
    knots: str = "kde"  # "kde" | "uniform"
    intervals: tuple[int, int] = (8, 8)  # for uniform knots
    bandwidth: str = "scott"
    bandwidth_factor: float = 1.0
    max_intervals: int = 15
    min_support: int | None = None
    window_ratio: float = 0.05
    weighting: str = "local_std"  # Table 12: local_std | uniform | magnitude | gradient
    lambda_reg: float = 1e-3
    lambda_smooth: float = 1e-3
    base: str = "pinhole"
    max_iterations: int = 500
    ftol: float = 1e-6

    def validate(self) -> None:
        if self.lambda_reg < 0 or self.lambda_smooth < 0:
            raise SettingsError("lambda_reg and lambda_smooth must be zero or positive")
        if self.base not in camera.BASES:
            raise SettingsError(f"base: expected one of {camera.BASES}, got {self.base!r}")
        if self.weighting not in knots.WEIGHTINGS:
            raise SettingsError(f"weighting: expected one of {knots.WEIGHTINGS}, got {self.weighting!r}")
        if self.max_iterations < 1:
            raise SettingsError("max_iterations must be at least 1")
        if not 0 < self.ftol < 1:
            raise SettingsError("ftol must lie in (0, 1)")
        if isinstance(self.intervals, int):
            self.intervals = (self.intervals, self.intervals)
        self.knot_settings().validate()

    def knot_settings(self) -> knots.KnotSettings:
        return knots.KnotSettings(
            strategy=self.knots, bandwidth=self.bandwidth, bandwidth_factor=self.bandwidth_factor,
            window_ratio=self.window_ratio, max_intervals=self.max_intervals, min_support=self.min_support,
            uniform_intervals=tuple(self.intervals),
        )


def ideal_samples(model, poses, data: Data, base: str):
    """Ideal pixels (N, 2) of every observed corner under ``model``'s intrinsics
    and poses on ``base``, and a mask of those the base can represent."""
    pc = camera.transform(poses, data.view_index, data.object_points)
    cos_angle = pc[:, 2] / np.linalg.norm(pc, axis=1)
    ok = np.ones(len(pc), dtype=bool)
    if base == "pinhole":
        ok = cos_angle > np.cos(np.radians(PINHOLE_MAX_ANGLE_DEG))
    ideal = np.full((len(pc), 2), np.nan)
    ideal[ok] = model.ideal_pixel(camera.normalise(pc[ok], base))
    return ideal, ok


def image_domain(init_model, intrinsics: np.ndarray, base: str, image_size, samples: np.ndarray):
    """Knot domain: the ideal positions of the whole image border (where the
    initial camera puts them) and of every sample, plus a margin."""
    w, h = image_size
    t = np.linspace(0, 1, 200)
    border = np.concatenate([
        np.column_stack([t * (w - 1), np.zeros_like(t)]), np.column_stack([t * (w - 1), np.full_like(t, h - 1)]),
        np.column_stack([np.zeros_like(t), t * (h - 1)]), np.column_stack([np.full_like(t, w - 1), t * (h - 1)]),
    ])
    rays = init_model.rays(border)
    rays = rays[np.all(np.isfinite(rays), axis=1)]
    if base == "pinhole":
        max_angle = np.radians(PINHOLE_MAX_ANGLE_DEG)
        theta = np.minimum(np.arccos(np.clip(rays[:, 2], -1, 1)), max_angle)
        rho = np.linalg.norm(rays[:, :2], axis=1)
        direction = rays[:, :2] / np.maximum(rho, 1e-12)[:, None]
        xn = np.tan(theta)[:, None] * direction
    else:
        xn = camera.normalise(rays, base)
    fx, fy, cx, cy, s = intrinsics
    ideal = np.column_stack([fx * xn[:, 0] + s * xn[:, 1] + cx, fy * xn[:, 1] + cy])
    pts = np.vstack([ideal, samples])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = DOMAIN_MARGIN * (hi - lo)
    return (lo[0] - pad[0], hi[0] + pad[0], lo[1] - pad[1], hi[1] + pad[1])


def solve_control_points(model: BSplineModel, samples: np.ndarray, response: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(Bᵀ W B + λ1 I + λ2 (D_rᵀD_r + D_cᵀD_c) + gauge) P = Bᵀ W d, per component.

    Weights are scaled to mean 1 so that λ keeps its meaning (one squared
    control value against one squared residual)."""
    field = model.field
    nc = field.n_controls
    b = field.design(samples).matrix(nc)
    d2 = field.bending()
    reg = model.lambda_reg * sp.identity(nc) + model.lambda_smooth * (d2.T @ d2)
    gauge = model.gauge_rows() * GAUGE_WEIGHT
    control = np.zeros((nc, 2))
    for c in range(2):
        w = weights[:, c] / weights[:, c].mean()
        g = gauge[c::2, c * nc : (c + 1) * nc]
        a = (b.T @ sp.diags(w) @ b + reg + g.T @ g).toarray()
        rhs = b.T @ (w * response[:, c])
        control[:, c] = np.linalg.lstsq(a, rhs, rcond=None)[0] if np.linalg.cond(a) > 1e14 else np.linalg.solve(a, rhs)
    return control


def fit_bspline(data: Data, image_size, s: BSplineSettings, progress: Progress) -> Fit:
    progress("initialise", 0.0)
    init = initialise(data, image_size)
    intrinsics = np.array([*init.model.intrinsics[:4], 0.0])
    base_model = BSplineModel(intrinsics, BSplineField.zeros(clamped_knots([0, 1]), clamped_knots([0, 1])), s.base)
    ideal, ok = ideal_samples(base_model, init.poses, data, s.base)
    if ok.sum() < 0.5 * len(ok):
        raise DataError(
            f"most corners lie more than {PINHOLE_MAX_ANGLE_DEG:.0f}° off axis, where a pinhole base cannot "
            "represent them: use --base equidistant or stereographic"
        )
    samples = ideal[ok]
    response = data.image_points[ok] - samples

    progress("knots", 0.15)
    ks = s.knot_settings()
    domain = image_domain(init.model, intrinsics, s.base, image_size, samples)
    weights = np.column_stack([
        knots.sample_weights(samples[:, a], response[:, a], s.weighting, ks) for a in range(2)
    ])
    if s.knots == "kde":
        bu, bv = knots.adaptive_breaks(samples, weights, domain, ks)
    else:
        bu, bv = knots.uniform_breaks(domain, ks.uniform_intervals)
    field = BSplineField.zeros(clamped_knots(bu), clamped_knots(bv))
    gauge_point = (float(intrinsics[2]), float(intrinsics[3]))
    model = BSplineModel(intrinsics, field, s.base, s.lambda_reg, s.lambda_smooth, gauge_point)
    n_params = model.n_params + 6 * data.n_views
    if 2 * ok.sum() <= n_params:
        raise DataError(
            f"{ok.sum()} corners give {2 * ok.sum()} equations for {n_params} unknowns: add views, "
            "or use fewer knot intervals (--max-intervals, or --knots uniform --intervals N)"
        )

    progress("control points", 0.25)
    control = solve_control_points(model, samples, response, weights)
    model = model.with_params(np.concatenate([intrinsics, control[:, 0], control[:, 1]]))
    d2 = field.bending()
    reg_rows = sp.vstack([np.sqrt(max(s.lambda_reg, 0)) * sp.identity(field.n_controls), np.sqrt(s.lambda_smooth) * d2])
    diagnostics = {
        "design": design_diagnostics(field.design(samples).matrix(field.n_controls), weights / weights.mean(axis=0),
                                     reg_rows, bu, bv, samples),
        "initialisation": {"focal_source": init.focal_source, "model": "kannala-brandt (4)", "rmse": init.rmse},
        "domain": list(domain),
    }

    progress("joint optimisation", 0.3)
    sub = Data(data.object_points[ok], data.image_points[ok], data.view_index[ok], data.n_views)

    def on_iteration(it: int, cost: float) -> None:
        progress("joint optimisation", 0.3 + 0.65 * min(1.0, it / 50))

    res = levenberg_marquardt(model, init.poses, sub, SolveSettings(s.max_iterations, s.ftol), on_iteration)
    settings = dataclasses.asdict(s)
    settings.update(res.model.settings_json())
    settings["knot_breaks_u"] = bu.tolist()
    settings["knot_breaks_v"] = bv.tolist()
    return Fit(res, ~ok, f"more than {PINHOLE_MAX_ANGLE_DEG:.0f}° off axis (outside the pinhole base)", settings, diagnostics)
