"""The baselines converge from the project's initialisation on the paper's
synthetic lenses (118° × 129° field of view); the two lenses beyond the paper's
(freeform, decentred) are sets like the others, and no textbook model fits them."""
import numpy as np
import pytest

from calib_core import Calibration, calibrate, synth
from calib_core.errors import SettingsError
from calib_core.evaluation.evaluate import evaluate
from calib_core.fitting.solve import SolveSettings, levenberg_marquardt
from calib_core.methods.common import no_progress
from calib_core.methods.opencv import OpenCVSettings, RationalSettings, fit_opencv
from calib_core.models.opencv import OpenCVModel
from calib_core.pipeline import to_data
from calib_core.synth import opencv_lenses

from ..conftest import synthetic

NOISE_RMSE = 0.3 * np.sqrt(2)  # per-point rmse of σ = 0.3 px per axis


def test_zhang_recovers_the_radial_lens():
    cal = calibrate(synthetic("radial").train, "zhang")
    assert cal.metrics.rmse < 1.05 * NOISE_RMSE
    assert np.allclose(cal.model.intrinsics[:4], synth.INTRINSICS, atol=0.5)
    assert np.allclose(cal.model.coefficients, [0.05, 0.0267, 0.0067, 0.01, 0.0067], atol=2e-3)


@pytest.mark.parametrize("method", ["rational", "fisheye"])
def test_wide_models_fit_the_fisheye_lens(method):
    cal = calibrate(synthetic("fisheye").train, method)
    assert cal.diagnostics.solver.status in ("converged", "stalled")
    assert cal.metrics.rmse < 1.05 * NOISE_RMSE


def test_residual_field_improves_on_zhang_where_no_parametric_model_fits():
    train = synthetic("asymmetric").train
    zhang = calibrate(train, "zhang")
    mls = calibrate(train, "mls")
    assert mls.metrics.rmse < 0.5 * zhang.metrics.rmse
    table = mls.diagnostics.extra["grid_search"]["table"]
    assert [row["value"] for row in table] == [0.05, 0.10, 0.15, 0.20]
    best = min(table, key=lambda row: row["cv_rmse"])["value"]
    assert mls.settings["chosen_support"] == best  # chosen by held-out views
    back = Calibration.from_json(mls.to_json())
    assert back.model.kind == "mls"


def test_bad_settings_say_what_to_do():
    with pytest.raises(SettingsError, match="4, 5, 8, 12, 14"):
        calibrate(synthetic("radial").train, "zhang", n_coefficients=6)
    with pytest.raises(SettingsError, match="smoothing"):
        calibrate(synthetic("radial").train, "tps", smoothing=[-1.0])


NEW_KINDS = ("freeform", "decentred")


@pytest.mark.parametrize("kind", NEW_KINDS)
def test_new_lenses_give_sets_like_the_papers(kind):
    s = synthetic(kind)
    assert len(s.train.views) == 10 and s.train.n_points >= 1000
    assert s.truth["kind"] == kind and s.truth["lens"] == synth.LENSES[kind]
    assert {"format", "sigma", "seed", "image_size", "intrinsics", "train_views", "holdout_views"} <= set(s.truth)
    # The hold-out covers the whole image: every cell of a 16 × 20 grid, corners included.
    uv = np.concatenate([v.image_points for v in s.holdout.views])
    w, h = synth.IMAGE_SIZE
    cells, _, _ = np.histogram2d(uv[:, 0], uv[:, 1], bins=[16, 20], range=[[0, w], [0, h]])
    assert cells.min() > 0


@pytest.mark.slow
@pytest.mark.parametrize("kind", NEW_KINDS)
def test_no_radial_model_represents_the_new_lenses(kind):
    """The best textbook model's hold-out error is several times the paper's field's."""
    s = synthetic(kind)
    rational = evaluate(calibrate(s.train, "rational"), s.holdout)["rmse"]
    field = evaluate(calibrate(s.train, "bspline", core="none"), s.holdout)["rmse"]
    assert field < 0.2 and rational > 3 * field, (rational, field)


def test_the_rational_model_takes_the_lowest_minimum_its_starts_reach():
    """The rational model starts from the best 5-coefficient fit (so it is never worse
    than zhang) and from no distortion: on this lens drawn at random the distortion-free
    start reaches a lower minimum than the nested one, and the fit must keep it."""
    lens, size, distance, spread = opencv_lenses.random_lens("bumpy", 8)
    data, _, _ = to_data(opencv_lenses.views_of(lens, size, 10, 8, 0.3, distance, spread))
    five = fit_opencv(data, size, OpenCVSettings(), no_progress)
    rational = fit_opencv(data, size, RationalSettings(), no_progress, five)
    nested_only = levenberg_marquardt(
        OpenCVModel(five.result.model.intrinsics, np.r_[five.result.model.coefficients, 0.0, 0.0, 0.0]),
        five.result.poses, data.points(~five.excluded), SolveSettings(500, 1e-12))
    assert np.array_equal(rational.excluded, five.excluded)
    assert rational.result.cost <= five.result.cost
    assert rational.result.cost < (1 - 1e-3) * nested_only.cost, (rational.result.cost, nested_only.cost)
