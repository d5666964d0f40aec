"""The B-spline method end to end on the paper's synthetic lenses: at the noise
floor on training corners, accurate on noise-free held-out views, and honest
about what it cannot do. (The benchmark averages over seeds; these use one.)"""
import numpy as np
import pytest

from calib_core import Calibration, calibrate, evaluate
from calib_core.errors import DataError, SettingsError
from calib_core.metrics import noise_floor
from calib_core.models.bspline import gauge_rows
from calib_core.observations import Observations

from .conftest import synthetic


@pytest.fixture(scope="module")
def results():
    out = {}
    for kind in ("radial", "asymmetric", "fisheye"):
        s = synthetic(kind)
        cal = calibrate(s.train, "bspline")
        out[kind] = (cal, evaluate(cal, s.holdout))
    return out


@pytest.mark.parametrize("kind, ratio", [("radial", 1.05), ("asymmetric", 1.05), ("fisheye", 1.5)])
def test_training_error_is_at_the_noise_floor(results, kind, ratio):
    cal, _ = results[kind]
    floor = noise_floor(0.3, cal.diagnostics["solver"]["n_unknowns"], cal.metrics["n_points"])
    assert cal.metrics["rmse_axis"] <= ratio * floor
    assert cal.metrics["rmse_axis"] >= 0.9 * floor  # not fitting the noise either


@pytest.mark.parametrize("kind, limit", [("radial", 0.12), ("asymmetric", 0.12), ("fisheye", 0.12)])
def test_holdout_error_over_the_whole_image(results, kind, limit):
    _, hold = results[kind]
    assert hold["rmse"] <= limit
    assert hold["rmse_edge"] <= 1.5 * limit  # edges and corners included


def test_result_carries_diagnostics_and_settings(results):
    cal, _ = results["asymmetric"]
    d = cal.diagnostics
    assert d["design"]["rank"] == d["design"]["n_controls"] and d["design"]["zero_columns"] >= 0
    assert d["solver"]["status"] in ("converged", "stalled") and d["solver"]["iterations"] > 0
    assert d["smoothing_curve"] and all("gcv" in c for c in d["smoothing_curve"])
    assert cal.settings["gauge"]["point"] is not None and cal.settings["intervals_used"]


def test_gauge_holds_the_field_flat_at_the_principal_point(results):
    cal, _ = results["asymmetric"]
    field = cal.model.field
    values = gauge_rows(field, tuple(cal.settings["gauge"]["point"])) @ np.concatenate(
        [field.control[..., 0].ravel(), field.control[..., 1].ravel()])
    assert np.max(np.abs(values)) < 1e-4


def test_a_lens_opencv_models_exactly_gets_that_model_and_no_field(results):
    """On OpenCV's own lens a field can only fit noise: GCV keeps the core
    alone, the very calibration the zhang method gives on the same corners."""
    cal, _ = results["radial"]
    assert cal.settings["core_used"] == "zhang" and cal.model.field_held
    assert not cal.model.field.control.any()
    assert "OpenCV 5-coefficient model alone" in cal.diagnostics["core_choice"]
    zhang = calibrate(synthetic("radial").train, "zhang")
    rays = np.array([[0.0, 0.0, 1.0], [0.8, -0.6, 1.0], [-1.2, 1.1, 1.0]])
    assert np.allclose(cal.project(rays), zhang.project(rays), atol=1e-9)
    assert np.isclose(cal.metrics["rmse"], zhang.metrics["rmse"], rtol=1e-12)


@pytest.mark.parametrize("kind", ["radial", "asymmetric"])
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
    floor = noise_floor(0.3, cal.diagnostics["solver"]["n_unknowns"], cal.metrics["n_points"])
    assert cal.model.kind == "bspline" and cal.metrics["rmse_axis"] <= 1.05 * floor
    assert evaluate(cal, s.holdout)["rmse"] < 0.2


def test_corners_crossing_the_pinhole_reach_during_the_fit_are_scored():
    """A wide lens on few views: some corners cross 85° off axis while the
    paper model is fitted; the final score must use the corners it has then."""
    from calib_core import synth

    train = synth.generate("fisheye", sigma=0.0, n_views=6).train
    cal = calibrate(train, "bspline", outlier_sigma=0, knots="uniform", intervals=(4, 4))
    assert cal.metrics["rmse"] < 0.05


def test_a_large_set_decides_the_core_on_a_spread_of_views_and_fits_all():
    from calib_core import synth
    from calib_core.methods.bspline_auto import DECISION_VIEWS

    s = synth.generate("radial", 0.3, 0, n_views=DECISION_VIEWS + 4)
    cal = calibrate(s.train, "bspline")
    assert f"decided on {DECISION_VIEWS} of the {DECISION_VIEWS + 4} views" in cal.diagnostics["core_choice"]
    assert len(cal.views) == DECISION_VIEWS + 4 and all(v.n_points > 0 for v in cal.views)
    assert cal.settings["core_used"] != "none"  # OpenCV's own lens: the core pays
    assert evaluate(cal, s.holdout)["rmse"] < 0.06


def test_too_few_views_is_a_clear_error():
    s = synthetic("radial")
    with pytest.raises(DataError, match="at least 3 views"):
        calibrate(Observations(s.train.image_size, s.train.views[:2]), "bspline")


@pytest.mark.parametrize("settings, message", [
    (dict(lambda_smooth=-1.0), "lambda_smooth"), (dict(core="quartic"), "core"),
    (dict(intervals=0), "intervals"), (dict(base="orthographic"), "base"), (dict(knotz="kde"), "unknown setting"),
])
def test_bad_settings_are_named(settings, message):
    with pytest.raises(SettingsError, match=message):
        calibrate(synthetic("radial").train, "bspline", **settings)


def test_a_core_that_cannot_fit_the_corners_leaves_the_others_in_the_running(monkeypatch):
    """A lens too wide for OpenCV's 5 coefficients (here: made to fail) must not
    fail the B-spline method: that candidate drops out, the others compete."""
    import json

    import calib_core.methods.bspline as bspline_method

    real = bspline_method.fit_opencv

    def five_coefficients_diverge(data, image_size, s, progress):
        if s.n_coefficients == 5:
            raise DataError("the OpenCV model diverged on these corners")
        return real(data, image_size, s, progress)

    monkeypatch.setattr(bspline_method, "fit_opencv", five_coefficients_diverge)
    cal = calibrate(synthetic("radial").train, "bspline")
    candidates = cal.diagnostics["core_candidates"]
    assert candidates[0]["gcv"] is None and not candidates[0]["chosen"]
    assert sum(c["chosen"] for c in candidates) == 1 and cal.settings["core_used"] == "rational"
    json.dumps(cal.to_json(), allow_nan=False)


def test_a_set_too_small_for_a_field_gets_a_core_alone_and_names_why():
    """110 corners cannot carry a 15 x 15 field (677 unknowns): the default keeps a
    parametric core; asked for the field alone, the error says what to do."""
    s = synthetic("radial")
    obs = Observations(s.train.image_size, [v.subset(np.arange(len(v)) % 6 == 0) for v in s.train.views[:4]],
                       s.train.board)
    cal = calibrate(obs, "bspline", knots="uniform", intervals=15)
    fields = [c for c in cal.diagnostics["core_candidates"] if "field" in c["model"]]
    assert all(c["gcv"] is None and not c["chosen"] for c in fields) and cal.model.field_held
    with pytest.raises(DataError, match="equations for .* unknowns: add views, or use fewer knot intervals"):
        calibrate(obs, "bspline", knots="uniform", intervals=15, core="none")
