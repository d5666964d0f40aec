"""The field screen with each view's pose refit: its closed form equals refitting
the field and the poses without each group, and it finds the field that poses hide."""
import functools

import numpy as np
import scipy.sparse as sp

from calib_core.evaluation.evaluate import validation_residuals
from calib_core.fitting.metrics import rmse
from calib_core.fitting.posed_cv import posed_cv_curve
from calib_core.fitting.smoothing import groups_of
from calib_core.pipeline import calibrate
from calib_core.synth import opencv_lenses as lenses
from tests.core.test_smoothing_cv import _problem


def _with_poses(seed: int, n_views: int = 6, per_view: int = 60):
    """``_problem``'s field, its response moved by each view's pose (random derivatives)."""
    field, b, weights, gauge, response, view = _problem(seed, n_views, per_view)
    rng = np.random.default_rng(100 + seed)
    n = len(view)
    derivatives = rng.normal(0, 1, size=(2 * n, 6))  # each corner's x and y rows along its view's pose
    moves = rng.normal(0, 0.5, size=(n_views, 6))
    response = response + np.einsum("nk,nk->n", derivatives, moves[np.repeat(view, 2)]).reshape(n, 2)
    rows, cols = np.repeat(np.arange(2 * n), 6), (6 * np.repeat(view, 2)[:, None] + np.arange(6)).ravel()
    jacobian = sp.csr_matrix((derivatives.ravel(), (rows, cols)), shape=(2 * n, 6 * n_views))
    return field, b, weights, gauge, response, view, jacobian


def _refit_sse(field, b, weights, gauge, response, view, jacobian, groups, ridge, lam):
    """Each group's left-out squared residuals by explicit refits: field and every
    other view's pose without the group (the gauge held exactly, KKT), then each
    left-out view's pose alone, the field held."""
    n, nc = len(view), field.n_controls
    x = np.zeros((2 * n, 2 * nc))
    x[0::2, :nc], x[1::2, nc:] = b.toarray(), b.toarray()
    full = np.hstack([x, jacobian.toarray()])
    w, d = weights.ravel(), response.ravel()
    bend = (field.bending().T @ field.bending()).toarray()
    reg = np.zeros((full.shape[1], full.shape[1]))
    reg[:2 * nc, :2 * nc] = np.kron(np.eye(2), lam * bend + ridge * np.eye(nc))
    g = gauge.toarray()
    g = np.hstack([np.vstack([g[0::2, :nc], np.zeros((3, nc))]), np.vstack([np.zeros((3, nc)), g[1::2, nc:]])])
    sse = np.zeros(groups.max() + 1)
    row_view = np.repeat(view, 2)
    for k in range(groups.max() + 1):
        out = np.repeat(groups == k, 2)
        left_views = np.unique(view[groups == k])
        keep_cols = np.r_[np.arange(2 * nc), [2 * nc + 6 * v + j for v in range(view.max() + 1)
                                              if v not in left_views for j in range(6)]]
        a_rows = full[~out][:, keep_cols]
        a = a_rows.T @ (w[~out, None] * a_rows) + reg[np.ix_(keep_cols, keep_cols)]
        gk = np.hstack([g, np.zeros((6, len(keep_cols) - 2 * nc))])
        kkt = np.block([[a, gk.T], [gk, np.zeros((6, 6))]])
        sol = np.linalg.solve(kkt, np.concatenate([a_rows.T @ (w[~out] * d[~out]), np.zeros(6)]))
        for v in left_views:
            rows = row_view == v
            e = d[rows] - x[rows] @ sol[:2 * nc]
            p = jacobian[np.flatnonzero(rows)][:, 6 * v:6 * v + 6].toarray()
            step = np.linalg.lstsq(np.sqrt(w[rows])[:, None] * p, np.sqrt(w[rows]) * e, rcond=None)[0]
            sse[k] += np.sum((e - p @ step) ** 2)
    return sse


def test_closed_form_equals_explicit_refits():
    for seed in range(2):
        field, b, weights, gauge, response, view, jacobian = _with_poses(seed)
        groups = groups_of(view)
        lambdas = np.array([1e-2, 1.0, 100.0])  # fewer than five: every λ is scored
        curve, _ = posed_cv_curve(b, weights, field.bending(), gauge, response, jacobian, view, 1e-6, groups, lambdas)
        for j, lam in enumerate(lambdas):
            explicit = _refit_sse(field, b, weights, gauge, response, view, jacobian, groups, 1e-6, lam)
            assert np.allclose(curve.group_sse[:, j], explicit, rtol=1e-8, atol=1e-10)


def test_no_field_is_each_view_posed_alone():
    field, b, weights, gauge, response, view, jacobian = _with_poses(2)
    groups = groups_of(view)
    _, none = posed_cv_curve(b, weights, field.bending(), gauge, response, jacobian, view, 1e-6, groups,
                             np.array([1.0]))
    w, d, row_view = weights.ravel(), response.ravel(), np.repeat(view, 2)
    explicit = np.zeros(len(none))
    for v in range(view.max() + 1):
        rows = row_view == v
        p = jacobian[np.flatnonzero(rows)][:, 6 * v:6 * v + 6].toarray()
        step = np.linalg.lstsq(np.sqrt(w[rows])[:, None] * p, np.sqrt(w[rows]) * d[rows], rcond=None)[0]
        explicit[groups[view == v][0]] += np.sum((d[rows] - p @ step) ** 2)
    assert np.allclose(none, explicit, rtol=1e-10)


def test_the_default_takes_the_field_that_the_poses_hid():
    # The core's fit tilts each view's pose to absorb part of the elliptic error, so held
    # at those poses no field predicts the views left out better; refit, one does.
    lens = functools.partial(lenses.elliptic_lens, camera=lenses.HD)  # boards far off centre, many partly seen
    train = lenses.views_of(lens, (1280, 720), 10, seed=0, sigma=0.3, distance=600, spread=0.5)
    holdout = lenses.views_of(lens, (1280, 720), 20, seed=1000, sigma=0.0, distance=600, spread=0.5)
    cal = calibrate(train, "auto")
    choice = cal.diagnostics.model_choice
    assert "each view's pose refit" in choice.how and "it did:" in choice.how
    assert cal.settings["chosen"] == "bspline" or cal.settings["chosen"].startswith("hybrid-")
    parametric = min(rmse(validation_residuals(calibrate(train, m), holdout)[0]) for m in ("zhang", "fisheye", "rational"))
    assert rmse(validation_residuals(cal, holdout)[0]) < 0.5 * parametric
