"""The closed-form grouped cross-validation of the control-point problem
equals refitting it without each group, and it chooses what predicts."""
import numpy as np
import pytest

from calib_core.fitting.smoothing import LAMBDA_GRID, cv_curve, groups_of
from calib_core.models.bspline import GAUGE_WEIGHT, gauge_rows
from calib_core.models.bspline_basis import BSplineField, clamped_knots


def _problem(seed: int, n_views: int = 6, per_view: int = 60, intervals: int = 5):
    rng = np.random.default_rng(seed)
    field = BSplineField.zeros(clamped_knots(np.linspace(0, 100, intervals + 1)),
                               clamped_knots(np.linspace(0, 80, intervals + 1)))
    view = np.repeat(np.arange(n_views), per_view)
    # Each view covers part of the image, as a board does.
    centre = rng.uniform([20, 15], [80, 65], size=(n_views, 2))
    pts = np.clip(centre[view] + rng.normal(0, 18, size=(len(view), 2)), 0, [100, 80])
    truth = np.column_stack([np.sin(pts[:, 0] / 17) * 2, np.cos(pts[:, 1] / 13)])
    response = truth + rng.normal(0, 0.3, size=truth.shape)
    weights = rng.uniform(0.5, 2.0, size=truth.shape)
    weights /= weights.mean(axis=0)
    b = field.design(pts).matrix(field.n_controls)
    gauge = gauge_rows(field, (50.0, 40.0)) * GAUGE_WEIGHT
    return field, b, weights, gauge, response, view


def _refit_sse(field, b, weights, gauge, response, groups, ridge, lam):
    """Each group's left-out squared residuals by an explicit refit without
    it: the regularised least squares with the gauge held exactly (KKT)."""
    n = field.n_controls
    bend = (field.bending().T @ field.bending()).toarray()
    sse = np.zeros(groups.max() + 1)
    for k in range(groups.max() + 1):
        out = groups == k
        for c in range(2):
            bi = b[~out].toarray()
            g = gauge[c::2, c * n:(c + 1) * n].toarray()
            a = bi.T @ (weights[~out, c][:, None] * bi) + ridge * np.eye(n) + lam * bend
            kkt = np.block([[a, g.T], [g, np.zeros((len(g), len(g)))]])
            rhs = np.concatenate([bi.T @ (weights[~out, c] * response[~out, c]), np.zeros(len(g))])
            p = np.linalg.solve(kkt, rhs)[:n]
            sse[k] += np.sum((response[out, c] - b[out] @ p) ** 2)
    return sse


@pytest.mark.slow
def test_closed_form_equals_explicit_refits():
    for seed in range(3):
        field, b, weights, gauge, response, view = _problem(seed)
        lambdas = np.array([1e-3, 0.1, 3.0, 100.0])
        curve = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view), lambdas)
        for j, lam in enumerate(lambdas):
            explicit = _refit_sse(field, b, weights, gauge, response, view, 1e-6, lam)
            assert np.allclose(curve.group_sse[:, j], explicit, rtol=1e-8, atol=1e-10)


def test_many_views_pool_into_interleaved_folds():
    view = np.repeat(np.arange(25), 3)
    groups = groups_of(view, max_groups=10)
    assert groups.max() == 9
    assert np.array_equal(groups[view == 13], np.full(3, 3))
    assert np.array_equal(groups_of(np.repeat([4, 7, 9], 2)), np.repeat([0, 1, 2], 2))


def test_left_out_error_exceeds_the_fit_and_has_an_interior_minimum():
    field, b, weights, gauge, response, view = _problem(0, intervals=8)
    curve = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view))
    # Prediction of new views is worse than the noise (σ² · 2 axes = 0.18) and
    # neither no smoothing nor the heaviest wins on a smooth, noisy field.
    assert curve.score.min() > 0.18
    assert 0 < curve.best < len(LAMBDA_GRID) - 1
    assert np.all(np.diff(curve.dof) < 1e-9)  # more smoothing, fewer effective parameters


def test_both_forms_of_a_group_agree():
    # Groups smaller than the controls take the corners' form, larger ones
    # the controls' form: the same residuals either way.
    field, b, weights, gauge, response, view = _problem(1, n_views=4, per_view=30, intervals=3)
    small = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view), np.array([0.5]))
    large = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, view // 2, np.array([0.5]))
    assert np.allclose(small.group_sse[:, 0], _refit_sse(field, b, weights, gauge, response, view, 1e-6, 0.5),
                       rtol=1e-8)
    assert np.allclose(large.group_sse[:, 0], _refit_sse(field, b, weights, gauge, response, view // 2, 1e-6, 0.5),
                       rtol=1e-8)


def test_refined_search_finds_the_full_grids_minimum():
    field, b, weights, gauge, response, view = _problem(2, intervals=8)
    full = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view))
    quick = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view), refine=True)
    assert quick.lambdas[quick.best] == full.lambdas[full.best]
    assert len(quick.lambdas) < 0.7 * len(full.lambdas)


def test_search_from_a_neighbouring_grids_choice_walks_to_the_same_minimum():
    field, b, weights, gauge, response, view = _problem(2, intervals=8)
    full = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view))
    for start in (LAMBDA_GRID[0], full.lambdas[full.best], LAMBDA_GRID[-1]):
        walked = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view), refine=True, start=start)
        assert walked.lambdas[walked.best] == full.lambdas[full.best]
        assert np.allclose(walked.score, full.score[np.isin(full.lambdas, walked.lambdas)], rtol=1e-12)
    near = cv_curve(b, weights, field.bending(), gauge, response, 1e-6, groups_of(view), refine=True,
                    start=full.lambdas[full.best])
    assert len(near.lambdas) == 3  # the choice and its two neighbours
