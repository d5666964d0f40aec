"""The default method (``auto``) and the B-spline method end to end on the
paper's synthetic lenses: at the noise floor on training corners, accurate on
noise-free held-out views, and honest about what they cannot do. (The
benchmark averages over seeds; these use one.)"""
import numpy as np
import pytest

from calib_core import Calibration, calibrate
from calib_core.errors import DataError, SettingsError
from calib_core.evaluation.evaluate import evaluate
from calib_core.fitting.metrics import noise_floor
from calib_core.models.bspline import gauge_rows
from calib_core.observations import Observations

from ..conftest import synthetic


@pytest.fixture(scope="module")
def results():
    out = {}
    for kind in ("radial", "asymmetric", "fisheye"):
        s = synthetic(kind)
        cal = calibrate(s.train)
        out[kind] = (cal, evaluate(cal, s.holdout))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kind, ratio", [("radial", 1.05), ("asymmetric", 1.05), ("fisheye", 1.5)])
def test_training_error_is_at_the_noise_floor(results, kind, ratio):
    cal, _ = results[kind]
    floor = noise_floor(0.3, cal.diagnostics.solver.n_unknowns, cal.metrics.n_points)
    assert cal.metrics.rmse_axis <= ratio * floor
    assert cal.metrics.rmse_axis >= 0.9 * floor  # not fitting the noise either


@pytest.mark.slow
@pytest.mark.parametrize("kind, limit", [("radial", 0.12), ("asymmetric", 0.12), ("fisheye", 0.12)])
def test_holdout_error_over_the_whole_image(results, kind, limit):
    _, hold = results[kind]
    assert hold["rmse"] <= limit
    assert hold["rmse_edge"] <= 1.5 * limit  # edges and corners included


@pytest.mark.slow
def test_result_carries_diagnostics_and_settings(results):
    cal, _ = results["asymmetric"]
    d = cal.diagnostics
    assert cal.method == "auto" and cal.settings["method"] == "auto" and cal.model.kind in ("bspline", "hybrid")
    assert cal.settings["chosen"] == "bspline" or cal.settings["chosen"].startswith("hybrid-")
    assert d.model_choice.chosen == cal.settings["chosen"]
    design = d.extra["design"]
    assert design["rank"] == design["n_controls"] and design["zero_columns"] >= 0
    assert d.solver.status in ("converged", "stalled") and d.solver.iterations > 0
    scored = [c for c in d.extra["smoothing_curve"] if "skipped" not in c]
    assert len(scored) >= 2 and all("cv" in c and "validation" in c for c in scored)
    assert cal.settings["gauge"]["point"] is not None and cal.settings["intervals_used"]


@pytest.mark.slow
def test_gauge_holds_the_field_flat_at_the_principal_point(results):
    cal, _ = results["asymmetric"]
    field = cal.model.field
    values = gauge_rows(field, tuple(cal.settings["gauge"]["point"])) @ np.concatenate(
        [field.control[..., 0].ravel(), field.control[..., 1].ravel()])
    assert np.max(np.abs(values)) < 1e-4


@pytest.mark.slow
def test_a_lens_opencv_models_exactly_gets_that_model_and_no_field(results):
    """On OpenCV's own lens a field can only fit noise: the choice is OpenCV's
    model, written as that model, the very calibration the zhang method gives
    on the same corners."""
    cal, _ = results["radial"]
    assert cal.settings["chosen"] == "zhang" and cal.model.kind == "opencv"
    assert cal.to_json()["distortion"]["type"] == "opencv"
    assert cal.diagnostics.model_choice.summary.startswith("OpenCV 5-coefficient model")
    zhang = calibrate(synthetic("radial").train, "zhang")
    rays = np.array([[0.0, 0.0, 1.0], [0.8, -0.6, 1.0], [-1.2, 1.1, 1.0]])
    assert np.allclose(cal.project(rays), zhang.project(rays), atol=1e-9)
    assert np.isclose(cal.metrics.rmse, zhang.metrics.rmse, rtol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["asymmetric"])
def test_a_saved_calibration_keeps_what_its_covariance_needs(results, kind):
    """The regularisers, the gauge and a held field come back from the JSON
    (its settings), so a reloaded calibration's uncertainty is the fit's own."""
    cal, _ = results[kind]
    back = Calibration.from_json(cal.to_json())
    assert np.array_equal(back.model.free_mask(), cal.model.free_mask())
    assert (back.model.lambda_reg, back.model.lambda_smooth) == (cal.model.lambda_reg, cal.model.lambda_smooth)
    assert back.model.gauge_point == cal.model.gauge_point
    assert (back.model.prior()[1] != cal.model.prior()[1]).nnz == 0


def test_paper_model_without_core_reaches_the_floor():
    s = synthetic("asymmetric")
    cal = calibrate(s.train, "bspline", core="none", intervals=10, lambda_smooth=100.0)
    floor = noise_floor(0.3, cal.diagnostics.solver.n_unknowns, cal.metrics.n_points)
    assert cal.model.kind == "bspline" and cal.metrics.rmse_axis <= 1.05 * floor
    assert evaluate(cal, s.holdout)["rmse"] < 0.2


@pytest.mark.slow
def test_a_field_that_cannot_follow_the_lens_says_so_and_the_default_can():
    """A wide lens on few views through the paper's pinhole base (asked for:
    "auto" would leave it for this lens) on a coarse grid: the field walks the camera to a wrong focal length (fx 224 for a
    true 305) and fits the corners at 17 px where Kannala-Brandt reaches
    0.04 px. The fit is restarted from the parametric camera, and when that
    does no better, it says so and what to do; the default, on the same
    corners, takes Kannala-Brandt."""
    from calib_core import synth

    train = synth.generate("fisheye", sigma=0.0, n_views=6).train
    cal = calibrate(train, "bspline", outlier_sigma=0, knots="uniform", intervals=(4, 4), base="pinhole")
    restart = cal.diagnostics.restart
    assert "focal length" in restart.reason and "use method auto" in restart.warning
    assert cal.metrics.rmse <= min(restart.first.rmse, restart.restarted.rmse) + 1e-9
    assert calibrate(train, outlier_sigma=0).metrics.rmse < 0.05


@pytest.mark.slow
def test_a_large_set_decides_the_model_on_a_spread_of_views_and_fits_all():
    from calib_core import synth
    from calib_core.methods.auto import AutoSettings

    n = AutoSettings().decision_views
    s = synth.generate("radial", 0.3, 0, n_views=n + 4)
    cal = calibrate(s.train)
    assert f"decided on {n} of the {n + 4} views" in cal.diagnostics.model_choice.how
    assert len(cal.views) == n + 4 and all(v.n_points > 0 for v in cal.views)
    assert cal.model.kind == "opencv"  # OpenCV's own lens: no field pays
    assert evaluate(cal, s.holdout)["rmse"] < 0.06


def test_too_few_views_is_a_clear_error():
    s = synthetic("radial")
    for method in ("auto", "bspline"):
        with pytest.raises(DataError, match="at least 3 views"):
            calibrate(Observations(s.train.image_size, s.train.views[:2]), method)


@pytest.mark.parametrize("settings, message", [
    (dict(lambda_smooth=-1.0), "lambda_smooth"), (dict(core="quartic"), "core"),
    (dict(intervals=0), "intervals"), (dict(base="orthographic"), "base"), (dict(knotz="kde"), "unknown setting"),
])
def test_bad_settings_are_named(settings, message):
    with pytest.raises(SettingsError, match=message):
        calibrate(synthetic("radial").train, "bspline", **settings)


@pytest.mark.slow
def test_a_core_that_cannot_fit_the_corners_leaves_the_others_in_the_running(monkeypatch):
    """A lens too wide for OpenCV's 5 coefficients (here: made to fail) must not
    fail the default: that candidate drops out, the others compete."""
    import json

    import calib_core.methods.bspline as bspline_method

    real = bspline_method.fit_opencv

    def five_coefficients_diverge(data, image_size, s, progress, *nested):
        if s.n_coefficients == 5:
            raise DataError("the OpenCV model diverged on these corners")
        return real(data, image_size, s, progress, *nested)

    monkeypatch.setattr(bspline_method, "fit_opencv", five_coefficients_diverge)
    cal = calibrate(synthetic("radial").train)
    candidates = cal.diagnostics.model_choice.candidates
    assert candidates[0].validation_rmse is None and "diverged" in candidates[0].error
    assert sum(c.chosen for c in candidates) == 1 and cal.settings["chosen"] == "rational"
    json.dumps(cal.to_json(), allow_nan=False)


def test_a_set_too_small_for_a_field_gets_a_core_alone_and_names_why():
    """57 corners can barely carry the paper's field: the default does not
    take it (it is not fitted, or cannot be, or predicts left-out views far
    worse), and says why; asked
    for the field on a fine grid, the error says what to do."""
    s = synthetic("radial")
    obs = Observations(s.train.image_size, [v.subset(np.arange(len(v)) % 12 == 0) for v in s.train.views[:4]],
                       s.train.board)
    cal = calibrate(obs)
    choice = cal.diagnostics.model_choice
    paper = next(c for c in choice.candidates if c.name == "bspline")
    best = choice.chosen_candidate
    assert not paper.chosen
    assert (paper.validation_rmse is None and ("unknowns" in paper.error or "not fitted" in paper.error)
            or paper.validation_rmse > 2 * best.validation_rmse)
    with pytest.raises(DataError, match="equations for .* unknowns: add views, or use fewer knot intervals"):
        calibrate(obs, "bspline", knots="uniform", intervals=15, core="none")


@pytest.mark.slow
def test_a_field_decided_on_a_spread_of_views_is_fitted_to_every_view_from_there():
    from calib_core import synth
    from calib_core.methods.auto import AutoSettings

    n = AutoSettings().decision_views
    s = synth.generate("asymmetric", 0.3, 0, n_views=n + 4)
    cal = calibrate(s.train)
    assert cal.model.kind in ("bspline", "hybrid")  # no parametric model represents this lens
    assert len(cal.views) == n + 4 and all(v.n_points > 0 for v in cal.views)
    design = cal.diagnostics.extra["design"]  # of the fit to every view
    assert design["rank"] == design["n_controls"] and design["intervals"] == cal.settings["intervals_used"]
    assert cal.diagnostics.solver.iterations <= 10  # from where the decision left it, not from scratch
    assert cal.metrics.rmse_axis < 1.05 * noise_floor(0.3, cal.diagnostics.solver.n_unknowns, cal.metrics.n_points)
    assert evaluate(cal, s.holdout)["rmse"] < 0.08


@pytest.mark.slow
def test_a_large_wide_set_reads_every_views_rays_for_the_pinholes_reach():
    from calib_core import synth
    from calib_core.methods.auto import AutoSettings

    n = AutoSettings().decision_views
    s = synth.generate("fisheye200", 0.3, 1, n_views=n + 6)
    cal = calibrate(s.train)
    how = cal.diagnostics.model_choice.how
    assert f"decided on {n} of the {n + 6} views" in how and "past the pinhole's reach" in how
    assert cal.model.kind in ("fisheye", "hybrid") and all(v.n_points > 0 for v in cal.views)
    assert evaluate(cal, s.holdout)["rmse"] < 0.05
