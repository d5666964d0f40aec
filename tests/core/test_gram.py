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
