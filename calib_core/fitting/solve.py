"""Joint sparse Levenberg–Marquardt over a camera model's parameters and every
board pose. Model-agnostic: it knows residual rows and their sparse Jacobian,
not lenses.

A model (see ``models/base.py``) projects camera-frame points and reports, per
residual row, which of its parameters it touches and how; it may add linear
prior rows (regularisers, gauge constraints). The solver adds the pose blocks
(left-perturbed SE(3), ``camera.py``), assembles the CSR Jacobian without a
Python loop over points, and solves the damped normal equations.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg
from numba import njit

from ..models import camera
from ..models.base import CameraModel
from .gram import gram

# The model a solve moves: its result holds the type it was started from.
ModelT = TypeVar("ModelT", bound=CameraModel)
# A result of a more specific model is a result of a camera model: results are read, not changed.
ModelT_co = TypeVar("ModelT_co", bound=CameraModel, covariant=True)


class Cancelled(Exception):
    """Raised by a progress callback to stop a running solve."""


@dataclass(eq=False)  # compared (and hashed) by identity: a Data is never modified
class Data:
    """The observations as flat arrays.

    object_points: (N, 3) board points; image_points: (N, 2) observed pixels;
    view_index: (N,) int, which pose sees each point; n_views: number of poses.
    """

    object_points: np.ndarray
    image_points: np.ndarray
    view_index: np.ndarray
    n_views: int

    @property
    def n_points(self) -> int:
        return len(self.image_points)

    def points(self, keep: np.ndarray) -> Data:
        """The points ``keep`` (bool mask or indices), every view kept (numbered as here)."""
        return Data(self.object_points[keep], self.image_points[keep], self.view_index[keep], self.n_views)


def select_views(data: Data, views: np.ndarray, points: np.ndarray | None = None) -> Data:
    """The ``points`` (bool mask; default all) of ``views``, renumbered 0..len(views)-1 in that order."""
    renumber = np.full(data.n_views, -1)
    renumber[views] = np.arange(len(views))
    keep = renumber[data.view_index] >= 0
    if points is not None:
        keep &= points
    return Data(data.object_points[keep], data.image_points[keep], renumber[data.view_index[keep]], len(views))


def spread_views(data: Data, max_views: int) -> Data:
    """At most ``max_views`` of the views, evenly spread over the set, renumbered."""
    spread = np.linspace(0, data.n_views - 1, min(max_views, data.n_views)).round().astype(int)
    return select_views(data, np.unique(spread))


@dataclass
class SolveResult(Generic[ModelT_co]):
    """Like ``scipy.optimize.least_squares``' result, for a model and poses."""

    model: ModelT_co
    poses: np.ndarray  # (V, 6)
    cost: float  # ½ Σ r², prior rows included
    residuals: np.ndarray  # (N, 2) projection minus observation, pixels
    iterations: int
    status: str  # "converged" | "max_iterations" | "stalled"
    message: str
    jac: sp.csr_matrix | None = None
    history: list[float] = field(default_factory=list)


@dataclass
class SolveSettings:
    max_iterations: int = 500
    ftol: float = 1e-6  # relative cost decrease that ends the solve (Table 2: 1e-6)
    xtol: float = 1e-8  # relative step size that ends the solve
    initial_damping: float = 1e-3
    fix_poses: bool = False  # refit the model only (poses held)
    fix_model: bool = False  # refit the poses only (hold-out evaluation)
    free_params: np.ndarray | None = None  # (n_params,) bool: model parameters to fit (None: the model's free_mask)
    gauss_newton_trials: bool = False  # try the undamped step first (see levenberg_marquardt)


# Up to this many unknowns the normal equations are dense (a Cholesky
# factorisation of 3000² takes ~0.3 s on one core); beyond, sparse.
DENSE_LIMIT = 3000

# Fewer pose columns than this (and than the model's) are factorised with
# the rest: eliminating them first costs more Python than it saves.
SCHUR_MIN_POSE_COLUMNS = 60

# Marquardt damping (relative to JᵀJ's diagonal) below which a damped step is a
# Gauss-Newton step for the convergence test.
NEGLIGIBLE_DAMPING = 1e-6
# A Gauss-Newton trial that raises the cost is retried at 1/2, 1/4, ... of its
# length this many times (measured: 100-view problem 22 -> 14 iterations with 3,
# 40 views 30 -> 10 with 1) before the damped step takes over.
GN_HALVINGS = 3
# The damping of a "Gauss-Newton" step: enough to keep JᵀJ positive definite
# when a parameter is (nearly) unseen.
UNDAMPED = 1e-12
# The finite-difference probe of a trial's geodesic acceleration, as a fraction
# of the step (Transtrum & Sethna's 0.1; 0.01 and 0.001 were measured to give
# the same iterations and minima).
GEODESIC_PROBE = 0.1
# The largest acceleration that is trusted, relative to the step (both in the
# metric of JᵀJ's diagonal): beyond it the second-order path is no model of the
# cost, and the trial goes straight. Transtrum & Sethna bound 2‖a‖/‖v‖ by 0.75;
# measured here: ‖a‖/‖v‖ ≤ 0.75 keeps every large-valley gain, and takes a
# 10-view rational-core fit to its lowest minimum (270.6) where no bound left
# it at 286.8.
MAX_ACCELERATION = 0.75
# The longest trial, as a multiple of the Gauss-Newton step, that the measured
# curvature along the last one may call for (see levenberg_marquardt). Below 2,
# where the quadratic model predicts no gain at all.
MAX_REACH = 1.75


def residuals(model: CameraModel, poses: np.ndarray, data: Data) -> np.ndarray:
    """Projection minus observation, (N, 2) pixels."""
    pc = camera.transform(poses, data.view_index, data.object_points)
    return model.project(pc) - data.image_points


def _assemble(model: CameraModel, poses: np.ndarray, data: Data, settings: SolveSettings):
    """Residual vector and CSR Jacobian over [free model params | poses]."""
    pc = camera.transform(poses, data.view_index, data.object_points)
    uv, d_pc, cols, vals = model.project(pc, jacobian=True)
    r = (uv - data.image_points).ravel()
    n_model = 0
    column = np.zeros(0, dtype=np.int64)
    if not settings.fix_model:
        column = model_columns(model.n_params, settings.free_params)
        n_model = int(column.max()) + 1 if len(column) else 0
    n_cols = n_model + (0 if settings.fix_poses else 6 * data.n_views)
    indptr, indices, values = _rows(np.ascontiguousarray(cols, dtype=np.int64), np.ascontiguousarray(vals, dtype=np.float64),
                                    column, np.ascontiguousarray(d_pc), pc, np.asarray(data.view_index, dtype=np.int64),
                                    n_model, not settings.fix_model, not settings.fix_poses)
    prior = None if settings.fix_model else model.prior()
    if prior is not None:
        # The prior rows (on model columns only) appended to the CSR arrays as
        # they are: no sparse stacking per iteration.
        pr, pj = prior
        pj = sp.csr_matrix(pj)
        p_ptr, p_idx, p_val = pj.indptr, pj.indices, pj.data
        if settings.free_params is not None:
            column = model_columns(model.n_params, settings.free_params)[p_idx]
            kept = column >= 0
            row = np.repeat(np.arange(len(p_ptr) - 1), np.diff(p_ptr))
            p_ptr = np.concatenate([[0], np.cumsum(np.bincount(row[kept], minlength=len(p_ptr) - 1))])
            p_idx, p_val = column[kept], p_val[kept]
        indptr = np.concatenate([indptr, p_ptr[1:] + indptr[-1]])
        indices, values = np.concatenate([indices, p_idx]), np.concatenate([values, p_val])
        r = np.concatenate([r, pr])
    jac = sp.csr_matrix((values, indices, indptr), shape=(len(indptr) - 1, n_cols))
    return r, jac


@njit(cache=True, nogil=True)
def _rows(cols, vals, column, d_pc, pc, view, n_model, with_model, with_poses):  # pragma: no cover (compiled)
    """CSR arrays (indptr, indices, data) of the points' Jacobian rows: each
    row's model entries (``cols``, ``vals``: (N, 2, w) from ``project``)
    mapped to their columns (``column``; held parameters, −1, left out), then
    its pose's six, ∂uv/∂Pc · ∂Pc/∂δ with ∂Pc/∂δ = [−[Pc]×  I₃]
    (``camera.d_transform``)."""
    n, _, w = cols.shape
    indptr = np.empty(2 * n + 1, dtype=np.int64)
    indptr[0] = 0
    for i in range(n):
        for r in range(2):
            count = 6 if with_poses else 0
            if with_model:
                for k in range(w):
                    if column[cols[i, r, k]] >= 0:
                        count += 1
            indptr[2 * i + r + 1] = indptr[2 * i + r] + count
    indices = np.empty(indptr[-1], dtype=np.int32)
    data = np.empty(indptr[-1])
    for i in range(n):
        x, y, z = pc[i, 0], pc[i, 1], pc[i, 2]
        for r in range(2):
            at = indptr[2 * i + r]
            if with_model:
                for k in range(w):
                    c = column[cols[i, r, k]]
                    if c >= 0:
                        indices[at] = c
                        data[at] = vals[i, r, k]
                        at += 1
            if with_poses:
                a0, a1, a2 = d_pc[i, r, 0], d_pc[i, r, 1], d_pc[i, r, 2]
                first = n_model + 6 * view[i]
                for k in range(6):
                    indices[at + k] = first + k
                data[at] = a1 * -z + a2 * y
                data[at + 1] = a0 * z + a2 * -x
                data[at + 2] = a0 * -y + a1 * x
                data[at + 3] = a0
                data[at + 4] = a1
                data[at + 5] = a2
    return indptr, indices, data


def drop_held(cols: np.ndarray, vals: np.ndarray):
    """Remove the entries of held parameters (column −1) from (N, 2, w)
    Jacobian rows: every entry costs in JᵀJ, and a hybrid model holds 16 of
    its 36 (its core's coefficients). When rows hold different numbers, the
    held entries become zero-valued padding on column 0 instead."""
    held = cols < 0
    if not held.any():
        return cols, vals
    kept = (~held).sum(axis=2)
    if np.all(kept == kept.flat[0]):
        n = len(cols)
        return cols[~held].reshape(n, 2, -1), vals[~held].reshape(n, 2, -1)
    return np.where(held, 0, cols), np.where(held, 0.0, vals)


def model_columns(n_params: int, free_params: np.ndarray | None) -> np.ndarray:
    """(n_params,) int: each model parameter's Jacobian column, −1 if held."""
    if free_params is None:
        return np.arange(n_params)
    free = np.asarray(free_params, dtype=bool)
    return np.where(free, np.cumsum(free) - 1, -1)


def _free_columns(settings: SolveSettings, n_views: int) -> np.ndarray:
    """Columns of the full [model | poses] state that are fitted."""
    keep = np.asarray(settings.free_params, dtype=bool)
    if not settings.fix_poses:
        keep = np.concatenate([keep, np.ones(6 * n_views, dtype=bool)])
    return np.flatnonzero(keep)


def _cost(model: CameraModel, poses: np.ndarray, data: Data, settings: SolveSettings) -> float:
    r = residuals(model, poses, data)
    total = float(np.sum(r * r))
    if not settings.fix_model:
        prior = model.prior()
        if prior is not None:
            total += float(np.sum(prior[0] ** 2))
    return 0.5 * total if np.isfinite(total) else np.inf


def _apply(model: ModelT, poses: np.ndarray, delta: np.ndarray, settings: SolveSettings) -> tuple[ModelT, np.ndarray]:
    if settings.free_params is not None and not settings.fix_model:
        full = np.zeros(model.n_params + (0 if settings.fix_poses else poses.size))
        full[_free_columns(settings, len(poses))] = delta
        delta = full
    n_model = 0 if settings.fix_model else model.n_params
    new_model = model if settings.fix_model else model.with_params(model.params() + delta[:n_model])
    new_poses = poses if settings.fix_poses else camera.retract_poses(poses, delta[n_model:].reshape(-1, 6))
    return new_model, new_poses


def _normal_equations(jac: sp.csr_matrix, r: np.ndarray):
    """(JᵀJ, Jᵀr): JᵀJ dense up to DENSE_LIMIT unknowns (formed by the
    compiled kernel, factorised densely), sparse beyond."""
    jtj = gram(jac) if jac.shape[1] <= DENSE_LIMIT else (jac.T @ jac).tocsr()
    return jtj, jac.T @ r


def _damping(jtj, mu: float) -> np.ndarray:
    """Marquardt's damping: μ times JᵀJ's diagonal, floored so that a
    parameter no row sees still gets a finite step."""
    diag = jtj.diagonal()
    return mu * np.maximum(diag, 1e-12 * max(diag.max(), 1.0))


def _predicted_decrease(jtj, g: np.ndarray, step: np.ndarray, mu: float) -> float:
    """The cost decrease the damped linear model predicts for ``step``."""
    return 0.5 * float(step @ (_damping(jtj, mu) * step - g))


def _solve_damped(jtj, g: np.ndarray, mu: float, n_model: int) -> np.ndarray:
    return _factorise(jtj, mu, n_model)(-g)


def _factorise(jtj, mu: float, n_model: int) -> Callable[[np.ndarray], np.ndarray]:
    """b ↦ (JᵀJ + μ·damping)⁻¹ b, factorised once for several right-hand
    sides. ``n_model``: the columns before the poses' (all of them when the
    poses are held). Each corner's rows touch one view's pose, so the poses'
    block is 6 × 6 blocks on the diagonal: with more pose columns than model
    columns the poses are eliminated first (``_schur``)."""
    d = _damping(jtj, mu)
    if sp.issparse(jtj):
        return scipy.sparse.linalg.factorized((jtj + sp.diags(d)).tocsc())
    a = jtj.copy()
    a[np.diag_indices_from(a)] += d
    try:
        if len(a) - n_model > max(n_model, SCHUR_MIN_POSE_COLUMNS):
            return _schur(a, n_model)
        factor = scipy.linalg.cho_factor(a, check_finite=False)
    except np.linalg.LinAlgError:
        return lambda b: scipy.linalg.lstsq(a, b)[0]
    return lambda b: scipy.linalg.cho_solve(factor, b, check_finite=False)


def _schur(a: np.ndarray, m: int) -> Callable[[np.ndarray], np.ndarray]:
    """b ↦ a⁻¹ b for a = [[A, B], [Bᵀ, C]] with C (the poses') block
    diagonal in 6 × 6 blocks C_v = L_v L_vᵀ, through the Schur complement
    S = A − B C⁻¹ Bᵀ = A − E Eᵀ, E = B L⁻ᵀ: (m + 6V)³/3 operations become
    m²·6V/2 + m³/3 (a 100-view field: 3x fewer, an OpenCV model: 100x).
    Raises LinAlgError if a is not positive definite."""
    views = (len(a) - m) // 6
    c = a[m:, m:].reshape(views, 6, views, 6)[np.arange(views), :, np.arange(views), :]  # (V, 6, 6)
    l_inv = np.linalg.inv(np.linalg.cholesky(c))
    b = a[:m, m:]
    e = (b.reshape(m, views, 6).transpose(1, 0, 2) @ l_inv.transpose(0, 2, 1)).transpose(1, 0, 2).reshape(m, 6 * views)
    factor = scipy.linalg.cho_factor(a[:m, :m] - e @ e.T, check_finite=False) if m else None

    def solve(rhs: np.ndarray) -> np.ndarray:
        top, poses = rhs[:m], rhs[m:]
        whitened = (l_inv @ poses.reshape(views, 6, 1)).ravel()  # L⁻¹ of each view's part
        x = scipy.linalg.cho_solve(factor, top - e @ whitened, check_finite=False) if m else top
        rest = l_inv @ (poses - b.T @ x).reshape(views, 6, 1)
        return np.concatenate([x, (l_inv.transpose(0, 2, 1) @ rest).ravel()])

    return solve


def _acceleration(model: CameraModel, poses: np.ndarray, data: Data, settings: SolveSettings, r: np.ndarray, jac: sp.csr_matrix, jtj,
                  v: np.ndarray, solve: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The geodesic acceleration a of the Gauss-Newton step v (Transtrum &
    Sethna 2012): a = −(JᵀJ)⁻¹ Jᵀ r_vv, with r_vv the residuals' second
    derivative along v, by a finite difference (one residual evaluation; the
    prior rows are linear, their r_vv is zero). The path t·v + ½t²·a then
    follows a curved valley's floor to second order where the straight step
    leaves it. Zero where the probe projects to non-finite pixels, and where
    a is larger than MAX_ACCELERATION of v."""
    m_h, p_h = _apply(model, poses, GEODESIC_PROBE * v, settings)
    r_h = residuals(m_h, p_h, data).ravel()
    n = r_h.size
    r_vv = (2.0 / GEODESIC_PROBE) * ((r_h - r[:n]) / GEODESIC_PROBE - (jac @ v)[:n])
    if not np.all(np.isfinite(r_vv)):
        return np.zeros_like(v)
    a = solve(-(jac.T @ np.concatenate([r_vv, np.zeros(len(r) - n)])))
    metric = np.sqrt(np.maximum(jtj.diagonal(), 0.0))
    if not np.linalg.norm(metric * a) <= MAX_ACCELERATION * np.linalg.norm(metric * v):
        return np.zeros_like(v)
    return a


def levenberg_marquardt(
    model: ModelT,
    poses: np.ndarray,
    data: Data,
    settings: SolveSettings | None = None,
    callback: Callable[[int, float], None] | None = None,
) -> SolveResult[ModelT]:
    """Minimise ½ Σ‖π(model, pose_k, P_j) − p_kj‖² + ½‖prior‖² over model and poses.

    ``callback(iteration, cost)`` is called after every accepted step; it may
    raise ``Cancelled``.

    With ``gauss_newton_trials`` the undamped step (already solved at each new
    point for the convergence test) is tried before the damped one. A field
    with a parametric intrinsic part has directions the corners hardly see and
    only the regularisers hold (a common tilt of the poses against the field's
    projective part): JᵀJ is so ill-conditioned along them that any damping
    that matters elsewhere stalls there, and damped steps alone crawl down
    that valley (paper-size problem: 40 iterations, 10 with trials). The
    regularisers' weight does not grow with the corners while JᵀJ's diagonal
    does, so the damping that stalls there grows with the data set (and a
    damping "negligible" by the diagonal is not negligible along the valley:
    with trials the convergence test is always the undamped step's).

    The valley is curved: the straight Gauss-Newton step runs up its wall
    (measured at 160 views: the quadratic model predicts a gain of 0.8, the
    step loses 83) and halving alone crawled (37 iterations). A trial therefore
    follows the path t·v + ½t²·a with a, the geodesic acceleration, bending it
    along the floor (``_acceleration``; straight where a is no small
    correction). Its length t starts where the last
    trial's measured gain ratio ρ at length s puts the minimum of a quadratic
    along the path, s / (2 − ρ(2 − s)) (a gain above 1 says the Gauss-Newton
    model overestimates the curvature there; at most MAX_REACH). A trial that
    raises the cost is halved, up to GN_HALVINGS times; where it keeps
    failing, as in the rational model's curved valley, trials back off
    exponentially. Parametric fits leave them off, which keeps their
    multi-start races on the minima they were measured with.
    """
    settings = settings or SolveSettings()
    if settings.free_params is None:
        settings = dataclasses.replace(settings, free_params=model.free_mask())
    poses = np.asarray(poses, dtype=np.float64).copy()
    cost = _cost(model, poses, data, settings)
    if not np.isfinite(cost):
        raise FloatingPointError("the initial estimate projects points to non-finite pixels")
    mu, nu = settings.initial_damping, 2.0
    # the columns before the poses' (``_factorise``): all of them when the poses are held
    n_model = 0 if settings.fix_model else model.n_params if settings.free_params is None else int(
        np.sum(settings.free_params))
    history = [cost]
    status, message = "max_iterations", f"stopped after {settings.max_iterations} iterations"
    it = 0
    r, jac = _assemble(model, poses, data, settings)
    jtj, g = _normal_equations(jac, r)
    check_step = False  # is the next damped step also the convergence test?
    # The Gauss-Newton step, its acceleration and the length to try them at
    # before the next damped step; and how often that trial was halved.
    trial: tuple[np.ndarray, np.ndarray, float] | None = None
    halvings = 0
    reach = 1.0  # the length of the next trial, as a multiple of the Gauss-Newton step
    gn_skip, gn_backoff = 0, 1  # new points to pass before the next trial
    converged = "converged", f"a Gauss-Newton step would gain less than ftol={settings.ftol:g} of the cost"
    while it < settings.max_iterations:
        gauss_newton = trial is not None
        if trial is not None:
            (v, a, length), trial = trial, None
            step = length * v + 0.5 * length * length * a
            # The quadratic model's gain along the straight part, for any
            # length: the acceleration only corrects for the valley's curvature.
            predicted = -length * float(v @ g) - 0.5 * length * length * float(v @ (jtj @ v))
        else:
            step = _solve_damped(jtj, g, mu, n_model)
            if check_step and -0.5 * float(step @ g) <= settings.ftol * cost:
                status, message = converged
                break
            predicted = _predicted_decrease(jtj, g, step, mu)
        check_step = False
        it += 1
        new_model, new_poses = _apply(model, poses, step, settings)
        new_cost = _cost(new_model, new_poses, data, settings)
        gain = (cost - new_cost) / predicted if predicted > 0 and np.isfinite(new_cost) else -1.0
        if gain > 0:
            model, poses, cost = new_model, new_poses, new_cost
            history.append(cost)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            nu = 2.0
            if gauss_newton:
                gn_backoff = 1
                # Along the path, cost(t) ≈ c − (t − ½κt²)·vᵀJᵀJv where the
                # quadratic model has κ = 1: the gain ratio measures κ, whose
                # minimum 1/κ is where the next trial starts.
                curvature = 2.0 - gain * (2.0 - length)
                reach = MAX_REACH if curvature * MAX_REACH <= length else length / curvature
            if callback is not None:
                callback(it, cost)
            r, jac = _assemble(model, poses, data, settings)
            jtj, g = _normal_equations(jac, r)
            # Converged when even an undamped Gauss-Newton step would gain
            # less than ftol of the cost: a heavily damped step alone can be
            # small (and gain little) far from the minimum. Without trials,
            # once the damping is negligible the next step is that
            # Gauss-Newton step: it is tested at the top of the loop instead
            # of being solved twice. (With trials the valley's curvature lies
            # far below NEGLIGIBLE_DAMPING of the diagonal: a step damped that
            # little gained 3x less than the undamped one, and stopped the
            # 80-view solve early.)
            if mu <= NEGLIGIBLE_DAMPING and not settings.gauss_newton_trials:
                check_step = True
                continue
            solve_gn = _factorise(jtj, UNDAMPED, n_model)
            gn = solve_gn(-g)
            if -0.5 * float(gn @ g) <= settings.ftol * cost:
                status, message = converged
                break
            if settings.gauss_newton_trials:
                if gn_skip == 0:
                    trial, halvings = (gn, _acceleration(model, poses, data, settings, r, jac, jtj, gn, solve_gn), reach), 0
                gn_skip = max(gn_skip - 1, 0)
        elif gauss_newton and halvings < GN_HALVINGS:
            # Overshot a curved valley's floor: part of the way often gains.
            trial, halvings = (v, a, 0.5 * length), halvings + 1
        elif gauss_newton:
            # Too far for the local model: back to damped steps, and to
            # trials only after exponentially more new points.
            gn_skip, gn_backoff = gn_backoff, 2 * gn_backoff
        else:
            step_small = np.linalg.norm(step) <= settings.xtol * (np.linalg.norm(_state(model, poses, settings)) + settings.xtol)
            if step_small or mu > 1e12:
                status, message = "stalled", "no step decreases the cost any more (at a minimum to machine precision)"
                break
            mu *= nu
            nu *= 2.0
    res = residuals(model, poses, data)
    return SolveResult(model, poses, cost, res, it, status, message, jac, history)


def _state(model: CameraModel, poses: np.ndarray, settings: SolveSettings) -> np.ndarray:
    parts = []
    if not settings.fix_model:
        parts.append(model.params())
    if not settings.fix_poses:
        parts.append(poses.ravel())
    return np.concatenate(parts) if parts else np.zeros(0)


def residuals_and_jacobian(model: CameraModel, poses: np.ndarray, data: Data, settings: SolveSettings | None = None):
    """(r, J) at this model and poses: the residual vector (2 rows per point,
    x then y, then the model's prior rows) and its CSR Jacobian over
    [free model parameters | poses], as the solver sees them."""
    settings = settings or SolveSettings()
    if settings.free_params is None:
        settings = dataclasses.replace(settings, free_params=model.free_mask())
    return _assemble(model, poses, data, settings)
