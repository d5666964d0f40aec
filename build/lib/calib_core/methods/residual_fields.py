"""Baselines ``mls`` and ``tps``: a Zhang calibration, then a smooth field
fitted to its residuals at the parametric pixels (``models/mls.py``,
``models/tps.py``).

The paper's settings: MLS, a first-order local polynomial with Gaussian
weights, support radius R ∈ {5, 10, 15, 20} % of the image diagonal (σ = R/3,
samples beyond 3σ dropped); TPS, the r² ln r kernel with smoothing
λ ∈ {1e-6, 1e-5, 1e-4, 1e-3, 1e-2}. The value is chosen by k-fold
cross-validation over views (fit the field on the other views' residuals,
score it on the held views' residuals), never by training error: on the
training points a field can always reach zero.

Zhang's poses and coefficients are fitted on all views and held during the
search (the field is what is being validated).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .. import ranges
from ..errors import DataError
from ..fitting.solve import Data, ModelT, SolveResult, SolveSettings, levenberg_marquardt, residuals
from ..models import camera
from ..models.base import CameraModel
from ..models.mls import MLSField, MLSModel
from ..models.opencv import OpenCVModel
from ..models.residual_field import Field, ResidualFieldModel
from ..models.tps import TPSField, TPSModel, affine_basis, kernel_matrix
from .common import Fit, Progress
from .opencv import OpenCVSettings, fit_opencv

MAX_CENTERS = 2000   # a TPS system is max_centers² (2000: 32 MB, solved once per fold and grid value)
MAX_FOLDS = 20


@dataclass
class TPSSettings:
    smoothing: list[float] = field(default_factory=lambda: [1e-6, 1e-5, 1e-4, 1e-3, 1e-2])  # grid (or one value)
    max_centers: int = 600  # a reduced-rank TPS: centres are a spatially even subset of the corners
    folds: int = 5
    zhang_coefficients: int = 5
    max_iterations: int = 500
    ftol: float = 1e-12

    def validate(self) -> None:
        # each grid value is a cross-validated fit, and max_centers² the size of the TPS system
        self.smoothing = ranges.values("smoothing", self.smoothing, 0, 1e6, above_low=True)
        ranges.whole("max_centers", self.max_centers, 10, MAX_CENTERS)
        ranges.whole("folds", self.folds, 2, MAX_FOLDS)
        OpenCVSettings(self.zhang_coefficients, self.max_iterations, self.ftol).validate()


@dataclass
class MLSSettings:
    support: list[float] = field(default_factory=lambda: [0.05, 0.10, 0.15, 0.20])  # × image diagonal (grid)
    ridge: float = 1e-3
    folds: int = 5
    zhang_coefficients: int = 5
    max_iterations: int = 500
    ftol: float = 1e-12

    def validate(self) -> None:
        self.support = ranges.values("support (fractions of the image diagonal)", self.support, 0, 1, above_low=True)
        ranges.number("ridge", self.ridge, 0, 1e6, above_low=True)
        ranges.whole("folds", self.folds, 2, MAX_FOLDS)
        OpenCVSettings(self.zhang_coefficients, self.max_iterations, self.ftol).validate()


# ---- the fields, fitted in closed form -------------------------------------------
def even_subset(points: np.ndarray, m: int) -> np.ndarray:
    """Indices of at most ``m`` points (N, 2) spread evenly: one per occupied grid cell."""
    if len(points) <= m:
        return np.arange(len(points))
    lo, hi = points.min(axis=0), points.max(axis=0)
    for cells in range(int(np.sqrt(m)) + 1, 1, -1):
        ij = np.floor((points - lo) / np.maximum(hi - lo, 1e-9) * (cells - 1e-9)).astype(int)
        _, first = np.unique(ij[:, 0] * cells + ij[:, 1], return_index=True)
        if len(first) <= m:
            return np.sort(first)
    return np.arange(m)


def fit_tps_field(samples: np.ndarray, offsets: np.ndarray, scale: float, lambdas: list[float],
                  max_centers: int) -> list[TPSField]:
    """Smoothing TPS fields, one per λ, minimising
    (1/N) Σ‖d_i − f(s_i)‖² + λ wᵀ K w  subject to  Qcᵀ w = 0 (w ⟂ affine).

    samples, offsets: (N, 2) pixels. Centres: an even subset of the samples."""
    centers = samples[even_subset(samples, max_centers)]
    m = len(centers)
    phi = kernel_matrix(samples, centers, scale)  # (N, M)
    kcc = kernel_matrix(centers, centers, scale)  # (M, M)
    qc = affine_basis(centers, scale)
    z = np.linalg.qr(qc, mode="complete")[0][:, 3:]  # w = z v satisfies Qcᵀ w = 0
    x = np.hstack([phi @ z, affine_basis(samples, scale)])
    n = len(samples)
    xtx, xtd = x.T @ x / n, x.T @ offsets / n
    pen = np.zeros_like(xtx)
    pen[: m - 3, : m - 3] = z.T @ kcc @ z
    out = []
    for lam in lambdas:
        a = xtx + lam * pen
        theta = _solve_spd(a, xtd)
        out.append(TPSField(centers, z @ theta[: m - 3], theta[m - 3 :], scale, lam))
    return out


def fit_mls_fields(samples, offsets, diagonal: float, supports: list[float], ridge: float) -> list[MLSField]:
    return [MLSField(samples, offsets, sigma=f * diagonal / 3.0, support=f * diagonal, ridge=ridge) for f in supports]


def cross_validate(view_index: np.ndarray, n_views: int, folds: int, samples, offsets,
                   build: Callable[[np.ndarray, np.ndarray], Sequence[Field]]) -> np.ndarray:
    """Validation rmse (per point, pixels) of each candidate field, k-fold over views: (n_candidates,)."""
    k = min(folds, n_views)
    fold_of_view = np.arange(n_views) % k
    err, count = None, 0
    for f in range(k):
        held = fold_of_view[view_index] == f
        if held.all() or not held.any():
            continue
        fields = build(samples[~held], offsets[~held])
        e = np.array([np.sum((fl.evaluate(samples[held])[0] - offsets[held]) ** 2) for fl in fields])
        err = e if err is None else err + e
        count += held.sum()
    if err is None:
        raise DataError("cross-validation needs at least 2 views")
    return np.sqrt(err / count)


# ---- the methods --------------------------------------------------------------------
def _zhang(data: Data, image_size: tuple[int, int], s: TPSSettings | MLSSettings, progress: Progress) -> Fit[OpenCVModel]:
    return fit_opencv(data, image_size, OpenCVSettings(s.zhang_coefficients, s.max_iterations, s.ftol), progress)


def _fit_field(res: SolveResult[OpenCVModel], data: Data, image_size: tuple[int, int],
               s: TPSSettings | MLSSettings) -> tuple[ResidualFieldModel, float, list[dict[str, float]]]:
    """The residual field on top of the parametric ``res`` on ``data``; the model,
    the chosen smoothing (tps) or support (mls), and the cross-validation table."""
    core = res.model
    pc = camera.transform(res.poses, data.view_index, data.object_points)
    samples = core.project(pc)
    offsets = data.image_points - samples
    diagonal = float(np.hypot(*image_size))
    build: Callable[[np.ndarray, np.ndarray], Sequence[TPSField | MLSField]]
    if isinstance(s, TPSSettings):
        grid = list(s.smoothing)
        max_centers = s.max_centers

        def build(sm: np.ndarray, of: np.ndarray) -> list[TPSField]:
            return fit_tps_field(sm, of, diagonal, grid, max_centers)
    else:
        grid = list(s.support)
        ridge = s.ridge

        def build(sm: np.ndarray, of: np.ndarray) -> list[MLSField]:
            return fit_mls_fields(sm, of, diagonal, grid, ridge)
    scores = cross_validate(data.view_index, data.n_views, s.folds, samples, offsets, build) if len(grid) > 1 else np.zeros(1)
    best = int(np.argmin(scores))
    chosen = build(samples, offsets)[best] if len(grid) > 1 else build(samples, offsets)[0]
    model = TPSModel(core, chosen) if isinstance(chosen, TPSField) else MLSModel(core, chosen)
    table = [{"value": float(v), "cv_rmse": float(e)} for v, e in zip(grid, scores, strict=True)]
    return model, grid[best], table


def _fit_residual(kind: str, data: Data, image_size: tuple[int, int], s: TPSSettings | MLSSettings,
                  progress: Progress) -> Fit[ResidualFieldModel]:
    base = _zhang(data, image_size, s, progress)
    progress(f"{kind} field", 0.6)
    used = ~base.excluded
    sub = data.points(used)
    model, chosen, table = _fit_field(base.result, sub, image_size, s)
    res = _with_model(base.result, model, sub)
    key = "smoothing" if kind == "tps" else "support"
    settings = dataclasses.asdict(s)
    settings["chosen_" + key] = chosen
    diagnostics = dict(base.diagnostics)
    diagnostics["grid_search"] = {"parameter": key, "folds": s.folds, "by": "k-fold over views", "table": table}

    def refit(sub2: Data, current: SolveResult[ResidualFieldModel]) -> SolveResult[ResidualFieldModel]:
        # Outliers removed: refit Zhang on the rest, then the field with the value already chosen.
        core_res = levenberg_marquardt(current.model.parametric, current.poses, sub2, SolveSettings(s.max_iterations, s.ftol))
        one = (dataclasses.replace(s, smoothing=[chosen]) if isinstance(s, TPSSettings)
               else dataclasses.replace(s, support=[chosen]))
        m, _, _ = _fit_field(core_res, sub2, image_size, one)
        return _with_model(core_res, m, sub2)

    return Fit(res, base.excluded, base.excluded_reason, settings, diagnostics, refit)


def _with_model(res: SolveResult[CameraModel], model: ModelT, data: Data) -> SolveResult[ModelT]:
    r = residuals(model, res.poses, data)
    return SolveResult(model, res.poses, 0.5 * float(np.sum(r * r)), r, res.iterations, res.status, res.message)


def fit_tps(data: Data, image_size: tuple[int, int], s: TPSSettings, progress: Progress) -> Fit[ResidualFieldModel]:
    return _fit_residual("tps", data, image_size, s, progress)


def fit_mls(data: Data, image_size: tuple[int, int], s: MLSSettings, progress: Progress) -> Fit[ResidualFieldModel]:
    return _fit_residual("mls", data, image_size, s, progress)


def _solve_spd(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cholesky when positive definite (the usual case), least squares otherwise."""
    import scipy.linalg

    try:
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(a), b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, b, rcond=None)[0]
