"""Exports load in the tools that read them and project like the calibration,
within the fit error they report."""
from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core.errors import SettingsError
from calib_core.exports import cameramodel, fit_lean, lean_yaml, opencv_yaml, read_opencv_yaml, ros_yaml
from calib_core.exports.lean_fit import LeanFitError, pole_radius, sample_grid
from calib_core.exports.mrcal import read_cameramodel
from calib_core.exports.targets import export
from calib_core.models.opencv import OpenCVModel
from calib_core.pipeline import calibrate

from ..conftest import synthetic


@functools.cache
def cal_of(kind: str, method: str, settings: tuple = ()):
    return calibrate(synthetic(kind).train, method, **dict(settings))


def check_points(cal, fit, project) -> None:
    """``project(rays (N, 3)) -> (N, 2)`` by the other tool matches cal within the reported max error,
    over the region the fit covers (the corners' hull the calibration recorded)."""
    hull = cal.diagnostics.coverage_hull
    u, v, rays, ok = sample_grid(cal, covered=np.asarray(hull) if hull else None)
    target = cal.project(rays[ok])
    err = np.linalg.norm(project(rays[ok]) - target, axis=1)
    assert err.max() <= fit.max + 1e-6
    assert np.sqrt(np.mean(err ** 2)) == pytest.approx(fit.rms, rel=1e-3, abs=1e-6)


def cv_project(k, d):
    return lambda rays: cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, d)[0].reshape(-1, 2)


def test_parametric_calibration_exports_exactly():
    cal = cal_of("radial", "zhang")
    doc = read_opencv_yaml(opencv_yaml(cal))
    assert doc["image_size"] == tuple(cal.image_size) and doc["distortion_model"] == "opencv"
    u, v, rays, ok = sample_grid(cal)
    got = cv_project(doc["camera_matrix"], doc["distortion_coefficients"])(rays[ok])
    assert np.abs(got - cal.project(rays[ok])).max() < 1e-6
    assert opencv_yaml(cal_of("asymmetric", "bspline")) is None  # not parametric: use a lean fit


@pytest.mark.slow
def test_the_default_on_opencvs_lens_exports_its_model_exactly():
    """On OpenCV's own lens the default keeps OpenCV's model, as that model:
    its YAML is that model, exactly."""
    cal = cal_of("radial", "auto")
    assert cal.model.kind == "opencv"
    doc = read_opencv_yaml(opencv_yaml(cal))
    assert doc["distortion_model"] == "opencv" and len(doc["distortion_coefficients"]) == 5
    u, v, rays, ok = sample_grid(cal)
    got = cv_project(doc["camera_matrix"], doc["distortion_coefficients"])(rays[ok])
    assert np.abs(got - cal.project(rays[ok])).max() < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("name, kind, core", [("opencv8", "radial", "rational"), ("kb4", "fisheye", "fisheye")])
def test_lean_fit_opencv_yaml_projects_within_its_fit_error(name, kind, core):
    # (OpenCV's 8 coefficients fitted to the field over Kannala-Brandt divide by zero on a ring of its corners:
    # refused, test_a_fitted_rational_model_with_a_pole_in_the_image_is_never_exported)
    cal = cal_of(kind, "bspline", (("core", core),))
    fit = fit_lean(cal, name)
    assert fit.error_map.shape == (len(fit.v), len(fit.u)) and fit.rms < 5.0
    doc = read_opencv_yaml(lean_yaml(fit, cal))
    k, d = doc["camera_matrix"], doc["distortion_coefficients"]
    if name == "kb4":
        assert doc["distortion_model"] == "fisheye"
        check_points(cal, fit, lambda r: cv2.fisheye.projectPoints(r.reshape(1, -1, 3), np.zeros(3), np.zeros(3), k, d)[0].reshape(-1, 2))
    else:
        check_points(cal, fit, cv_project(k, d))


def test_pole_radius_finds_where_the_rational_denominator_vanishes():
    k = np.zeros(8)
    k[5] = -3.0  # 1 - 3 r²: zero at r² = 1/3
    model = OpenCVModel([500, 500, 320, 240, 0], k)
    assert pole_radius(model, 1.0) == pytest.approx(np.sqrt(1 / 3))
    assert pole_radius(model, 0.3) is None  # beyond the image's rays
    assert pole_radius(OpenCVModel([500, 500, 320, 240, 0], np.zeros(5)), 1e9) is None  # no denominator
    k[5:8] = [0.1, 0.2, 0.3]  # no positive root
    assert pole_radius(OpenCVModel([500, 500, 320, 240, 0], k), 1e9) is None


@pytest.mark.slow  # a field calibration, then three lean fits: about 8 s
def test_a_fitted_rational_model_with_a_pole_in_the_image_is_never_exported(tmp_path):
    """The freeform lens (seed 3), its field over the rational core: every opencv8 fit's denominator
    vanished on a ring 180 px from the principal point, inside the corners, and the file was
    written with 'max 5.64 px' where cv2.projectPoints was 7e12 px off next to the ring (the grid
    of samples stepped over it)."""
    cal = calibrate(synthetic("freeform", seed=3).train, "bspline", core="rational")
    with pytest.raises(LeanFitError, match="divides by zero inside the corners' region .* export as opencv5 or kb4"):
        fit_lean(cal, "opencv8")
    done = export(cal, "opencv")  # the choice among the target's candidates passes over it
    assert done.fit.name == "kb4" and [f.name for f in done.tried] == ["kb4"]
    doc = read_opencv_yaml(done.text)
    check_points(cal, done.fit, lambda r: cv2.fisheye.projectPoints(r.reshape(1, -1, 3), np.zeros(3), np.zeros(3),
                                                                     doc["camera_matrix"],
                                                                     doc["distortion_coefficients"])[0].reshape(-1, 2))


def test_a_kannala_brandt_calibration_exports_to_the_rational_model_within_hundredths_of_a_pixel():
    """The synthetic fisheye lens, as Kannala-Brandt: OpenCV's rational model describes it
    over the corners to noise level, and the lean fit finds that (from zero coefficients it
    stopped at 40 px rms)."""
    fit = fit_lean(cal_of("fisheye", "fisheye"), "opencv8")
    assert fit.rms < 0.02 and fit.max < 0.2


@pytest.mark.slow
def test_ros_and_mrcal_exports_load_and_project_within_fit_error(tmp_path):
    cal = cal_of("radial", "bspline", (("core", "rational"),))
    fit = fit_lean(cal, "opencv8", covered=np.concatenate([v.image_points for v in synthetic("radial").train.views]))
    path = tmp_path / "camera_info.yaml"
    path.write_text(ros_yaml(fit))
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # ROS's YAML has no %YAML header; OpenCV reads it
    k = np.array([fs.getNode("camera_matrix").getNode("data").at(i).real() for i in range(9)]).reshape(3, 3)
    d = np.array([fs.getNode("distortion_coefficients").getNode("data").at(i).real() for i in range(8)])
    assert fs.getNode("distortion_model").string() == "rational_polynomial"
    u, v, rays, ok = sample_grid(cal)
    assert np.abs(cv_project(k, d)(rays[ok]) - fit.calibration.project(rays[ok])).max() < 1e-5  # the fitted model
    model = read_cameramodel(cameramodel(fit))
    assert model["lensmodel"] == "LENSMODEL_OPENCV8" and model["imagersize"] == list(cal.image_size)
    i = np.array(model["intrinsics"])
    kk = np.array([[i[0], 0, i[2]], [0, i[1], i[3]], [0, 0, 1]])
    assert np.abs(cv_project(kk, i[4:])(rays[ok]) - fit.calibration.project(rays[ok])).max() < 1e-6
    with pytest.raises(SettingsError):
        cameramodel(fit_lean(cal, "kb4"))  # mrcal has no Kannala–Brandt model


def test_cli_export_and_undistort(tmp_path, capsys):
    cal = cal_of("radial", "zhang")
    cal.save(tmp_path / "cal.json")
    assert cli(["export", str(tmp_path / "cal.json"), "--to", "ros", "-o", str(tmp_path / "ros.yaml")]) == 0
    assert "plumb_bob" in (tmp_path / "ros.yaml").read_text()
    assert cli(["export", str(tmp_path / "cal.json"), "--to", "mrcal", "--model", "kb4", "-o", str(tmp_path / "x")]) == 2
    assert cli(["undistort", str(tmp_path / "cal.json"), "-o", str(tmp_path / "out"), "--size", "128x160"]) == 0
    mx = cv2.imread(str(tmp_path / "out" / "map_x.tiff"), cv2.IMREAD_UNCHANGED)
    assert mx.dtype == np.float32 and mx.shape == (160, 128)
    assert np.array_equal(mx, np.load(tmp_path / "out" / "maps.npz")["map_x"])
