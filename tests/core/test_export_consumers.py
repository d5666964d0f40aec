"""Every export, read by its consumer (OpenCV, mrcal in its own venv, PyYAML
with the schema checks of ROS's and Kalibr's readers, COLMAP's and
nerfstudio's projections re-implemented from their sources in consumers.py),
projects like the calibration over the image: an exact model to 1e-9 px, a
fitted one within the error it reports, over the covered region and over the
whole image."""
from __future__ import annotations

import functools
import json

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core.exports import TARGETS, export, fit_lean
from calib_core.exports.lean_fit import sample_grid
from calib_core.exports.targets import closeness
from calib_core.pipeline import calibrate
from calib_core.products.rectify import undistort_maps

from ..conftest import synthetic
from . import consumers, mrcal_run

EXACT_PX = 1e-9
# mrcal's converters write the .cameramodel they make with 10 significant digits ({:.10g}):
# 1e-7 px is what that rounding costs, nothing of ours
MRCAL_WRITER_PX = 1e-6


@functools.cache
def cal_of(kind: str, method: str, settings: tuple = ()):
    return calibrate(synthetic(kind).train, method, **dict(settings))


@functools.cache
def opencv4_calibration():
    """An OpenCV four-coefficient calibration (Kalibr's radtan, COLMAP's OPENCV): the lean
    fit of the radial lens's zhang calibration, with the corners' hull it was fitted on."""
    source = cal_of("radial", "zhang")
    cal = fit_lean(source, "opencv4").calibration
    cal.diagnostics.coverage_hull = source.diagnostics.coverage_hull
    cal.method = "zhang"
    return cal


def rays_of(cal, fit):
    """The photo grid's rays the fit was scored on: (covered rays, covered pixels), (image rays, image pixels)."""
    hull = np.asarray(cal.diagnostics.coverage_hull) if cal.diagnostics.coverage_hull else None
    u, v, rays, covered = sample_grid(cal, covered=hull)
    _, _, _, image = sample_grid(cal, max_angle_deg=fit.reach_deg)
    pixels = np.column_stack([a.ravel() for a in np.meshgrid(u, v)])
    return (rays[covered], pixels[covered]), (rays[image], pixels[image])


def check_against(cal, fit, project) -> None:
    """The consumer's projection ``project(rays)`` against the calibration's pixels: exact
    to 1e-9 px, or within the fit error reported for each region (and equal to it)."""
    for (rays, pixels), reported in zip(rays_of(cal, fit), (fit.covered, fit.image), strict=True):
        err = np.linalg.norm(project(rays) - pixels, axis=1)
        assert np.all(np.isfinite(err)) and len(err) == reported.n
        if fit.exact:
            assert err.max() < EXACT_PX
        else:
            assert err.max() <= reported.max + 1e-6
            assert np.sqrt(np.mean(err**2)) == pytest.approx(reported.rms, rel=1e-6, abs=1e-9)


EXACT = {  # (calibration, model it is) per consumer model
    "opencv4": opencv4_calibration,
    "opencv5": lambda: cal_of("radial", "zhang"),
    "kb4": lambda: cal_of("fisheye", "fisheye"),
}


# ---- COLMAP -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("model,colmap", [("opencv4", "OPENCV"), ("opencv5", "FULL_OPENCV"), ("kb4", "OPENCV_FISHEYE")])
def test_colmap_reads_the_calibrations_own_model_exactly(model, colmap):
    cal = EXACT[model]()
    done = export(cal, "colmap")
    assert done.fit.exact and done.fit.name == model and done.consumer_model == colmap
    camera = consumers.colmap_cameras(done.text)[1]
    assert camera["model"] == colmap and (camera["width"], camera["height"]) == tuple(cal.image_size)
    check_against(cal, done.fit, lambda r: consumers.colmap_project(camera, r))


@pytest.mark.slow
def test_colmap_full_opencv_of_a_bspline_calibration_within_its_reported_error():
    cal = cal_of("radial", "bspline", (("core", "rational"),))
    done = export(cal, "colmap", "opencv8")
    assert not done.fit.exact and "fit error over the covered region" in done.text.splitlines()[0]
    camera = consumers.colmap_cameras(done.text)[1]
    assert camera["model"] == "FULL_OPENCV"
    check_against(cal, done.fit, lambda r: consumers.colmap_project(camera, r))


# ---- nerfstudio -------------------------------------------------------------------------------------
@pytest.mark.parametrize("model,camera_model", [("opencv4", "OPENCV"), ("opencv5", "OPENCV"), ("kb4", "OPENCV_FISHEYE")])
def test_nerfstudio_reads_the_calibrations_own_model_exactly(model, camera_model):
    cal = EXACT[model]()
    done = export(cal, "nerfstudio")
    meta = consumers.nerfstudio_camera(done.text)
    assert done.fit.exact and meta["camera_model"] == camera_model and (meta["w"], meta["h"]) == tuple(cal.image_size)
    assert meta["frames"] == [] and meta["freecal_export"]["exact"] is True
    check_against(cal, done.fit, lambda r: consumers.nerfstudio_project(meta, r))
    # the rays nerfstudio casts through the covered region's pixels (its own Newton steps) are the calibration's
    (_, pixels), _ = rays_of(cal, done.fit)
    a, b = consumers.nerfstudio_rays(meta, pixels), cal.rays(pixels)
    angle = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))
    assert angle.max() < 1e-9  # radians


@pytest.mark.slow
def test_nerfstudio_of_a_rational_calibration_is_fitted_within_its_error():
    """nerfstudio's OPENCV is a polynomial (k1..k4 in r²), not OpenCV's rational model:
    a rational calibration is fitted, and says how well."""
    cal = cal_of("fisheye", "rational")
    done = export(cal, "nerfstudio")
    assert not done.fit.exact and {f.name for f in done.tried} == {"opencv5", "kb4"}
    assert done.fit is min(done.tried, key=closeness)
    meta = consumers.nerfstudio_camera(done.text)
    assert meta["freecal_export"]["covered"]["max_px"] == done.fit.covered.max
    check_against(cal, done.fit, lambda r: consumers.nerfstudio_project(meta, r))


# ---- Kalibr -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("model,distortion", [("opencv4", "radtan"), ("kb4", "equidistant")])
def test_kalibr_reads_the_calibrations_own_model_exactly(model, distortion):
    cal = EXACT[model]()
    done = export(cal, "kalibr")
    cam = consumers.kalibr_camera(done.text)
    assert done.fit.exact and cam["distortion_model"] == distortion and cam["resolution"] == list(cal.image_size)
    check_against(cal, done.fit, lambda r: consumers.kalibr_project(cam, r))


@pytest.mark.slow
def test_kalibr_of_a_bspline_calibration_within_its_reported_error():
    cal = cal_of("fisheye", "bspline", (("core", "fisheye"),))
    done = export(cal, "kalibr")
    cam = consumers.kalibr_camera(done.text)
    assert not done.fit.exact and done.fit.name in ("opencv4", "kb4")
    check_against(cal, done.fit, lambda r: consumers.kalibr_project(cam, r))


def test_mrcal_from_kalibr_reads_our_radtan_camchain(tmp_path):
    cal = opencv4_calibration()
    done = export(cal, "kalibr")
    (tmp_path / "camchain.yaml").write_text(done.text)
    proc = mrcal_run.tool("mrcal-from-kalibr", "camchain.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (model,) = tmp_path.glob("*.cameramodel")
    (rays, pixels), _ = rays_of(cal, done.fit)
    got = mrcal_run.project(model, rays, tmp_path)
    assert str(got["lensmodel"]) == "LENSMODEL_OPENCV4"
    assert np.abs(got["q"] - pixels).max() < MRCAL_WRITER_PX


# ---- ROS --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("model,distortion", [("opencv4", "plumb_bob"), ("opencv5", "plumb_bob"), ("kb4", "equidistant")])
def test_ros_camera_info_schema_projection_and_rectification_map(model, distortion):
    cal = EXACT[model]()
    done = export(cal, "ros")
    assert done.fit.exact  # 4 coefficients: plumb_bob with k3 = 0 (it was fitted as rational_polynomial)
    info = consumers.ros_camera_info(done.text)
    assert info["distortion_model"] == distortion and (info["image_width"], info["image_height"]) == tuple(cal.image_size)
    k, d, r, p = (info[n] for n in ("camera_matrix", "distortion_coefficients", "rectification_matrix", "projection_matrix"))
    assert np.array_equal(r, np.eye(3)) and np.array_equal(p[:, :3], done.camera.matrix) and not p[:, 3].any()
    if distortion == "equidistant":
        def project(rays):
            return cv2.fisheye.projectPoints(rays.reshape(1, -1, 3), np.zeros(3), np.zeros(3), k, d.ravel())[0].reshape(-1, 2)
        maps = cv2.fisheye.initUndistortRectifyMap(k, d.ravel(), r, p[:, :3], tuple(cal.image_size), cv2.CV_32FC1)
    else:
        def project(rays):
            return cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, d.ravel())[0].reshape(-1, 2)
        maps = cv2.initUndistortRectifyMap(k, d.ravel(), r, p, tuple(cal.image_size), cv2.CV_32FC1)
    check_against(cal, done.fit, project)
    # image_proc's rectification (OpenCV's map with P) is freecal's, to float32 precision
    ours = undistort_maps(cal, done.camera)
    for theirs, mine in zip(maps, ours, strict=True):
        assert np.abs(theirs - mine).max() < 2e-3


def test_mrcal_from_ros_reads_our_camera_info(tmp_path):
    cal = cal_of("radial", "zhang")
    done = export(cal, "ros")
    (tmp_path / "camera_info.yaml").write_text(done.text)
    proc = mrcal_run.tool("mrcal-from-ros", "camera_info.yaml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    (model,) = tmp_path.glob("*.cameramodel")
    (rays, pixels), _ = rays_of(cal, done.fit)
    assert np.abs(mrcal_run.project(model, rays, tmp_path)["q"] - pixels).max() < MRCAL_WRITER_PX


# ---- mrcal ------------------------------------------------------------------------------------------
def mrcal_check(cal, done, tmp_path) -> dict:
    path = tmp_path / "camera.cameramodel"
    path.write_text(done.text)
    check_against(cal, done.fit, lambda rays: mrcal_run.project(path, rays, tmp_path)["q"])
    got = mrcal_run.project(path, np.array([[0.0, 0.0, 1.0]]), tmp_path)
    # the covered region, as mrcal reads it: the corners' hull, closed
    hull = np.asarray(cal.diagnostics.coverage_hull)
    region = got["region"]
    assert np.array_equal(region[0], region[-1]) and len(region) == len(hull) + 1
    assert {tuple(np.round(x, 6)) for x in region} == {tuple(np.round(x, 6)) for x in hull}
    assert list(got["imagersize"]) == list(cal.image_size)
    return got


def test_mrcal_reads_an_opencv_calibration_exactly(tmp_path):
    cal = cal_of("radial", "zhang")
    done = export(cal, "mrcal")
    assert done.fit.exact and mrcal_check(cal, done, tmp_path)["lensmodel"] == "LENSMODEL_OPENCV5"


@pytest.mark.slow
@pytest.mark.parametrize("kind,method,settings", [("asymmetric", "bspline", ()), ("fisheye", "fisheye", ()),
                                                  ("fisheye", "bspline", (("core", "fisheye"),))])
def test_bspline_hybrid_and_kannala_brandt_reach_mrcal_as_its_splined_model(kind, method, settings, tmp_path):
    cal = cal_of(kind, method, settings)
    done = export(cal, "mrcal")
    assert done.fit.name == "splined" and "splined" in {f.name for f in done.tried}  # opencv8, where it has no pole
    got = mrcal_check(cal, done, tmp_path)
    assert str(got["lensmodel"]).startswith("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=")
    assert done.fit.covered.max < 0.05  # a rich model: what it loses is far below the corners' noise


@pytest.mark.slow
def test_a_200_degree_fisheye_reaches_mrcal_within_its_image_circle(tmp_path, capsys):
    """Outside its image circle a 200° lens's calibration extrapolates rays to 176-179° off axis:
    knots spread that far left the lit disc about one interval (74 px rms over the corners'
    region, the auto choice then OpenCV's 8 coefficients, which miss 58 % of the image). The
    knots now stop 20° past the covered region, what lies beyond is counted as out of reach, and
    an exact export that cannot see past 90° says how much of the image it leaves out."""
    cal = cal_of("fisheye200", "fisheye")
    done = export(cal, "mrcal")
    assert done.fit.name == "splined" and done.fit.covered.max < 0.05
    assert done.fit.reach_deg < 150 and done.fit.n_beyond > 0
    mrcal_check(cal, done, tmp_path)
    # nerfstudio casts Kannala-Brandt rays round to θ = π: the whole lit image, exactly
    meta = consumers.nerfstudio_camera(export(cal, "nerfstudio").text)
    exact = export(cal, "nerfstudio").fit
    assert exact.exact and exact.reach_deg == 179.0 and exact.image.n > export(cal, "kalibr").fit.image.n
    check_against(cal, exact, lambda r: consumers.nerfstudio_project(meta, r))
    cal.save(tmp_path / "kb.json")
    assert cli(["export", str(tmp_path / "kb.json"), "--to", "kalibr", "-o", str(tmp_path / "camchain.yaml")]) == 0
    said = capsys.readouterr().out
    assert "exact, the calibration is this model; " in said and "lie past what this model can represent" in said


def test_the_hint_names_model_when_mrcal_has_no_such_model(tmp_path, capsys):
    cal = cal_of("fisheye", "fisheye")
    cal.save(tmp_path / "kb.json")
    assert cli(["export", str(tmp_path / "kb.json"), "--to", "mrcal", "--model", "kb4", "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--model kb4" in err and "--model" in err and "splined (LENSMODEL_SPLINED_STEREOGRAPHIC)" in err
    assert err.count("\n") == 1


@pytest.mark.slow
def test_cli_exports_every_target_and_says_what_it_lost(tmp_path, capsys):
    cal = cal_of("asymmetric", "bspline")
    cal.save(tmp_path / "cal.json")
    for name in TARGETS:
        out = tmp_path / TARGETS[name].file_name
        assert cli(["export", str(tmp_path / "cal.json"), "--to", name, "-o", str(out),
                    "--error-map", str(tmp_path / f"{name}.npz")]) == 0
        printed = capsys.readouterr().out
        assert "fit error, covered region" in printed and "fit error, whole image" in printed
        assert "the closest of" in printed and "another with --model" in printed
        with np.load(tmp_path / f"{name}.npz") as d:
            assert d["error_px"].shape == d["covered"].shape and d["image_max"] >= d["max"]
    assert json.loads((tmp_path / "transforms.json").read_text())["camera_model"] in ("OPENCV", "OPENCV_FISHEYE")


@pytest.mark.slow
def test_an_mrcal_export_without_a_covered_region_says_how_to_get_one(tmp_path, capsys):
    cal = opencv4_calibration()
    bare = type(cal)(cal.model, cal.image_size, cal.method)  # no coverage_hull recorded
    bare.save(tmp_path / "bare.json")
    assert cli(["export", str(tmp_path / "bare.json"), "--to", "mrcal", "-o", str(tmp_path / "m")]) == 0
    assert "give --observations" in capsys.readouterr().out
    assert "valid_intrinsics_region" not in (tmp_path / "m").read_text()
    obs = synthetic("radial").train
    obs.save(tmp_path / "obs.json")
    assert cli(["export", str(tmp_path / "bare.json"), "--to", "mrcal", "-o", str(tmp_path / "m2"),
                "--observations", str(tmp_path / "obs.json")]) == 0
    assert "valid_intrinsics_region" in (tmp_path / "m2").read_text()
