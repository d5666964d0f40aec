"""Analytic Jacobians of the baseline models (OpenCV, TPS, MLS) against
central finite differences, the pattern of ``test_jacobians.py``."""
import cv2
import numpy as np
import pytest

from calib_core.models.mls import MLSField, MLSModel
from calib_core.models.opencv import OpenCVModel
from calib_core.models.tps import TPSField, TPSModel

from .test_jacobians import full_jacobian_pair, numeric

K = [300.0, 310.0, 500.0, 400.0, 0.0]


def opencv_models():
    rng = np.random.default_rng(0)
    for n in (4, 5, 8, 12, 14):
        yield OpenCVModel(K, rng.normal(size=n) * 0.05)


def field_models():
    rng = np.random.default_rng(1)
    core = OpenCVModel(K, [0.05, -0.01, 0.001, -0.002, 0.003])
    centers = np.column_stack([rng.uniform(0, 1000, 30), rng.uniform(0, 800, 30)])
    w = rng.normal(size=(30, 2)) * 2
    w -= np.column_stack([np.ones(30), centers / 1280.0]) @ np.linalg.lstsq(np.column_stack([np.ones(30), centers / 1280.0]), w, rcond=None)[0]
    yield TPSModel(core, TPSField(centers, w, rng.normal(size=(3, 2)), 1280.0, 1e-4))
    samples = np.column_stack([rng.uniform(0, 1000, 300), rng.uniform(0, 800, 300)])
    offsets = np.column_stack([np.sin(samples[:, 0] / 200), np.cos(samples[:, 1] / 150)]) * 2
    yield MLSModel(core, MLSField(samples, offsets, sigma=60.0))


def points(n=40, seed=2):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0.8, 2.0, n)])


def check(model, pc):
    uv, d_pc, cols, vals = model.project(pc, jacobian=True)
    num_pc = np.stack([numeric(lambda p: model.project(p[None])[0], pc[i], 1e-6) for i in range(len(pc))])
    assert np.allclose(d_pc, num_pc, rtol=1e-5, atol=1e-4)
    x0 = model.params()
    dense = np.zeros((len(pc), 2, len(x0)))
    for r in range(2):
        np.add.at(dense[:, r], (np.arange(len(pc))[:, None], cols[:, r]), vals[:, r])
    steps = np.maximum(np.abs(x0) * 1e-7, 1e-7)
    num = np.stack([(model.with_params(x0 + np.eye(len(x0))[k] * steps[k]).project(pc)
                     - model.with_params(x0 - np.eye(len(x0))[k] * steps[k]).project(pc)) / (2 * steps[k])
                    for k in range(len(x0))], axis=-1)
    assert np.allclose(dense, num, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("model", list(opencv_models()), ids=lambda m: f"opencv{len(m.coefficients)}")
def test_opencv_jacobians(model):
    check(model, points())


@pytest.mark.parametrize("model", list(field_models()), ids=lambda m: m.kind)
def test_residual_field_jacobians(model):
    check(model, points(30))


@pytest.mark.parametrize("model", list(opencv_models()), ids=lambda m: f"opencv{len(m.coefficients)}")
def test_opencv_model_is_cv2_projectpoints(model):
    pc = points(200, seed=5)
    fx, fy, cx, cy, _ = model.intrinsics
    ref = cv2.projectPoints(pc, np.zeros(3), np.zeros(3), np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]]),
                            model.coefficients)[0].reshape(-1, 2)  # OpenCV 5: (N, 1, 2)
    assert np.abs(model.project(pc) - ref).max() < 1e-9


def test_residual_field_full_jacobian_with_poses():
    jac, num = full_jacobian_pair(list(field_models())[0], n_views=2, per_view=15)
    assert np.allclose(jac, num, rtol=1e-5, atol=5e-4)
