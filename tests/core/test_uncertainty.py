"""B-spline projection uncertainty against the spread over noise realisations."""
import numpy as np
import pytest

from calib_core import calibrate, synth
from calib_core.evaluation.uncertainty import aligned_projection, projection_uncertainty
from calib_core.fitting.solve import Data, SolveSettings, levenberg_marquardt
from calib_core.models import camera
from calib_core.pipeline import to_data


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["radial", "asymmetric"])  # an exact parametric core; a lens none represents
def test_predicted_projection_spread_matches_noise_realisations(kind):
    sigma, rng = 0.3, np.random.default_rng(1)
    clean = synth.generate(kind, sigma=0.0, seed=0, n_views=6)
    data, _, _ = to_data(clean.train)
    keep = np.arange(data.n_points) % 2 == 0  # half the corners: a faster solve, the same question
    data = Data(data.object_points[keep], data.image_points[keep], data.view_index[keep], data.n_views)
    # A small case: coarse uniform knots; the truth is the fitted model itself,
    # so the only spread is the noise's.
    cal = calibrate(clean.train, "bspline", outlier_sigma=0, knots="uniform", intervals=(4, 4))
    poses = np.array([v.pose for v in cal.views])
    truth = cal.model.project(camera.transform(poses, data.view_index, data.object_points))

    def noisy() -> Data:
        return Data(data.object_points, truth + rng.normal(0, sigma, truth.shape), data.view_index, data.n_views)

    d0 = noisy()
    fit = levenberg_marquardt(cal.model, poses, d0, SolveSettings(ftol=1e-12))
    um = projection_uncertainty(fit.model, fit.poses, d0, clean.train.image_size, step=96.0)
    assert abs(um.sigma - sigma) < 0.03  # σ from the residuals
    assert um.covered.sum() > 50
    rays = um.rays.reshape(-1, 3)[um.covered.reshape(-1)]
    projs = [aligned_projection(r.model, r.poses, fit.poses, rays) for r in
             (levenberg_marquardt(fit.model, fit.poses, noisy(), SolveSettings(ftol=1e-10, max_iterations=40))
              for _ in range(16))]
    emp = np.sqrt(0.5 * np.var(np.array(projs), axis=0, ddof=1).sum(axis=-1))
    ratio = um.std_rms[um.covered] / emp
    assert 0.77 < np.median(ratio) < 1.3
    # 16 draws: each pixel's empirical spread itself scatters ~18 %, so most, not all, pixels fall within 30 %
    assert np.mean(np.abs(ratio - 1) <= 0.3) > 0.6
    assert np.all(um.std_worst[um.covered] >= um.std_rms[um.covered] - 1e-12)


def test_schur_complement_equals_the_model_block_of_the_full_covariance():
    from calib_core.evaluation.uncertainty import full_covariance, model_covariance
    from calib_core.fitting.init import initialise

    train = synth.generate("fisheye", sigma=0.3, seed=0, n_views=4).train
    data, _, _ = to_data(train)
    init = initialise(data, train.image_size)
    full, s_full, dof_full = full_covariance(init.model, init.poses, data)
    block, s_block, dof_block = model_covariance(init.model, init.poses, data)
    n = init.model.n_params
    assert np.isclose(s_full, s_block) and np.isclose(dof_full, dof_block)
    assert np.isclose(dof_full, n + 6 * 4, rtol=1e-6)  # no prior: every parameter is fitted
    assert np.allclose(block, full[:n, :n], rtol=1e-6, atol=1e-12 * np.abs(full[:n, :n]).max())
