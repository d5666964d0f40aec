import numpy as np
import pytest
from scipy.interpolate import NdBSpline

from calib_core.errors import FormatError
from calib_core.models.bspline_basis import BSplineField, basis, bending_operator, clamped_knots, validate_knots


@pytest.fixture
def field():
    rng = np.random.default_rng(0)
    tu = clamped_knots([-120.0, 40.0, 300.0, 310.0, 800.0, 1100.0])
    tv = clamped_knots([0.0, 500.0, 900.0, 1300.0])
    f = BSplineField.zeros(tu, tv)
    return f.with_control(rng.normal(size=(f.n_u, f.n_v, 2)) * 5)


def test_partition_of_unity_inside_and_outside_the_domain():
    t = clamped_knots([0.0, 1.0, 1.5, 4.0, 9.0])
    x = np.linspace(-3, 12, 1001)
    _, values, deriv = basis(t, x, derivative=True)
    assert np.allclose(values.sum(axis=1), 1.0, atol=1e-12)
    assert np.allclose(deriv.sum(axis=1), 0.0, atol=1e-12)


def test_field_matches_scipy_ndbspline_with_extrapolation(field):
    rng = np.random.default_rng(1)
    uv = np.column_stack([rng.uniform(-400, 1400, 2000), rng.uniform(-300, 1600, 2000)])
    for c in range(2):
        ref = NdBSpline((field.knots_u, field.knots_v), field.control[..., c], 3)
        assert np.allclose(field(uv)[:, c], ref(uv), atol=1e-10)
        _, jac, _ = field.evaluate(uv)
        assert np.allclose(jac[:, c, 0], ref(uv, nu=(1, 0)), atol=1e-12)
        assert np.allclose(jac[:, c, 1], ref(uv, nu=(0, 1)), atol=1e-12)


def test_design_matrix_reproduces_the_field(field):
    uv = np.array([[0.0, 0.0], [512.3, 640.1], [1099.9, 1299.0]])
    b = field.design(uv).matrix(field.n_controls)
    assert b.nnz == 16 * len(uv)
    assert np.allclose(b @ field.control.reshape(-1, 2), field(uv))


@pytest.mark.slow
def test_bending_energy_of_a_quadratic_is_grid_independent():
    energies = []
    for n in (6, 12, 24):
        tu, tv = clamped_knots(np.linspace(0, 1000, n + 1)), clamped_knots(np.linspace(0, 800, n + 1))
        d = bending_operator(tu, tv)
        # Cubic splines reproduce quadratics: control values are the quadratic's
        # blossom, approximated here by sampling it on a fine least-squares fit.
        f = BSplineField.zeros(tu, tv)
        g = np.stack(np.meshgrid(np.linspace(0, 1000, 60), np.linspace(0, 800, 60), indexing="ij"), -1).reshape(-1, 2)
        b = f.design(g).matrix(f.n_controls).toarray()
        coef = np.linalg.lstsq(b, 1e-3 * g[:, 0] ** 2, rcond=None)[0]
        energies.append(np.sum((d @ coef) ** 2))
    expected = (2e-3) ** 2 * 1000 * 800
    assert np.allclose(energies, expected, rtol=0.15)


@pytest.mark.parametrize("knots, message", [
    ([0, 0, 0, 1, 1, 1], "at least 8"),
    ([0, 0, 0, 0, 2, 1, 1, 1, 1], "non-decreasing"),
    ([0, 0, 0, 1, 2, 2, 2, 2], "repeated 4 times"),
    ([0, 0, 0, 0, float("nan"), 3, 3, 3, 3], "finite"),
])
def test_bad_knot_vectors_are_named(knots, message):
    with pytest.raises(FormatError, match=message):
        validate_knots(knots, "knots_u")


def test_far_and_non_finite_points_give_numbers_not_exceptions(field):
    """Newton's inversion of a model may probe absurd points; the field answers
    with (possibly non-finite) numbers there, as numpy would, and stays exact
    at ordinary points in the same call."""
    uv = np.array([[-7.5e19, 7.7e19], [np.nan, 1.0], [np.inf, 3.0], [512.3, 640.1]])
    ref = NdBSpline((field.knots_u, field.knots_v), field.control[..., 0], 3)
    offsets = field(uv)
    _, jac, _ = field.evaluate(uv)
    assert offsets.shape == (4, 2) and jac.shape == (4, 2, 2)
    assert np.isnan(offsets[1:3]).all()
    assert np.isclose(offsets[3, 0], ref(uv[3:])[0], atol=1e-10)
