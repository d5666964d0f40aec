"""The paper's method (Wang et al. 2026), method.md §"Pipeline", with an
optional parametric core under the field (``core``):

initialise → observed distortion at the field's sample positions → adaptive
knots → control points by regularised least squares → joint
Levenberg–Marquardt over intrinsics (or the core), every pose and every
control point.

``core="none"`` is the paper's model: the field moves ideal pixels of the base
projection. With ``core="rational"`` or ``"fisheye"`` the field moves the
pixels of a jointly fitted OpenCV-rational or Kannala–Brandt camera and is
regularised towards zero (``models/hybrid.py``). Which of these, or a
parametric model alone, a lens wants is ``method="auto"``'s choice
(``auto.py``).

With ``intervals="auto"`` and ``lambda_smooth="auto"`` (the defaults) a first
joint fit on a middle-sized grid takes out the initial camera's errors; then
the knot count and the smoothing weight (and, with
``bandwidth_factor="auto"``, the KDE bandwidth) are chosen by how well the
control points predict views left out of their fit (``smoothing.py``), within
``time_budget`` seconds if one is set, and the joint fit is run again on that
grid.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import ranges
from ..errors import DataError, SettingsError
from ..fit_report import Restart, RestartFit
from ..fitting import knots, metrics
from ..fitting.crossval import linearised_view_errors
from ..fitting.gram import gram
from ..fitting.init import initialise
from ..fitting.knots import KnotSettings
from ..fitting.metrics import design_diagnostics
from ..fitting.smoothing import LAMBDA_GRID, CVCurve, cv_curve, groups_of
from ..fitting.solve import Data, SolveSettings, levenberg_marquardt, residuals
from ..models import camera
from ..models.base import CameraModel
from ..models.bspline import GAUGE_WEIGHT, BSplineModel, gauge_rows
from ..models.bspline_basis import BSplineField, clamped_knots
from ..models.hybrid import HybridModel
from ..models.unproject import frame_border
from .common import Fit, Progress
from .fisheye import FisheyeSettings, fit_fisheye
from .opencv import OpenCVSettings, RationalSettings, fit_opencv

PINHOLE_MAX_ANGLE_DEG = camera.PINHOLE_MAX_ANGLE_DEG
DOMAIN_MARGIN = 0.02  # of the domain's span, on every side
# A field fit whose focal length is this far (relative) from a parametric
# camera's on the same corners, or whose rmse is this many times that
# camera's, has walked to a wrong camera (``wrong_camera``).
WRONG_FOCAL = 0.1
WORSE_FIT = 1.2
AUTO = "auto"
# How far (relative RMS) the initial camera's radial profile may lie from every pinhole
# camera's before the paper's model leaves the pinhole base ("auto": ``base_for``). Measured
# on 35 sets (docs/method.md, "Base projection"): the fisheyes lay 0.086-0.65 from it, and
# the base they lie nearest served each better (0.36x the pinhole's hold-out error down to
# 1e-13x); lenses within 0.033 of it were served better by another base on some seeds (by up
# to 2.9x) and far worse on others (3.9x), so they keep the paper's base.
PINHOLE_MISFIT = 0.05
AUTO_INTERVALS = (6, 8, 10, 12, 15)
STALE_GRIDS = 2
GRID_FIT_ITERATIONS = 100  # of a grid's joint fit while grids are scored (fit_field)
# Scott × factor candidates (method.md §"Adaptive knots"), the paper's 1.0 first:
# with a time budget the search covers every grid at 1.0 before the others.
AUTO_BANDWIDTH_FACTORS = (1.0, 1.2, 0.8, 1.5)
CORES = ("none", "zhang", "rational", "fisheye")
MAX_LAMBDA = 1e6  # regularisation weights: far past this the field is flat whatever the data


@dataclass
class BSplineSettings:
    core: str = "none"  # "none" (the paper's model) | "zhang" (OpenCV's 5 coefficients) | "rational" | "fisheye"
    knots: str = "kde"  # "kde" | "kde-paper" (the paper's candidates only) | "uniform" | "explicit"
    interior_knots: tuple | None = None  # "explicit": ([u knots], [v knots]) in the field's pixels
    intervals: int | tuple[int, int] | str = AUTO  # per direction; "auto": chosen by validation over views
    bandwidth: str = "scott"
    bandwidth_factor: float | str = 1.0  # "auto": chosen from AUTO_BANDWIDTH_FACTORS by validation
    max_intervals: int = 15
    min_support: int | None = None
    window_ratio: float = 0.05
    weighting: str = "local_std"  # Table 12: local_std | uniform | magnitude | gradient
    lambda_reg: float = 1e-6
    lambda_smooth: float | str = AUTO  # "auto": chosen by validation over views
    time_budget: float | None = None  # seconds for the search over knot grids and bandwidths; None: no limit
    base: str = AUTO  # the paper's model's base projection; "auto": ``base_for`` its initial camera
    max_iterations: int = 500
    ftol: float = 1e-6

    def validate(self) -> None:
        if self.core not in CORES:
            raise SettingsError(f"core: expected one of {CORES}, got {self.core!r}")
        ranges.number("lambda_reg", self.lambda_reg, 0, MAX_LAMBDA)
        if self.lambda_smooth != AUTO:
            ranges.number("lambda_smooth", self.lambda_smooth, 0, MAX_LAMBDA, alternative="'auto'")
        if self.bandwidth_factor != AUTO:
            ranges.number("bandwidth_factor", self.bandwidth_factor, 0, knots.MAX_BANDWIDTH_FACTOR, above_low=True,
                          alternative="'auto'")
        if self.time_budget is not None:
            ranges.number("time_budget (seconds)", self.time_budget, 0, 86_400, above_low=True,
                          alternative="null (no limit)")
        if self.base != AUTO and self.base not in camera.BASES:
            raise SettingsError(f"base: expected {AUTO} or one of {camera.BASES}, got {self.base!r}")
        if self.core != "none" and self.base not in (AUTO, "pinhole"):
            raise SettingsError("a parametric core brings its own projection: use --base only with --core none")
        if self.weighting not in knots.WEIGHTINGS:
            raise SettingsError(f"weighting: expected one of {knots.WEIGHTINGS}, got {self.weighting!r}")
        ranges.iterations_and_tolerance(self.max_iterations, self.ftol)
        if isinstance(self.intervals, int):
            self.intervals = (self.intervals, self.intervals)
        elif self.intervals != AUTO:
            try:
                if len(self.intervals) != 2:
                    raise IndexError
                self.intervals = (int(self.intervals[0]), int(self.intervals[1]))
            except (TypeError, ValueError, IndexError):
                raise SettingsError(f"intervals must be 'auto', N or (N, M), each from 1 to {knots.MAX_INTERVALS}, "
                                    f"got {self.intervals!r}") from None
        self.knot_settings(self.fixed_intervals() or (10, 10)).validate()

    # ---- the settings a fit uses, "auto" resolved to None -------------------------
    def fixed_intervals(self) -> tuple[int, int] | None:
        """The knot intervals (u, v) given, or None when validation chooses them."""
        if isinstance(self.intervals, str):
            return None
        if isinstance(self.intervals, int):
            return (self.intervals, self.intervals)
        return (self.intervals[0], self.intervals[1])

    def fixed_bandwidth_factor(self) -> float | None:
        """The bandwidth factor given, or None when validation chooses it."""
        return None if isinstance(self.bandwidth_factor, str) else self.bandwidth_factor

    def fixed_lambda_smooth(self) -> float | None:
        """The smoothing weight given, or None when validation chooses it."""
        return None if isinstance(self.lambda_smooth, str) else float(self.lambda_smooth)

    def knot_settings(self, intervals: tuple[int, int], bandwidth_factor: float | None = None) -> KnotSettings:
        """The knot placement's settings; ``bandwidth_factor`` overrides the
        setting (with "auto" and no override: the first candidate)."""
        if bandwidth_factor is None:
            fixed = self.fixed_bandwidth_factor()
            bandwidth_factor = AUTO_BANDWIDTH_FACTORS[0] if fixed is None else fixed
        return KnotSettings(
            strategy=self.knots, bandwidth=self.bandwidth, bandwidth_factor=bandwidth_factor,
            window_ratio=self.window_ratio, max_intervals=self.max_intervals, min_support=self.min_support,
            intervals=intervals, interior=self.interior_knots,
        )


@dataclass
class FieldProblem:
    """What the field is fitted to: where it is evaluated and how to build it.

    ``samples(model, poses, data)`` gives the field's evaluation points (N, 2),
    the offsets (N, 2) it must add there and the view (N,) of each; ``make(field, λ_smooth, start)``
    builds the camera model around a field, from a model whose non-field part
    it keeps."""

    domain: tuple[float, float, float, float]
    footprint: np.ndarray  # (M, 2) the image border in the field's coordinates
    gauge_point: tuple[float, float]
    prior_control: Callable[[BSplineField], np.ndarray]  # (n_u, n_v, 2) control values the regulariser pulls towards
    samples: Callable[[CameraModel, np.ndarray, Data], tuple[np.ndarray, np.ndarray, np.ndarray]]
    make: Callable[[BSplineField, float, CameraModel], CameraModel]


# ---- the paper's model: a field on ideal pixels ----------------------------------
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


def ideal_footprint(init_model, intrinsics: np.ndarray, base: str, image_size) -> np.ndarray:
    """The image border (M, 2) in ideal pixels, where the initial camera puts it
    (rays past the pinhole's reach clipped to it)."""
    rays = init_model.rays(frame_border(image_size))
    rays = rays[np.all(np.isfinite(rays), axis=1)]
    if base == "pinhole":
        theta = np.minimum(np.arccos(np.clip(rays[:, 2], -1, 1)), np.radians(PINHOLE_MAX_ANGLE_DEG))
        direction = rays[:, :2] / np.maximum(np.linalg.norm(rays[:, :2], axis=1), 1e-12)[:, None]
        xn = np.tan(theta)[:, None] * direction
    else:
        xn = camera.normalise(rays, base)
    fx, fy, cx, cy, s = intrinsics
    return np.column_stack([fx * xn[:, 0] + s * xn[:, 1] + cx, fy * xn[:, 1] + cy])


def _padded_box(pts: np.ndarray):
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = DOMAIN_MARGIN * (hi - lo)
    return (lo[0] - pad[0], hi[0] + pad[0], lo[1] - pad[1], hi[1] + pad[1])


def prior_field(init_model, intrinsics: np.ndarray, field: BSplineField, base: str) -> np.ndarray:
    """Control values (n_u, n_v, 2) of the initial camera's distortion field:
    a least-squares fit of (its pixel − ideal pixel) over the knot domain."""
    u0, u1, v0, v1 = field.domain
    grid = np.stack(np.meshgrid(np.linspace(u0, u1, 4 * field.n_u), np.linspace(v0, v1, 4 * field.n_v),
                                indexing="ij"), -1).reshape(-1, 2)
    fx, fy, cx, cy, s = intrinsics
    y = (grid[:, 1] - cy) / fy
    rays = camera.ray_of(np.column_stack([(grid[:, 0] - cx - s * y) / fx, y]), base)
    offset = init_model.project(rays) - grid
    # Past the angle where the initial camera's radius stops growing, its polynomial folds back and
    # projects anywhere (a fisheye seen within 60°: 31 000 px at the domain's corners, which bent the
    # whole field): the field there is left to the smoothness term.
    ok = np.all(np.isfinite(offset), axis=1) & (camera.off_axis(rays) < unfolded_reach(init_model))
    b = field.design(grid[ok]).matrix(field.n_controls)
    d2 = field.bending()
    a = (b.T @ b + 1e-6 * (d2.T @ d2) + 1e-9 * sp.identity(field.n_controls)).toarray()
    return np.linalg.solve(a, b.T @ offset[ok]).reshape(field.n_u, field.n_v, 2)


def unfolded_reach(model) -> float:
    """The angle off axis (rad) up to which ``model``'s radius grows (π at most)."""
    theta = np.linspace(1e-3, np.pi, 2000)
    _, slope = model.radial_profile(theta)
    fold = np.flatnonzero(slope <= 0)
    return float(theta[fold[0]]) if len(fold) else float(np.pi)


def base_for(init, data: Data) -> tuple[str, dict[str, float]]:
    """The paper's model's base projection for these corners ("auto"), and the
    initial camera's misfit to each base (``_profile_misfit``): the pinhole
    (the paper's), unless the initial camera's radial profile over the
    corners' angles lies more than PINHOLE_MISFIT from any pinhole camera's and
    nearer another base's. The field then carries what the base misses: on a
    fisheye, a pinhole base stretches the periphery towards infinity (tan θ)
    and its field, compressing it back, walks off."""
    pc = camera.transform(init.poses, data.view_index, data.object_points)
    theta = camera.off_axis(pc)
    radius, _ = init.model.radial_profile(theta)
    ideal = {"pinhole": np.tan(np.minimum(theta, np.radians(PINHOLE_MAX_ANGLE_DEG))),
             "stereographic": 2 * np.tan(theta / 2), "equidistant": theta}
    misfit = {base: _profile_misfit(radius, g) for base, g in ideal.items()}
    nearest = min(misfit, key=lambda base: misfit[base])
    return (nearest if misfit["pinhole"] > PINHOLE_MISFIT else "pinhole"), misfit


def _profile_misfit(radius: np.ndarray, ideal: np.ndarray) -> float:
    """RMS of ``radius`` − f·``ideal`` over RMS of ``radius``, at the best f:
    how far a radial profile lies from every camera of a base."""
    f = float(radius @ ideal / max(float(ideal @ ideal), 1e-300))
    return float(np.sqrt(np.mean((radius - f * ideal) ** 2) / max(float(np.mean(radius**2)), 1e-300)))


def ideal_field_problem(init, data: Data, image_size, s: BSplineSettings):
    intrinsics = np.array([*init.model.intrinsics[:4], 0.0])
    unit = clamped_knots(np.array([0.0, 1.0]))  # a one-cell field: the probe only needs the base projection
    probe = BSplineModel(intrinsics, BSplineField.zeros(unit, unit), s.base)
    ideal, ok = ideal_samples(probe, init.poses, data, s.base)
    if ok.sum() < 0.5 * len(ok):
        raise DataError(
            f"most corners lie more than {PINHOLE_MAX_ANGLE_DEG:.0f}° off axis, where a pinhole base cannot "
            "represent them: use --base equidistant or stereographic, or --core fisheye"
        )

    def samples(model, poses, sub):
        pts, seen = ideal_samples(model, poses, sub, s.base)
        return pts[seen], sub.image_points[seen] - pts[seen], sub.view_index[seen]

    def make(field, lambda_smooth, start):
        k = start.intrinsics
        return BSplineModel(k, field, s.base, s.lambda_reg, lambda_smooth, gauge_point,
                            prior_field(init.model, k, field, s.base))

    gauge_point = (float(intrinsics[2]), float(intrinsics[3]))
    footprint = ideal_footprint(init.model, intrinsics, s.base, image_size)
    priors: dict[tuple[bytes, bytes], np.ndarray] = {}  # by knots: each grid's is asked for by every step on it

    def prior_control(field):
        key = (field.knots_u.tobytes(), field.knots_v.tobytes())
        if key not in priors:
            priors[key] = prior_field(init.model, intrinsics, field, s.base)
        return priors[key]

    problem = FieldProblem(_padded_box(np.vstack([footprint, ideal[ok]])), footprint, gauge_point,
                           prior_control, samples, make)
    return problem, probe, init.poses, ok, f"more than {PINHOLE_MAX_ANGLE_DEG:.0f}° off axis (outside the pinhole base)"


# ---- a field over a parametric core -----------------------------------------------
def fit_core(data: Data, image_size, core: str, progress: Progress, five: Fit | None = None) -> Fit:
    """A parametric core ("zhang", "rational" or "fisheye") calibrated alone,
    as its own method does it, converged from several starts (``five``: the
    zhang fit, a start of the rational one). The field then starts from what
    the core truly misses."""
    if core == "fisheye":
        return fit_fisheye(data, image_size, FisheyeSettings(), progress)
    if core == "rational":
        return fit_opencv(data, image_size, RationalSettings(), progress, five)
    return fit_opencv(data, image_size, OpenCVSettings(), progress)


def core_field_problem(data: Data, image_size, s: BSplineSettings, core: str, progress: Progress,
                       core_fit: Fit | None = None):
    fit = core_fit or fit_core(data, image_size, core, progress)
    fitted, ok = fit.result.model, ~fit.excluded

    def samples(model, poses, sub):
        core_model = model.core if isinstance(model, HybridModel) else model
        pc = camera.transform(poses, sub.view_index, sub.object_points)
        pts = core_model.project(pc)
        return pts, sub.image_points - pts, sub.view_index

    def make(field, lambda_smooth, start):
        core_model = start.core if isinstance(start, HybridModel) else start
        return HybridModel(core_model, field, s.lambda_reg, lambda_smooth, gauge_point)

    gauge_point = (float(fitted.intrinsics[2]), float(fitted.intrinsics[3]))
    pc = camera.transform(fit.result.poses, data.view_index[ok], data.object_points[ok])
    domain = _padded_box(np.vstack([frame_border(image_size), fitted.project(pc)]))
    problem = FieldProblem(domain, frame_border(image_size), gauge_point, lambda field: np.zeros((field.n_u, field.n_v, 2)), samples, make)
    return problem, fitted, fit.result.poses, ok, fit.excluded_reason


# ---- shared steps ---------------------------------------------------------------------
def solve_control_points(field: BSplineField, problem: FieldProblem, lambda_reg: float, lambda_smooth: float,
                         samples: np.ndarray, response: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(Bᵀ W B + λ1 I + λ2 DᵀD + gauge) P = Bᵀ W d + (λ1 I + λ2 DᵀD) P₀, per component;
    returns (n_controls, 2). Weights are scaled to mean 1 so that λ keeps its meaning."""
    nc = field.n_controls
    b = field.design(samples).matrix(nc)
    d2 = field.bending()
    reg = lambda_reg * np.eye(nc) + lambda_smooth * (d2.T @ d2).toarray()
    gauge = (gauge_rows(field, problem.gauge_point) * GAUGE_WEIGHT).toarray()
    p0 = problem.prior_control(field).reshape(nc, 2)
    control = np.zeros((nc, 2))
    for c in range(2):
        w = weights[:, c] / weights[:, c].mean()
        g = gauge[c::2, c * nc : (c + 1) * nc]
        a = gram(b, w) + reg + g.T @ g  # BᵀWB by the compiled kernel from B's sparse rows
        a[np.diag_indices(nc)] += 1e-12
        control[:, c] = np.linalg.solve(a, b.T @ (w * response[:, c]) + reg @ p0[:, c])
    return control


def _fitted(problem: FieldProblem, breaks, lambda_reg, lambda_smooth, start, samples, response, weights):
    """A camera model on these knots, its control values fitted to the samples."""
    field = BSplineField.zeros(clamped_knots(breaks[0]), clamped_knots(breaks[1]))
    control = solve_control_points(field, problem, lambda_reg, lambda_smooth, samples, response, weights)
    return problem.make(field.with_control(control), lambda_smooth, start)


def field_cv(problem: FieldProblem, field: BSplineField, samples, response, weights, views, lambda_reg: float,
              lambdas: np.ndarray, refine: bool = False, start: float | None = None) -> CVCurve:
    """Grouped (by view) cross-validation of the control points on this
    field's knots (``smoothing.cv_curve``). What is smoothed is the departure
    from the prior field: that is what is cross-validated."""
    b = field.design(samples).matrix(field.n_controls)
    p0 = problem.prior_control(field).reshape(-1, 2)
    return cv_curve(b, weights / weights.mean(axis=0), field.bending(),
                    gauge_rows(field, problem.gauge_point) * GAUGE_WEIGHT, response - b @ p0,
                    lambda_reg, groups_of(views), lambdas, refine, start)


def _choose_smoothing(problem: FieldProblem, samples, response, weights, views, s: BSplineSettings,
                      joint=None):
    """(intervals, bandwidth factor, λ_smooth, breaks, curve): what is left
    "auto", chosen by how well the field predicts views left out of its fit,
    within ``s.time_budget`` seconds. Each grid takes the λ whose control
    points predict left-out views best at the current camera and poses
    (``field_cv``, closed form). Grids are compared by ``joint(breaks, λ)``
    when given: the views' errors left out of the joint fit of camera, poses
    and field (``crossval.linearised_view_errors``), where the camera and
    the other views take up what a coarse field leaves (at a held camera a
    6 × 6 grid predicted left-out views 2× worse than 15 × 15 and the
    hold-out 1.7× better, decentred lens; a grid ``joint`` cannot score
    enters the curve as skipped, with its reason). Of the grids, the one that
    predicts best (``_best_grid``).
    Candidates run cheapest (fewest intervals) and most likely (the paper's
    bandwidth) first; the first always runs. Finer grids stop once
    STALE_GRIDS in a row have not predicted better than the best so far,
    and those the time budget leaves out
    stop too; both enter the curve as skipped."""
    fixed_intervals, fixed_factor, fixed_lambda = s.fixed_intervals(), s.fixed_bandwidth_factor(), s.fixed_lambda_smooth()
    counts = [(m, m) for m in AUTO_INTERVALS if m <= s.max_intervals] if fixed_intervals is None else [fixed_intervals]
    factors = list(AUTO_BANDWIDTH_FACTORS) if fixed_factor is None else [fixed_factor]
    lambdas = LAMBDA_GRID if fixed_lambda is None else np.array([fixed_lambda])
    started = time.perf_counter()
    curve: list[dict[str, Any]] = []
    # (total intervals, intervals, bandwidth factor, λ, per-unit SSE, units, breaks) of each grid scored
    options: list[tuple[int, tuple[int, int], float, float, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]] = []
    scored: dict[tuple[bytes, bytes], tuple[CVCurve, float, np.ndarray | None, np.ndarray, str]] = {}
    jointly = joint is not None and len(counts) * len(factors) > 1  # grids to compare
    previous = None  # the λ of the grid scored last: where the next grid's search starts
    for factor in factors:
        stale = 0  # finer grids in a row that predicted no better than the best so far
        for m in counts:
            skip = ("time budget" if options and s.time_budget is not None
                    and time.perf_counter() - started > s.time_budget else
                    f"{STALE_GRIDS} coarser grids predicted no better" if stale >= STALE_GRIDS else "")
            if skip:
                curve.append({"intervals": list(m), "bandwidth_factor": factor, "skipped": skip})
                continue
            breaks = knots.breaks_for(samples, weights, problem.domain, s.knot_settings(m, factor), problem.footprint)
            key = (breaks[0].tobytes(), breaks[1].tobytes())
            if key not in scored:  # factors that move no knot (e.g. uniform knots) cost nothing more
                field = BSplineField.zeros(clamped_knots(breaks[0]), clamped_knots(breaks[1]))
                cv = field_cv(problem, field, samples, response, weights, views, s.lambda_reg, lambdas, refine=True,
                               start=previous)
                lam = previous = float(cv.lambdas[cv.best])
                if jointly:  # per view
                    sse, units, unscored = joint(breaks, lam)
                else:  # per group of the control points' validation
                    sse, units, unscored = cv.group_sse[:, cv.best], cv.counts, ""
                scored[key] = (cv, lam, sse, units, unscored)
            cv, lam, sse, units, unscored = scored[key]
            intervals = [len(breaks[0]) - 1, len(breaks[1]) - 1]
            if sse is None:
                curve.append({"intervals": intervals, "bandwidth_factor": factor, "skipped": unscored})
                continue
            curve.append({"intervals": intervals, "bandwidth_factor": factor, "lambda_smooth": lam,
                          "cv": float(cv.score[cv.best]), "validation": float(sse.sum() / units.sum()),
                          "dof": float(cv.dof[cv.best])})
            options.append((sum(intervals), m, factor, lam, sse, units, breaks))
            # a finer grid earns its keep when it predicts better than every coarser one
            stale = 0 if _best_grid(options) == len(options) - 1 else stale + 1
    if not options:  # no grid the corners can carry: the coarsest, for the fit's own error to say so
        m = counts[0]
        breaks = knots.breaks_for(samples, weights, problem.domain, s.knot_settings(m, factors[0]), problem.footprint)
        return m, factors[0], 1.0, breaks, curve
    _, m, factor, lam, _, _, breaks = options[_best_grid(options)]
    return m, factor, lam, breaks, curve


def _best_grid(options) -> int:
    """The grid whose fits predict the views left out of them best. Not the
    one-standard-error rule's coarsest within the noise: each grid's λ,
    chosen by the same prediction, already prices its flexibility (a fine
    grid smoothed hard is a smooth field), and preferring coarse grids on top
    of it kept fields too stiff for a freeform lens's image corners."""
    return int(np.argmin([o[4].sum() for o in options]))

def wrong_camera(res, reference, data: Data) -> str:
    """Why the field's fit is not to be trusted, or "": it ends far from a
    parametric camera (``reference``: model, poses) fitted to the same
    corners. The field can mimic a change of focal length away from the
    gauge point, so a lens its grid cannot follow (a fisheye on a pinhole
    base, a coarse grid) may walk the camera to a wrong focal length and
    throw corners out as outliers; a field is more flexible than the
    parametric camera and must fit at least about as well."""
    ref_model, ref_poses = reference
    focal = res.model.intrinsics[:2] / ref_model.intrinsics[:2] - 1
    ref_rmse = metrics.rmse(residuals(ref_model, ref_poses, data))
    fit_rmse = metrics.rmse(res.residuals)
    why = []
    if np.max(np.abs(focal)) > WRONG_FOCAL:
        why.append(f"its focal length (fx {res.model.intrinsics[0]:.1f}, fy {res.model.intrinsics[1]:.1f}) is "
                   f"{100 * np.max(np.abs(focal)):.0f} % from the parametric camera's "
                   f"(fx {ref_model.intrinsics[0]:.1f}, fy {ref_model.intrinsics[1]:.1f})")
    if fit_rmse > WORSE_FIT * ref_rmse + 0.01:
        why.append(f"it fits the corners at {fit_rmse:.3f} px where the parametric camera reaches {ref_rmse:.3f} px")
    return "; ".join(why)


def _restarted(res, start, reference, data: Data, final: SolveSettings, why: str):
    """The fit again from the parametric camera's intrinsics and poses,
    first with the intrinsics held (the field and poses settle on the right
    camera), then with everything free; the better of the two fits, and a
    record of both."""
    ref_model, ref_poses = reference
    free = start.free_mask()
    free = np.ones(start.n_params, dtype=bool) if free is None else free.copy()
    free[:4] = False  # fx, fy, cx, cy
    settled = levenberg_marquardt(start, ref_poses, data, dataclasses.replace(final, free_params=free))
    again = levenberg_marquardt(settled.model, settled.poses, data, final)

    def record(r) -> RestartFit:
        return RestartFit(metrics.rmse(r.residuals), float(r.model.intrinsics[0]), float(r.model.intrinsics[1]),
                          r.iterations)

    keep = again if again.cost < res.cost else res
    still = wrong_camera(keep, reference, data)
    warning = (f"the field cannot follow this lens on this grid and base ({still}): use method auto, "
               "--base equidistant for a wide lens, or more views") if still else ""
    return keep, Restart(why, record(res), record(again), "restarted" if keep is again else "first", warning)


def field_design(model: BSplineModel | HybridModel, poses: np.ndarray, data: Data, s: BSplineSettings) -> dict:
    """The design diagnostics of ``model``'s field where these corners meet it
    (``metrics.design_diagnostics``): at each corner's ideal pixel, or its
    pixel under a hybrid's core."""
    pc = camera.transform(poses, data.view_index, data.object_points)
    samples = model.core.project(pc) if isinstance(model, HybridModel) else model.ideal_pixel(
        camera.normalise(pc, model.base))
    weights = sample_weights(samples, data.image_points - samples, s)
    field = model.bspline_field
    reg_rows = sp.vstack([np.sqrt(model.lambda_reg) * sp.identity(field.n_controls),
                          np.sqrt(model.lambda_smooth) * field.bending()])
    breaks = model.knot_breaks()
    assert breaks is not None  # a field has knots
    return design_diagnostics(field.design(samples).matrix(field.n_controls), weights / weights.mean(axis=0),
                              reg_rows, breaks[0], breaks[1], samples)


def sample_weights(samples: np.ndarray, response: np.ndarray, s: BSplineSettings) -> np.ndarray:
    """(N, 2) per-axis sample weights (``s.weighting``; the paper's local std)."""
    ks = s.knot_settings((10, 10))
    return np.column_stack([knots.sample_weights(samples[:, a], response[:, a], s.weighting, ks) for a in range(2)])


def fit_bspline(data: Data, image_size, s: BSplineSettings, progress: Progress) -> Fit:
    """The method: one field fit with the core asked for."""
    return fit_field(data, image_size, s, s.core, progress)


def fit_field(data: Data, image_size, s: BSplineSettings, core: str, progress: Progress,
               core_fit: Fit | None = None) -> Fit:
    """One fit with this core ("none": the paper's model)."""
    progress("initialise", 0.0)
    asked_base, base_choice = s.base, None
    if core == "none":
        init = initialise(data, image_size)
        if s.base == AUTO:
            base, misfit = base_for(init, data)
            s = dataclasses.replace(s, base=base)
            base_choice = {"base": base, "misfit": misfit, "max_misfit": PINHOLE_MISFIT}
        problem, start, poses, ok, reason = ideal_field_problem(init, data, image_size, s)
        init_info = {"focal_source": init.focal_source, "model": "kannala-brandt (4)", "rmse": init.rmse}
    else:
        problem, start, poses, ok, reason = core_field_problem(data, image_size, s, core, progress, core_fit)
        init_info = {"model": f"{core} core, fitted alone first"}
    sub = data.points(ok)

    reference = (init.model, init.poses) if core == "none" else (start, poses)  # a parametric camera
    progress("knots", 0.1)
    samples, response, views = problem.samples(start, poses, sub)
    weights = sample_weights(samples, response, s)
    first_samples = (samples, response, weights)
    auto = AUTO in (s.intervals, s.bandwidth_factor, s.lambda_smooth)
    m = s.fixed_intervals() or (10, 10)
    lam = s.fixed_lambda_smooth()
    lam = 1.0 if lam is None else lam
    factor = s.knot_settings(m).bandwidth_factor
    breaks = knots.breaks_for(samples, weights, problem.domain, s.knot_settings(m), problem.footprint)
    progress("control points", 0.15)
    model = _fitted(problem, breaks, s.lambda_reg, lam, start, samples, response, weights)
    curve = []
    final = SolveSettings(s.max_iterations, s.ftol, gauss_newton_trials=True)
    # A grid's joint fit only scores it: on a few noisy views a field over a core can crawl its
    # principal point's flat valley for hundreds of iterations. The chosen grid's fit goes on.
    scoring = dataclasses.replace(final, max_iterations=min(final.max_iterations, GRID_FIT_ITERATIONS))
    joint_fits = {}  # (breaks, λ) → the joint fit made while choosing the grid
    if auto:
        # A first joint fit takes out the initial camera's errors, so that the
        # choice of knots and smoothing sees the lens alone. Plain damped steps
        # here: the smoothing chosen depends on where this loose fit stops,
        # and Gauss-Newton trials were measured to move that choice for the
        # worse (radial and fisheye hold-out up to +25 % on some seeds).
        progress("joint optimisation", 0.2)
        first = levenberg_marquardt(model, poses, sub, SolveSettings(min(s.max_iterations, 50), 1e-4))
        progress("knots", 0.45)
        samples, response, views = problem.samples(first.model, first.poses, sub)
        weights = sample_weights(samples, response, s)

        def joint(grid_breaks, grid_lam):
            """A grid's joint fit (kept for reuse), its views' errors left out of it and
            their corner counts; or None for the errors, and why the grid is not scored."""
            start_model = _fitted(problem, grid_breaks, s.lambda_reg, grid_lam, first.model, samples, response,
                                  weights)
            units = np.bincount(sub.view_index, minlength=sub.n_views)
            if 2 * ok.sum() <= start_model.n_params + 6 * data.n_views:
                return None, units, "more unknowns than the corners give equations"
            fitted = levenberg_marquardt(start_model, first.poses, sub, scoring)
            # Views are left out of a fit at its minimum. One stopped far from it, worse than the
            # parametric camera, predicts nothing, and its views left out would each be refitted
            # for hundreds of iterations (a fisheye on a pinhole base: 20 s of a 25 s calibration).
            wrong = wrong_camera(fitted, reference, sub) if fitted.status == "max_iterations" else ""
            if wrong:
                return None, units, f"its joint fit stopped after {fitted.iterations} iterations, unconverged: {wrong}"
            joint_fits[(grid_breaks[0].tobytes(), grid_breaks[1].tobytes(), grid_lam)] = fitted
            return linearised_view_errors(fitted.model, fitted.poses, sub).errors, units, ""

        m, factor, lam, breaks, curve = _choose_smoothing(problem, samples, response, weights, views, s, joint)
        progress("control points", 0.5)
        chosen = joint_fits.get((breaks[0].tobytes(), breaks[1].tobytes(), lam))  # fitted while choosing
        model = chosen.model if chosen is not None else _fitted(problem, breaks, s.lambda_reg, lam, first.model,
                                                                samples, response, weights)
        poses = first.poses

    n_params = model.n_params + 6 * data.n_views
    if 2 * ok.sum() <= n_params:
        raise DataError(
            f"{ok.sum()} corners give {2 * ok.sum()} equations for {n_params} unknowns: add views, "
            "or use fewer knot intervals (--intervals N)"
        )
    diagnostics = {
        "initialisation": init_info,
        "domain": list(problem.domain),
        "smoothing_curve": curve,
    }
    if base_choice is not None:  # the initial camera's radial profile against each base's (base_for)
        diagnostics["base_choice"] = base_choice

    progress("joint optimisation", 0.55)

    def on_iteration(it: int, cost: float) -> None:
        progress("joint optimisation", 0.55 + 0.4 * min(1.0, it / 30))

    res = joint_fits.get((breaks[0].tobytes(), breaks[1].tobytes(), lam))
    if res is None:
        res = levenberg_marquardt(model, poses, sub, final, on_iteration)
    elif res.status == "max_iterations" and final.max_iterations > res.iterations:
        rest = dataclasses.replace(final, max_iterations=final.max_iterations - res.iterations)
        done = res.iterations
        res = levenberg_marquardt(res.model, res.poses, sub, rest, on_iteration)
        res.iterations += done
    wrong = wrong_camera(res, reference, sub)
    restart_record = None
    if wrong:
        progress("restart", 0.9)
        restart = _fitted(problem, breaks, s.lambda_reg, lam, start, *first_samples)
        res, restart_record = _restarted(res, restart, reference, sub, final, wrong)
    diagnostics["design"] = field_design(res.model, res.poses, sub, s)
    settings = dataclasses.asdict(s)
    settings["base"], settings["base_used"] = asked_base, res.model.base
    settings.update(res.model.settings_json())
    settings["intervals_used"] = [len(breaks[0]) - 1, len(breaks[1]) - 1]
    settings["bandwidth_factor_used"] = factor
    settings["knot_breaks_u"] = breaks[0].tolist()
    settings["knot_breaks_v"] = breaks[1].tolist()
    settings["core_used"] = core
    return Fit(res, ~ok, reason, settings, diagnostics, solve_settings=final, restart=restart_record)
