"""The design diagnostics' singular values, taken from the design's sparse
rows, against a dense SVD of the same design: B-spline field designs whose
rows touch one knot cell each, well and ill conditioned, with untouched
controls, and rows that touch columns in no order."""
import numpy as np
import pytest
import scipy.sparse as sp

from calib_core.fitting.metrics import singular_values
from calib_core.models.bspline_basis import BSplineField, clamped_knots


def field_design(intervals: int, samples: np.ndarray) -> sp.csr_matrix:
    breaks = np.linspace(0.0, 100.0, intervals + 1)
    field = BSplineField.zeros(clamped_knots(breaks), clamped_knots(breaks))
    return sp.csr_matrix(field.design(samples).matrix(field.n_controls))


@pytest.mark.parametrize("intervals, spread", [(6, 100.0), (15, 100.0), (15, 40.0)])
def test_singular_values_are_the_dense_svds(intervals, spread):
    rng = np.random.default_rng(intervals)
    design = field_design(intervals, rng.uniform(0.0, spread, (3000, 2)))  # spread 40: controls no row touches
    expected = np.linalg.svd(design.toarray(), compute_uv=False)
    got = singular_values(design)
    assert np.allclose(got, expected, rtol=0, atol=1e-12 * expected.max())
    tol = expected.max() * max(design.shape) * np.finfo(float).eps
    assert np.sum(got > tol) == np.sum(expected > tol)
    if spread < 100.0:
        assert np.sum(expected > tol) < design.shape[1]  # the case is rank deficient


def test_singular_values_of_rows_in_any_column_order():
    rng = np.random.default_rng(1)
    rows, width, n = 400, 5, 30
    cols = np.stack([rng.permutation(n)[:width] for _ in range(rows)])
    design = sp.csr_matrix((rng.normal(size=rows * width), cols.ravel(), np.arange(0, rows * width + 1, width)),
                           shape=(rows, n))
    expected = np.linalg.svd(design.toarray(), compute_uv=False)
    assert np.allclose(singular_values(design), expected, rtol=0, atol=1e-12 * expected.max())
