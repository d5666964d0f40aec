"""The JSON contract (formats.md): round trips, independent readers, clear errors."""
import json

import numpy as np
import pytest
from scipy.interpolate import NdBSpline
from scipy.spatial.transform import Rotation

from calib_core import Calibration, Observations, calibrate
from calib_core.errors import FormatError
from calib_core.observations import FORMAT

from ..conftest import synthetic


@pytest.fixture(scope="module")
def calibration():
    """The paper's model (a field on ideal pixels, no parametric core)."""
    return calibrate(synthetic("asymmetric").train, "bspline", core="none", intervals=8, lambda_smooth=100.0)


@pytest.fixture(scope="module")
def hybrid():
    """A field over OpenCV's rational core (formats.md 'hybrid')."""
    return calibrate(synthetic("radial").train, "bspline", core="rational", intervals=6, lambda_smooth=300.0)


def project_with_scipy_only(doc, view, points):
    """formats.md §2 'Projection', written from the spec with scipy alone."""
    k, d = doc["intrinsics"], doc["distortion"]
    pc = Rotation.from_rotvec(view["rvec"]).apply(points) + view["tvec"]
    xn, yn = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
    u = k["fx"] * xn + k["skew"] * yn + k["cx"]
    v = k["fy"] * yn + k["cy"]
    knots = (np.array(d["knots_u"]), np.array(d["knots_v"]))
    uv = np.column_stack([u, v])
    dx = NdBSpline(knots, np.array(d["control_x"]), 3)(uv)
    dy = NdBSpline(knots, np.array(d["control_y"]), 3)(uv)
    return np.column_stack([u + dx, v + dy])


def test_saved_calibration_projects_identically_with_scipy_alone(calibration, tmp_path):
    path = tmp_path / "cal.json"
    calibration.save(path)
    doc = json.loads(path.read_text())
    assert doc["format"] == "freecal.calibration/1" and doc["model"] == "bspline" and doc["base"] == "pinhole"
    for view_doc in doc["views"][:3]:
        pts = synthetic("asymmetric").train.view(view_doc["name"]).object_points
        ours = calibration.project(pts, view_doc["rvec"], view_doc["tvec"])
        assert np.max(np.abs(ours - project_with_scipy_only(doc, view_doc, pts))) < 1e-9


def test_saved_hybrid_projects_identically_with_opencv_and_scipy(hybrid, tmp_path):
    """formats.md 'hybrid': cv2.projectPoints for the core, NdBSpline at its pixel."""
    import cv2

    path = tmp_path / "hybrid.json"
    hybrid.save(path)
    doc = json.loads(path.read_text())
    d, k = doc["distortion"], doc["intrinsics"]
    assert d["type"] == "hybrid" and d["core"]["type"] == "opencv" and doc["base"] == "pinhole"
    camera_matrix = np.array([[k["fx"], 0, k["cx"]], [0, k["fy"], k["cy"]], [0, 0, 1.0]])
    field = d["field"]
    knots = (np.array(field["knots_u"]), np.array(field["knots_v"]))
    for view_doc in doc["views"][:3]:
        pts = synthetic("radial").train.view(view_doc["name"]).object_points
        core, _ = cv2.projectPoints(pts, np.array(view_doc["rvec"]), np.array(view_doc["tvec"]), camera_matrix,
                                    np.array(d["core"]["coefficients"]))
        p = core.reshape(-1, 2)
        expected = p + np.column_stack([NdBSpline(knots, np.array(field["control_x"]), 3)(p),
                                        NdBSpline(knots, np.array(field["control_y"]), 3)(p)])
        ours = hybrid.project(pts, view_doc["rvec"], view_doc["tvec"])
        assert np.max(np.abs(ours - expected)) < 1e-8


def test_calibration_round_trip(calibration, tmp_path):
    calibration.save(tmp_path / "a.json")
    again = Calibration.load(tmp_path / "a.json")
    pts = np.array([[0.1, 0.2, 1.0], [-1.0, 0.8, 1.2], [0.0, 0.0, 1.0]])
    assert np.allclose(again.project(pts), calibration.project(pts), atol=1e-12)
    assert again.to_json() == calibration.to_json()


def test_calibration_metrics_and_views_follow_the_spec(calibration):
    doc = calibration.to_json()
    m = doc["metrics"]
    for key in ("rmse", "rmse_axis", "rmse_center", "rmse_edge", "n_points"):
        assert key in m
    assert m["rmse"] == pytest.approx(m["rmse_axis"] * np.sqrt(2), rel=0.05)
    names = {v.name for v in synthetic("asymmetric").train.views}
    assert {v["name"] for v in doc["views"]} == names
    for v in doc["views"]:
        assert set(v) >= {"name", "rvec", "tvec", "rmse", "rmse_axis", "n_points", "outliers"}
    assert "gauge" in doc["settings"]


def test_undistort_points_inverts_distortion_to_1e6_px(calibration):
    rng = np.random.default_rng(0)
    ideal = np.column_stack([rng.uniform(150, 880, 500), rng.uniform(150, 1130, 500)])
    back = calibration.undistort_points(calibration.distort(ideal))
    assert np.max(np.abs(back - ideal)) < 1e-6


def test_observations_round_trip(tmp_path):
    obs = synthetic("radial").train
    obs.save(tmp_path / "o.json")
    again = Observations.load(tmp_path / "o.json")
    assert again.image_size == obs.image_size and len(again.views) == len(obs.views)
    for a, b in zip(again.views, obs.views, strict=True):
        assert a.name == b.name and np.array_equal(a.image_points, b.image_points) and np.array_equal(a.ids, b.ids)


def minimal():
    return {"format": FORMAT, "image_size": [640, 480], "views": [
        {"name": "a.png", "object_points": [[0, 0, 0], [1, 0, 0]], "image_points": [[1.0, 2.0], [3.0, 4.0]], "ids": [0, 1]}]}


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(format="freecal.observations/2"), "format"),
    (lambda d: d.update(image_size=[640]), "image_size"),
    (lambda d: d.update(image_size=[640, -1]), "image_size"),
    (lambda d: d.update(views=[]), "views"),
    (lambda d: d["views"][0].update(image_points=[[1.0, 2.0]]), r"views\[0\] \('a.png'\).*pair up"),
    (lambda d: d["views"][0].update(image_points=[[1.0, 2.0], [3.0, "x"]]), r"views\[0\] \('a.png'\).image_points\[1\]"),
    (lambda d: d["views"][0].update(object_points=[[0, 0], [1, 0]]), r"object_points\[0\]"),
    (lambda d: d["views"][0].update(ids=[0, 0]), "twice"),
    (lambda d: d["views"][0].update(ids=[0, -1]), "ids"),
    (lambda d: d["views"].append(dict(d["views"][0])), "appears twice"),
    (lambda d: d["views"][0].pop("name"), "name"),
])
def test_malformed_observations_name_the_field_and_view(mutate, message):
    doc = minimal()
    mutate(doc)
    with pytest.raises(FormatError, match=message):
        Observations.from_json(doc)


def test_nan_in_observations_is_rejected(tmp_path):
    path = tmp_path / "nan.json"
    path.write_text(json.dumps(minimal()).replace("3.0, 4.0", "NaN, 4.0"))
    with pytest.raises(FormatError, match="not finite"):
        Observations.load(path)


def test_unreadable_json_says_where(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"format": ')
    with pytest.raises(FormatError, match="line 1"):
        Observations.load(path)


def test_unknown_calibration_type_is_rejected(calibration):
    doc = calibration.to_json()
    doc["distortion"] = {"type": "polynomial-9000"}
    with pytest.raises(FormatError, match="unknown type"):
        Calibration.from_json(doc)


@pytest.mark.parametrize("kind", ["fisheye", "opencv"])
def test_a_parametric_calibration_with_skew_projects_as_the_format_says(calibration, kind):
    """formats.md puts skew into every type's pixels, u = fx·xd + skew·yd + cx (cv2.fisheye's alpha =
    skew / fx). A fisheye file's skew was read as 0 (3 px elsewhere, without a word) and an opencv
    file with one refused: both now project as written, their Jacobians with them, and export fitted."""
    import cv2

    from calib_core.exports.lean_fit import exact_name

    coefficients = [0.05, -0.01, 0.002, -0.001] + ([0.01] if kind == "opencv" else [])
    doc = {**calibration.to_json(), "distortion": {"type": kind, "coefficients": coefficients}, "base": "pinhole"}
    doc["intrinsics"] = {"fx": 300.0, "fy": 310.0, "cx": 512.0, "cy": 640.0, "skew": 3.0}
    cal = Calibration.from_json(doc)
    rng = np.random.default_rng(0)
    pc = np.column_stack([rng.uniform(-0.8, 0.8, (50, 2)), np.ones(50)])
    k = np.array([[300.0, 0.0, 512.0], [0.0, 310.0, 640.0], [0.0, 0.0, 1.0]])
    if kind == "fisheye":
        want = cv2.fisheye.projectPoints(pc.reshape(1, -1, 3), np.zeros(3), np.zeros(3), k, np.array(coefficients),
                                         alpha=3.0 / 300.0)[0].reshape(-1, 2)
    else:
        plain = cv2.projectPoints(pc, np.zeros(3), np.zeros(3), k, np.array(coefficients))[0].reshape(-1, 2)
        want = plain + np.column_stack([3.0 * (plain[:, 1] - 640.0) / 310.0, np.zeros(50)])
    assert np.abs(cal.project(pc) - want).max() < 1e-9
    assert Calibration.from_json(cal.to_json()).model.intrinsics[4] == 3.0  # written back as read
    np.testing.assert_allclose(cal.model.project(cal.model.rays(want)), want, atol=1e-6)  # its inverse too
    # the Jacobians the pose refits use: against finite differences
    xn = pc[:, :2]
    _, d_uv, cols, vals = cal.model.pixel_of(xn, jacobian=True)
    h = 1e-7
    for j in range(2):
        step = np.zeros(2)
        step[j] = h
        numeric = (cal.model.pixel_of(xn + step) - cal.model.pixel_of(xn - step)) / (2 * h)
        assert np.abs(d_uv[:, :, j] - numeric).max() < 1e-4
    params = cal.model.params()
    for col in range(len(params)):
        step = np.zeros(len(params))
        step[col] = h
        numeric = (cal.model.with_params(params + step).pixel_of(xn) - cal.model.with_params(params - step).pixel_of(xn)) / (2 * h)
        analytic = np.where(cols == col, vals, 0.0).sum(axis=2)
        assert np.abs(analytic - numeric).max() < 1e-3 * max(1.0, np.abs(numeric).max())
    assert exact_name(cal) is None  # OpenCV's consumers have no skew: an export is fitted


def test_a_corners_vnl_cell_that_is_no_number_is_named_in_words():
    from calib_core.board import BoardSpec
    from calib_core.imports.mrcal_corners import read_corners_vnl

    rows = "".join(f"a.png {10 * c + 5} {10 * r + 5} 0\n" for r in range(3) for c in range(3)).replace("25 0\n", "abc 0\n", 1)
    with pytest.raises(FormatError) as err:
        read_corners_vnl("# filename x y level\n" + rows, BoardSpec.parse("chessboard:3x3:10mm"), (100, 100))
    assert "'abc' is no number" in str(err.value) and "np." not in str(err.value)
