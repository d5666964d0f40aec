"""The compiled JᵀJ kernel against scipy's sparse product, repeated columns
within a row included (models pad their rows with zero-valued repeats)."""
import numpy as np
import scipy.sparse as sp

from calib_core.fitting.gram import gram


def test_gram_is_scipys_product_with_repeated_columns():
    rng = np.random.default_rng(0)
    rows, width, n = 500, 9, 40
    cols = rng.integers(0, n, (rows, width))
    cols[:, 1] = cols[:, 0]  # a repeated column in every row
    vals = rng.normal(size=(rows, width))
    jac = sp.csr_matrix((vals.ravel(), cols.ravel(), np.arange(0, rows * width + 1, width)), shape=(rows, n))
    expected = (jac.T @ jac).toarray()
    got = gram(jac)
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12) and np.array_equal(got, got.T)


def test_gram_of_an_empty_row_block_is_zero():
    assert not gram(sp.csr_matrix((3, 5))).any()


def test_gram_of_rows_sharing_columns_is_scipys_product():
    """A parametric model's rows: every view's u rows touch the same columns (the model's and
    the view's pose), and its v rows others; blocks longer than the kernel gathers at once,
    shorter than it multiplies by BLAS, a repeated column, and weights."""
    rng = np.random.default_rng(1)
    model, views = 9, [300, 4, 129, 1, 7]
    rows, cols = [], []
    for v, n in enumerate(views):
        pose = 20 + 6 * v + np.arange(6)
        for _ in range(n):
            for axis in (0, 1):
                c = np.concatenate([np.arange(model - 1) + axis, [0], pose])  # column 0 twice
                cols.append(c)
                rows.append(rng.normal(size=len(c)))
    width = len(cols[0])
    jac = sp.csr_matrix((np.concatenate(rows), np.concatenate(cols), np.arange(0, len(rows) * width + 1, width)),
                        shape=(len(rows), 20 + 6 * len(views)))
    weights = rng.uniform(0.1, 3.0, len(rows))
    for w in (None, weights):
        expected = (jac.T @ (jac if w is None else sp.diags(w) @ jac)).toarray()
        got = gram(jac, w)
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12) and np.array_equal(got, got.T)
