"""Cross-validation over views: how well a fitted model predicts views it has not seen.

The same protocol as ``compare`` and ``evaluate``: the model is fitted
without the validated views, then held while only their poses are refit.
``folds`` splits the views; ``linearised_view_errors`` leaves each view out
of a fit in closed form, its structure (knots, smoothing, which parameters
are free) held, so that scoring a model costs about a solver iteration, not
a calibration per fold; ``refitted_view_errors`` refits the model without
each view instead, for a model the closed form flatters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.base import CameraModel, free_parameters
from .cholesky import cholesky_solve
from .gram import gram
from .solve import Data, SolveSettings, levenberg_marquardt, residuals, residuals_and_jacobian, select_views

# A view's closed form is trusted when the model moved by its step predicts
# the view (poses answering linearly) within this share of the linear
# prediction; beyond, the step has left the linear regime (a rational
# model's denominators near a pole) and the view is refitted exactly.
LINEAR_AGREEMENT = 0.2
# How a view's exact refit converges: a score needs the left-out error to a
# fraction of a percent, not the fit to the last digit (ftol 1e-10 cost up to
# 200 iterations a view on the rational model's flat valleys).
REFIT = SolveSettings(200, 1e-6, gauss_newton_trials=True)


def folds(n_views: int, splits: int) -> list[np.ndarray]:
    """View indices validated in each split: interleaved, each view exactly once."""
    return [np.arange(k, n_views, splits) for k in range(splits)]


@dataclass
class ViewErrors:
    """Leave-one-view-out in closed form: ``errors`` (n_views,) squared
    left-out residuals per view (px², both axes) and ``steps`` (n_views,
    n_free) the free model parameters' move when each view leaves."""

    errors: np.ndarray
    steps: np.ndarray
    refitted: int = 0  # views whose closed form left the linear regime, refitted exactly


def linearised_view_errors(model: CameraModel, poses: np.ndarray, data: Data, scored: np.ndarray | None = None,
                           held_steps: np.ndarray | None = None) -> ViewErrors:
    """Each view's squared residuals over its ``scored`` points (bool mask;
    default all) when it is left out of the fit, in closed form: one
    Gauss-Newton step from the full solution (``model``, ``poses``, at the
    minimum on ``data``) without the view, then the view predicted with only
    its own pose refit.

    With the poses eliminated (the Schur complement S of the normal
    equations over the model parameters), leaving view v out removes its
    share S_v, the model moves by Δ = (S − S_v)⁻¹ A_vᵀ r_v (A_v: the view's
    model columns; the other views' poses follow, their gradients being
    zero), and the view's residuals become r_v + A_v Δ less what its pose
    absorbs, the projection onto its pose columns B_v. One small solve per
    view: the cost of a solver iteration or two for the whole validation,
    where refits cost a few iterations per fold.

    ``held_steps`` (n_views, n_held): for a model whose held parameters
    (those outside ``free_mask``, e.g. a hybrid's core coefficients) were
    fitted to the same views in a first stage, their move δc when each view
    leaves that stage. The free parameters then also answer it,
    Δ = (S − S_v)⁻¹ (A_vᵀ r_v − (T − T_v) δc) with T the pose-reduced cross
    block of free and held columns, and the view's residuals gain C_v δc.
    Without it a two-stage model is scored with the left-out view still
    inside its first stage, which flatters it on small sets.

    Each view's step is checked: the model moved by it predicts the view
    again (its pose answering linearly). A view where that disagrees with
    the closed form (``LINEAR_AGREEMENT``), or without which the model is
    undetermined to first order, is refitted exactly (``refitted`` counts
    them)."""
    free = model.free_mask()
    # The held parameters' move per view, when the model holds any (else they need no answer).
    held_moves = held_steps if free is not None and not free.all() else None
    jc = None  # the Jacobian's held columns
    if held_moves is not None and free is not None:
        r, full = residuals_and_jacobian(model, poses, data, SolveSettings(free_params=np.ones(model.n_params, bool)))
        keep = np.concatenate([np.flatnonzero(free), model.n_params + np.arange(6 * data.n_views)])
        jac, jc = full[:, keep].tocsr(), full[:, np.flatnonzero(~free)].tocsr()
    else:
        r, jac = residuals_and_jacobian(model, poses, data)
    n_model = jac.shape[1] - 6 * data.n_views
    model_cols = jac[:, :n_model].tocsr()
    s = gram(model_cols)  # prior rows included: they stay when a view leaves
    order = np.argsort(data.view_index, kind="stable")
    rows = np.column_stack([2 * order, 2 * order + 1]).ravel()  # the points' rows, view by view
    by_view = model_cols[rows]  # the model's columns, sparse (a corner touches few of a field's controls)
    pose_block = jac[rows][:, n_model:].toarray()
    held_block = None if jc is None else jc[rows].toarray()
    r_view = r[rows]
    weight = np.repeat(np.ones(data.n_points, dtype=bool) if scored is None else scored, 2)[rows]
    bounds = np.concatenate([[0], np.cumsum(2 * np.bincount(data.view_index, minlength=data.n_views))])
    parts = []
    cross = 0.0
    for v in range(data.n_views):
        span = slice(bounds[v], bounds[v + 1])
        a = by_view[span]
        at = a.T.tocsr()
        m = pose_basis(pose_block[span, 6 * v : 6 * v + 6])
        atm = at @ m
        coupling = atm @ atm.T
        s -= coupling
        held_part = None  # C_v, T_v and δc of the view
        if held_block is not None and held_moves is not None:
            c = held_block[span]
            t = at @ c - atm @ (m.T @ c)
            cross = cross + t
            held_part = (c, t, held_moves[v])
        parts.append((span, a, at, m, gram(a) - coupling, held_part))
    errors = np.zeros(data.n_views)
    steps = np.zeros((data.n_views, n_model))
    ridge = 1e-12 * np.trace(s) / max(n_model, 1) * np.eye(n_model)
    free_idx = np.flatnonzero(free_parameters(model))
    refitted = 0
    for v, (span, a, at, m, share, held_part) in enumerate(parts):
        rv = r_view[span]
        rhs = at @ rv
        held_move = None if held_part is None else held_part[2]
        if held_part is not None:
            rhs -= (cross - held_part[1]) @ held_part[2]
        try:
            steps[v] = _spd_solve(s - share + ridge, rhs)
            e = rv + a @ steps[v]
            if held_part is not None:
                e += held_part[0] @ held_move
            e -= m @ (m.T @ e)
            errors[v] = float(np.sum(e[weight[span]] ** 2))
            moved = residuals(_moved(model, free_idx, steps[v], held_move), poses[[v]],
                              select_views(data, np.array([v]))).ravel()
            moved -= m @ (m.T @ moved)
            predicted = float(np.sum(moved[weight[span]] ** 2))
            linear = abs(predicted - errors[v]) <= LINEAR_AGREEMENT * max(errors[v], predicted)
        except np.linalg.LinAlgError:  # undetermined to first order without the view
            linear = False
        if not linear:
            errors[v], steps[v] = _refit_without(model, poses, data, v, free_idx, held_move, weight[span][::2])
            refitted += 1
    return ViewErrors(errors, steps, refitted)


def refitted_view_errors(model: CameraModel, poses: np.ndarray, data: Data,
                         scored: np.ndarray | None = None) -> ViewErrors:
    """``linearised_view_errors``' answer by exact refits: each view's squared
    residuals over its ``scored`` points (default all) when the model, fitted
    again without the view from the full fit, is held while the view's pose is
    refit; ``steps``: the free parameters' move. The closed form's step is
    Gauss-Newton's, whose curvature leaves out the residuals' own second
    derivatives: where a model misfits the lens (large residuals) or trades
    parameters along a flat valley (the rational model's numerator and
    denominator), that step falls short of the refit, and the view left out
    looks better predicted than it is (docs/model-choice.md, "Views left out,
    refitted"). A parametric model's refits cost a few solver iterations a
    view."""
    free_idx = np.flatnonzero(free_parameters(model))
    weight = np.ones(data.n_points, dtype=bool) if scored is None else scored
    errors = np.zeros(data.n_views)
    steps = np.zeros((data.n_views, len(free_idx)))
    for v in range(data.n_views):
        errors[v], steps[v] = _refit_without(model, poses, data, v, free_idx, None, weight[data.view_index == v])
    return ViewErrors(errors, steps, data.n_views)


def held_steps(model: CameraModel, core: CameraModel, core_steps: np.ndarray) -> np.ndarray:
    """A model over ``core`` holds some of the core's parameters where the core's
    own fit put them (a hybrid's coefficients): their move when each view leaves
    that fit, from the core's own ``ViewErrors.steps`` (over its free
    parameters), as ``linearised_view_errors`` takes it."""
    column = {p: j for j, p in enumerate(np.flatnonzero(free_parameters(core)))}
    held = np.flatnonzero(~free_parameters(model))  # the model's parameters start with its core's
    out = np.zeros((len(core_steps), len(held)))
    for k, p in enumerate(held):
        if p in column:
            out[:, k] = core_steps[:, column[p]]
    return out


def _moved(model: CameraModel, free_idx: np.ndarray, step: np.ndarray, held_move: np.ndarray | None) -> CameraModel:
    """The model with its free parameters moved by ``step`` and its held ones by ``held_move``."""
    x = model.params().copy()
    x[free_idx] += step
    if held_move is not None:
        x[np.setdiff1d(np.arange(model.n_params), free_idx)] += held_move
    return model.with_params(x)


def _refit_without(model: CameraModel, poses: np.ndarray, data: Data, v: int, free_idx: np.ndarray,
                   held_move: np.ndarray | None, scored: np.ndarray) -> tuple[float, np.ndarray]:
    """View v's squared error over its ``scored`` points when the model is
    refitted without it from the full fit (held parameters moved by
    ``held_move``), then held while the view's pose is refit; and the free
    parameters' move."""
    others = np.setdiff1d(np.arange(data.n_views), [v])
    start = _moved(model, free_idx, np.zeros(len(free_idx)), held_move)
    fit = levenberg_marquardt(start, poses[others], select_views(data, others), REFIT)
    alone = levenberg_marquardt(fit.model, poses[[v]], select_views(data, np.array([v])),
                                SolveSettings(100, fix_model=True))
    return float(np.sum(alone.residuals[scored] ** 2)), fit.model.params()[free_idx] - model.params()[free_idx]


def pose_basis(p: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """P (PᵀWP)^-½ (rows, ≤ 6) of a view's pose columns P (W: the rows' weights,
    default 1), the directions PᵀWP cannot tell apart dropped (a view left with
    too few corners, or corners on one line, to pose): M Mᵀ W projects onto the
    pose's columns, what refitting the view's pose takes up."""
    pwp = p.T @ p if w is None else p.T @ (w[:, None] * p)
    s, u = np.linalg.eigh(pwp)
    keep = s > 1e-12 * max(float(s.max(initial=0.0)), 1e-300)
    return p @ (u[:, keep] / np.sqrt(s[keep]))


def _spd_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b (``a`` overwritten); a fit that no longer determines the model is an error here."""
    x = cholesky_solve(a, b, overwrite=True)
    if x is None:
        raise np.linalg.LinAlgError("the fit without this view is undetermined (not positive definite)")
    return x
