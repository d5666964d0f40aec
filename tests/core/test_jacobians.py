"""Every analytic Jacobian block against central finite differences."""
import numpy as np
import pytest

from calib_core.fitting.solve import Data, SolveSettings, _assemble
from calib_core.models import camera
from calib_core.models.bspline import BSplineModel
from calib_core.models.bspline_basis import BSplineField, clamped_knots
from calib_core.models.fisheye import FisheyeModel


def numeric(f, x, eps):
    cols = []
    for k in range(len(x)):
        d = np.zeros_like(x)
        d[k] = eps
        cols.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(cols, axis=-1)


def models():
    rng = np.random.default_rng(0)
    f = BSplineField.zeros(clamped_knots([-200.0, 100.0, 450.0, 700.0, 1200.0]), clamped_knots([-100.0, 300.0, 800.0, 1400.0]))
    f = f.with_control(rng.normal(size=(f.n_u, f.n_v, 2)) * 3)
    yield BSplineModel([305.0, 302.0, 511.0, 631.0, 0.7], f, lambda_reg=1e-3, lambda_smooth=1e-1, gauge_point=(511.0, 631.0))
    yield FisheyeModel([300.0, 298.0, 500.0, 620.0, 0.0], [0.05, -0.02, 0.01, 0.003])


@pytest.mark.parametrize("model", list(models()), ids=lambda m: m.kind)
def test_projection_jacobians(model):
    rng = np.random.default_rng(2)
    pc = np.column_stack([rng.uniform(-1, 1, 40), rng.uniform(-1, 1, 40), rng.uniform(0.6, 2.0, 40)])
    uv, d_pc, cols, vals = model.project(pc, jacobian=True)
    # ∂uv/∂Pc
    for i in range(len(pc)):
        num = numeric(lambda p: model.project(p[None])[0], pc[i], 1e-6)
        assert np.allclose(d_pc[i], num, rtol=1e-5, atol=1e-5)
    # ∂uv/∂params, from the sparse (cols, vals) rows
    x0 = model.params()
    dense = np.zeros((len(pc), 2, len(x0)))
    for r in range(2):
        np.add.at(dense[:, r], (np.arange(len(pc))[:, None], cols[:, r]), vals[:, r])
    num = numeric(lambda x: model.with_params(x).project(pc), x0, 1e-5)
    assert np.allclose(dense, num, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("base", camera.BASES)
def test_base_projection_jacobians(base):
    rng = np.random.default_rng(3)
    pc = np.column_stack([rng.uniform(-1, 1, 30), rng.uniform(-1, 1, 30), rng.uniform(0.3, 2.0, 30)])
    _, jac = camera.normalise(pc, base, jacobian=True)
    for i in range(len(pc)):
        num = numeric(lambda p: camera.normalise(p[None], base)[0], pc[i], 1e-7)
        assert np.allclose(jac[i], num, rtol=1e-5, atol=1e-6)


POSES = np.array([[0.1, -0.2, 0.05, -200, -150, 500], [-0.3, 0.1, 0.2, -150, -100, 450],
                  [0.2, 0.3, -0.1, -250, -120, 600.0]])


def full_jacobian_pair(model, n_views: int, per_view: int):
    """The assembled Jacobian over [model | poses] and its central finite
    differences, for board points seen by ``n_views`` of POSES."""
    rng = np.random.default_rng(4)
    n = n_views * per_view
    obj = np.column_stack([rng.uniform(0, 400, n), rng.uniform(0, 300, n), np.zeros(n)])
    poses = POSES[:n_views]
    data = Data(obj, np.zeros((n, 2)), np.repeat(np.arange(n_views), per_view), n_views)
    _, jac = _assemble(model, poses, data, SolveSettings())
    n_model, x0 = model.n_params, model.params()

    def residual(delta):
        m = model.with_params(x0 + delta[:n_model])
        return _assemble(m, camera.retract_poses(poses, delta[n_model:].reshape(-1, 6)), data, SolveSettings())[0]

    return jac.toarray(), numeric(residual, np.zeros(n_model + 6 * n_views), 1e-6)


def test_full_jacobian_with_poses_matches_finite_differences():
    jac, num = full_jacobian_pair(next(models()), n_views=3, per_view=20)
    assert np.allclose(jac, num, rtol=1e-5, atol=2e-5)


@pytest.mark.parametrize("angle", [0.0, 1e-5, 1e-3, 0.5, 3.0, np.pi - 1e-6])
def test_the_compiled_rotations_are_scipys(angle):
    """transform and retract_poses rotate as scipy's Rotation does (their kernels follow its
    algorithms), from no rotation to one of nearly π, where the rotation vector's sign turns."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    axes = rng.normal(size=(8, 3))
    poses = np.hstack([angle * axes / np.linalg.norm(axes, axis=1, keepdims=True), rng.normal(size=(8, 3)) * 100])
    points = rng.normal(size=(40, 3)) * 50
    views = rng.integers(0, 8, size=40)
    expected = Rotation.from_rotvec(poses[views, :3]).apply(points) + poses[views, 3:]
    assert np.allclose(camera.transform(poses, views, points), expected, rtol=0, atol=1e-10)
    delta = np.hstack([rng.normal(size=(8, 3)) * 0.01, rng.normal(size=(8, 3))])
    step = Rotation.from_rotvec(delta[:, :3])
    new = camera.retract_poses(poses, delta)
    turned = (step * Rotation.from_rotvec(poses[:, :3])).inv() * Rotation.from_rotvec(new[:, :3])
    assert np.max(turned.magnitude()) < 1e-12
    assert np.allclose(new[:, 3:], step.apply(poses[:, 3:]) + delta[:, 3:], rtol=0, atol=1e-10)


@pytest.mark.parametrize("base", ["equidistant", "stereographic"])
def test_an_angular_base_on_the_axis_and_past_90_degrees(base):
    """On the optical axis the angular bases take the pinhole's limit (xn = 0, ∂xn/∂Pc = I/Z);
    a point behind the camera's plane stays on its side, θ = atan2(ρ, Z) > 90° (formats.md)."""
    xn, jac = camera.normalise(np.array([[0.0, 0.0, 2.0], [1.0, 0.0, -1.0]]), base, jacobian=True)
    assert np.array_equal(xn[0], [0.0, 0.0]) and np.allclose(jac[0], [[0.5, 0, 0], [0, 0.5, 0]])
    g = 3 * np.pi / 4 if base == "equidistant" else 2 * np.tan(3 * np.pi / 8)
    assert np.allclose(xn[1], [g, 0.0])
