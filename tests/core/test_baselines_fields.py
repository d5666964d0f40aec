"""The residual fields against their documented formulas (docs/methods.md, models/mls.py,
models/tps.py), computed point by point the slow, obvious way."""
import numpy as np

from calib_core.calibration import Calibration
from calib_core.methods.residual_fields import fit_tps_field
from calib_core.models.mls import MLSField, MLSModel
from calib_core.models.opencv import OpenCVModel
from calib_core.models.tps import TPSModel


def brute_mls(field: MLSField, p):
    out = []
    for q in p:
        d = field.samples - q
        dist = np.linalg.norm(d, axis=1)
        w = np.where(dist <= field.support, np.exp(-dist**2 / (2 * field.sigma**2)), 0.0)
        g = np.column_stack([np.ones(len(d)), d / field.support])
        m = (g * w[:, None]).T @ g + field.ridge * np.eye(3)
        out.append(np.linalg.solve(m, (g * w[:, None]).T @ field.offsets)[0])
    return np.array(out)


def test_mls_matches_its_formula():
    rng = np.random.default_rng(0)
    samples = np.column_stack([rng.uniform(0, 1000, 500), rng.uniform(0, 800, 500)])
    offsets = np.column_stack([np.sin(samples[:, 0] / 200), samples[:, 1] / 400]) + rng.normal(0, 0.1, (500, 2))
    field = MLSField(samples, offsets, sigma=40.0)
    p = np.column_stack([rng.uniform(-50, 1050, 60), rng.uniform(-50, 850, 60)])
    assert np.allclose(field.evaluate(p)[0], brute_mls(field, p), atol=1e-9)


def test_mls_with_any_support_matches_its_formula():
    """The neighbour buckets hold for a support far smaller or larger than the
    samples' spread (a saved file may carry any positive value), and points
    far outside the samples get the core alone (offset 0)."""
    rng = np.random.default_rng(3)
    samples = np.column_stack([rng.uniform(0, 1000, 300), rng.uniform(0, 800, 300)])
    offsets = rng.normal(0, 1.0, (300, 2))
    p = np.vstack([samples[:20] + 1e-4, np.column_stack([rng.uniform(-50, 1050, 20), rng.uniform(-50, 850, 20)]),
                   [[1e30, 0.0], [-5e6, 4e6]]])
    for support in (3e-4, 2.0, 5000.0):
        field = MLSField(samples, offsets, sigma=support / 3, support=support)
        assert np.allclose(field.evaluate(p)[0], brute_mls(field, p), atol=1e-9)
        assert np.all(field.evaluate(p[-2:])[0] == 0.0)


def test_mls_first_order_reproduces_an_affine_field():
    rng = np.random.default_rng(1)
    samples = np.column_stack([rng.uniform(0, 1000, 800), rng.uniform(0, 800, 800)])
    offsets = samples @ np.array([[0.01, -0.02], [0.003, 0.004]]) + [1.5, -2.0]
    field = MLSField(samples, offsets, sigma=50.0, ridge=1e-9)
    p = np.column_stack([rng.uniform(200, 800, 50), rng.uniform(200, 600, 50)])
    off, grad = field.evaluate(p)
    assert np.allclose(off, p @ np.array([[0.01, -0.02], [0.003, 0.004]]) + [1.5, -2.0], atol=1e-6)
    assert np.allclose(grad, np.array([[0.01, 0.003], [-0.02, 0.004]]), atol=1e-6)


def test_tps_matches_its_formula_and_interpolates_when_unsmoothed():
    rng = np.random.default_rng(2)
    samples = np.column_stack([rng.uniform(0, 1000, 80), rng.uniform(0, 800, 80)])
    offsets = np.column_stack([np.sin(samples[:, 0] / 150), np.cos(samples[:, 1] / 120)])
    field = fit_tps_field(samples, offsets, 1280.0, [1e-12], max_centers=1000)[0]
    assert np.allclose(field.evaluate(samples)[0], offsets, atol=1e-4)  # every sample a centre, λ ≈ 0
    q = np.array([[123.0, 456.0]])
    r = np.linalg.norm(field.centers - q, axis=1) / field.scale
    phi = np.where(r > 0, r**2 * np.log(np.where(r > 0, r, 1)), 0)
    expected = phi @ field.weights + np.array([1, 123.0 / 1280, 456.0 / 1280]) @ field.affine
    assert np.allclose(field.evaluate(q)[0][0], expected)


def test_residual_field_json_round_trip_projects_identically():
    rng = np.random.default_rng(3)
    core = OpenCVModel([300.0, 310.0, 500.0, 400.0, 0.0], [0.05, -0.01, 0.001, -0.002, 0.003])
    samples = np.column_stack([rng.uniform(0, 1000, 100), rng.uniform(0, 800, 100)])
    offsets = rng.normal(size=(100, 2))
    pc = np.column_stack([rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50), rng.uniform(0.8, 2.0, 50)])
    for model in (TPSModel(core, fit_tps_field(samples, offsets, 1280.0, [1e-4], 50)[0]),
                  MLSModel(core, MLSField(samples, offsets, sigma=60.0))):
        cal = Calibration(model, (1000, 800), model.kind)
        back = Calibration.from_json(cal.to_json())
        assert type(back.model) is type(model)
        assert np.allclose(back.project(pc), cal.project(pc), atol=1e-10)
