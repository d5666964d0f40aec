"""The camera's parameters ± σ, its field of view and the verdict (``evaluation.parameters``)."""
import numpy as np
import pytest

from calib_core import Calibration, calibrate, synth
from calib_core.evaluation.parameters import (
    describe_without_corners,
    field_of_view,
    model_in_words,
    no_ray_beyond,
    parameter_table,
)
from calib_core.evaluation.uncertainty import model_covariance
from calib_core.evaluation.verdict import uncovered_regions, verdict
from calib_core.fitting.solve import Data, SolveSettings, levenberg_marquardt
from calib_core.models import FisheyeModel, HybridModel, OpenCVModel, camera
from calib_core.models.bspline_basis import BSplineField, clamped_knots
from calib_core.pipeline import to_data
from calib_core.report.tables import report_files

from ..conftest import synthetic


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "method"), [("radial", "zhang"), ("fisheye", "fisheye")])
def test_standard_deviations_match_the_spread_of_refits_on_new_noise(kind, method):
    """The ± shown next to each parameter: refit the same views with fresh noise of the
    same σ many times; each parameter's spread is what the covariance predicted."""
    sigma, rng = 0.3, np.random.default_rng(3)
    clean = synth.generate(kind, sigma=0.0, seed=0, n_views=6)
    cal = calibrate(clean.train, method, outlier_sigma=0)
    data, _, _ = to_data(clean.train)
    poses = np.array([v.pose for v in cal.views])
    truth = cal.model.project(camera.transform(poses, data.view_index, data.object_points))

    def noisy() -> Data:
        return Data(data.object_points, truth + rng.normal(0, sigma, truth.shape), data.view_index, data.n_views)

    settings = SolveSettings(ftol=1e-12, max_iterations=60)
    first = levenberg_marquardt(cal.model, poses, noisy(), settings)
    cov, est_sigma, _ = model_covariance(first.model, first.poses, noisy())
    assert abs(est_sigma - sigma) < 0.03
    refits = np.array([levenberg_marquardt(cal.model, poses, noisy(), settings).model.params() for _ in range(40)])
    ratio = np.sqrt(np.diag(cov)) / refits.std(axis=0, ddof=1)
    # 40 draws: an empirical standard deviation itself scatters ~11 %, so 0.7-1.4 is a real test
    assert np.all((ratio > 0.7) & (ratio < 1.4)), ratio
    rows = parameter_table(first.model, cov)
    assert [r["name"] for r in rows][:5] == ["fx", "fy", "cx", "cy", "skew"]
    assert rows[4]["status"] == "fixed" and rows[4]["std"] is None  # OpenCV's models have no skew
    assert rows[0]["std"] == pytest.approx(np.sqrt(cov[0, 0]))


def test_field_of_view_is_the_models_own_angle_across_the_image():
    w, h, f = 1001, 801, 400.0
    k = [f, f, (w - 1) / 2, (h - 1) / 2, 0.0]
    pinhole = Calibration(OpenCVModel(k, [0, 0, 0, 0, 0]), (w, h), "zhang")
    fov = field_of_view(pinhole)
    assert fov["horizontal"] == pytest.approx(2 * np.degrees(np.arctan(500 / f)), abs=1e-3)
    assert fov["vertical"] == pytest.approx(2 * np.degrees(np.arctan(400 / f)), abs=1e-3)
    assert fov["diagonal"] == pytest.approx(2 * np.degrees(np.arctan(np.hypot(500, 400) / f)), abs=1e-3)
    # the equidistant lens, r = f θ: past 180° across the frame, which no pinhole formula gives
    equidistant = Calibration(FisheyeModel([300.0, 300.0, (w - 1) / 2, (h - 1) / 2, 0.0], [0, 0, 0, 0]), (w, h), "fisheye")
    fov = field_of_view(equidistant)
    assert fov["horizontal"] == pytest.approx(np.degrees(1000 / 300.0), rel=1e-3) and fov["horizontal"] > 180


def test_a_model_whose_distortion_turns_back_inside_the_image_is_called_out():
    """A barrel polynomial r(1 + k1 r²) peaks at r = 1/√(−3 k1): past that pixel
    radius it maps no ray, and two rays to the pixels short of it. Where corners
    show the lens lights the image beyond it, undistorting the whole image with
    this model is wrong: the verdict says so and grades it fair at best; where
    no corner reached, it may be a circular fisheye's dark corner, and says that."""
    w, h, f, k1 = 1001, 801, 500.0, -0.5
    model = OpenCVModel([f, f, (w - 1) / 2, (h - 1) / 2, 0.0], [k1, 0, 0, 0, 0])
    cal = Calibration(model, (w, h), "zhang")
    peak = f * (2 / 3) * np.sqrt(1 / (-3 * k1))  # r_d at r = 1/√(−3 k1), in pixels
    no_ray = no_ray_beyond(cal)
    assert set(no_ray) == {"horizontal", "vertical", "diagonal"}  # 272 px: inside every line's half
    assert min(no_ray.values()) == pytest.approx(peak, abs=2.0)
    assert field_of_view(cal)["diagonal"] is None
    dark = describe_without_corners(cal)["verdict"]
    assert "right if the lens leaves them dark" in dark["text"]
    cal.diagnostics.coverage_hull = [[100.0, 100.0], [900.0, 100.0], [900.0, 700.0], [100.0, 700.0]]
    lit = describe_without_corners(cal)["verdict"]
    assert "lights the image" in lit["text"] and "Kannala-Brandt" in lit["text"] and lit["grade"] != "good"
    barrel = Calibration(OpenCVModel(model.intrinsics, [-0.05, 0, 0, 0, 0]), (w, h), "zhang")  # peaks past the image
    assert no_ray_beyond(barrel) == {} and "no ray" not in describe_without_corners(barrel)["verdict"]["text"]


def test_parameter_names_follow_the_model():
    k = [300.0, 300.0, 500.0, 400.0, 0.0]
    rational = OpenCVModel(k, np.zeros(8))
    assert [r["name"] for r in parameter_table(rational, None)][5:] == ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    assert model_in_words(rational) == "OpenCV rational model (8 coefficients)"
    knots = clamped_knots(np.linspace(0, 1000, 5)), clamped_knots(np.linspace(0, 800, 4))
    hybrid = HybridModel(FisheyeModel(k, [0.1, 0, 0, 0]), BSplineField.zeros(*knots))
    rows = parameter_table(hybrid, np.eye(hybrid.n_params))
    assert [r["name"] for r in rows] == ["fx", "fy", "cx", "cy", "skew", "k1", "k2", "k3", "k4"]
    # a hybrid holds its core's coefficients: no ± for them, and the page says why
    assert all(r["std"] is None and r["status"] == "held" and "core" in r["note"] for r in rows[5:])
    assert rows[0]["std"] == 1.0
    assert model_in_words(hybrid) == "B-spline field over the Kannala-Brandt model (k1..k4), 4 × 3 knot intervals"


def test_verdict_in_words_names_where_views_are_missing():
    covered = np.ones((9, 12), bool)
    covered[:3, :4] = False  # the top-left ninth has no corner
    inside = np.ones_like(covered)
    assert uncovered_regions(covered, inside) == ["top-left"]
    inside[:3, :4] = False  # outside the lens's image (a fisheye's black corner): nothing to advise there
    assert uncovered_regions(covered, inside) == []
    v = verdict(0.26, {"median_px": 0.03, "covered_share": 0.85, "uncovered_regions": ["top-left"]})
    assert v["text"] == ("0.26 px rms, 0.03 px projection uncertainty over the covered image: good; "
                         "add views at the top-left to cover the rest")
    assert verdict(1.6, {"median_px": 0.03, "covered_share": 0.9, "uncovered_regions": []})["grade"] == "poor"
    assert verdict(0.3, {"median_px": 0.2, "covered_share": 0.9, "uncovered_regions": []})["grade"] == "fair"


def test_the_advice_on_a_poor_fit_agrees_with_the_model_choice():
    """Three noisy views of the freeform lens: the default keeps Kannala–Brandt, which leaves
    2.9 px rms on the corners, over the paper's field, which predicted the views left out
    better but within their noise. The verdict names that field and why it was not taken,
    instead of a generic "try a model with a field"; a model that has a field is not told
    to try one, and one the user asked for is."""
    s = synth.generate("freeform", sigma=1.0, seed=8, n_views=3)
    cal = calibrate(s.train, "auto")
    text = describe_without_corners(cal)["verdict"]["text"]
    choice = cal.diagnostics.model_choice
    field = min((c for c in choice.candidates if (c.name == "bspline" or c.name.startswith("hybrid-")) and c.validation_rmse),
                key=lambda c: c.validation_rmse)
    if cal.model.kind in ("bspline", "hybrid") or field.validation_rmse >= choice.chosen_candidate.validation_rmse:
        assert "field" not in text.split("poor")[-1]
    else:
        assert f"calibrate with the {field.label}" in text and "3 views" in text
    assert "try a model with a field" not in text
    asked = calibrate(s.train, "fisheye")
    assert "try a model with a field" in describe_without_corners(asked)["verdict"]["text"]
    assert verdict(1.6, None, other_model=None)["text"] == (
        "1.60 px rms: poor; the corners are far from the model: check the board size and the photos' corners")


def test_calibration_json_carries_the_camera_block():
    """What the page and the CLI show is in the calibration JSON itself (``diagnostics.camera``)."""
    s = synthetic("radial")
    cal = calibrate(s.train, "zhang")
    doc = report_files(cal, s.train)["calibration.json"]
    cam = Calibration.from_json(doc).diagnostics.camera
    assert cam["model"] == "OpenCV model, 5 coefficients (k1, k2, p1, p2, k3)"
    assert cam["chosen"] == "as asked (method zhang)" and cam["fitted_parameters"] == 9
    fx = next(p for p in cam["parameters"] if p["name"] == "fx")
    assert fx["value"] == cal.model.intrinsics[0] and 0 < fx["std"] < 1
    truth = synth.INTRINSICS[0]
    assert abs(fx["value"] - truth) < 4 * fx["std"]  # the truth within the stated uncertainty
    assert cam["field"] is None and cam["verdict"]["grade"] in ("good", "fair")
    assert 100 < cam["field_of_view_deg"]["horizontal"] < 140  # ≈ 118° through a pinhole (synth's docstring)
    assert 0 < cam["projection_uncertainty"]["median_px"] < 0.2


def test_without_the_corners_the_parameters_are_listed_with_no_standard_deviation():
    from calib_core.report.tables import report_products

    cal = calibrate(synthetic("radial").train, "zhang")
    doc = report_products(cal)["parameters.json"]
    assert [r["name"] for r in doc["parameters"]][:4] == ["fx", "fy", "cx", "cy"]
    assert all(r["std"] is None for r in doc["parameters"]) and doc["projection_uncertainty"] is None
    assert "corners" in doc["uncertainty_error"]
