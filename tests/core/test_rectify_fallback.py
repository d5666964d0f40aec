"""Rectification where the model folds over inside the photo: a default that
still gives a result (the largest rectangle of valid pixels), says so, and
never paints the folded sheet's ghosts.

The two lenses are the calibrations that used to be refused, written out: the
GoPro Hero3 set under ``zhang`` (5 coefficients: the polynomial folds back 62°
off axis, before the photo's sides) and OpenCV's ChArUco sample under
``fisheye`` (four views, as calibrated before such sets were refused as degenerate: Kannala–Brandt
coefficients that fold 28° off axis); a third folds only near the frame's corners."""
from __future__ import annotations

import numpy as np
import pytest

from backend.cli import main as cli
from calib_core import Calibration
from calib_core.fit_report import Diagnostics
from calib_core.models import FisheyeModel, OpenCVModel
from calib_core.pipeline import calibrate
from calib_core.products.rectify import covered_camera, fixed_camera, rectified_camera, undistort_maps

from ..conftest import synthetic

GOPRO_ZHANG = Calibration(
    OpenCVModel([433.7254884, 432.29100541, 494.5056528, 380.05672999, 0.0],
                [-0.23508216, 0.06178554, -0.00042355, 0.00030124, -0.0075505]),
    (1000, 750), "zhang", diagnostics=Diagnostics(coverage_hull=[[64.58, 58.58], [944.12, 58.58], [944.12, 689.05], [64.58, 689.05]]))
CHARUCO_FISHEYE = Calibration(
    FisheyeModel([458.68058508, 461.26962323, 317.87168607, 271.18819479, 0.0],
                 [0.64974082, -5.10419581, 35.81459822, -85.990675]),
    (640, 480), "fisheye", diagnostics=Diagnostics(coverage_hull=[[182.81, 80.55], [455.48, 80.55], [455.48, 373.12], [182.81, 373.12]]))
# A rational calibration of the decentred lens (seed 0) whose border folds near the frame's corners
# only: the box of the border's other unprojected points held 2 910 pixels with no source at alpha 0.
DECENTRED_RATIONAL = Calibration(
    OpenCVModel([308.008725, 304.930527, 519.801255, 625.15212, 0.0],
                [0.7447623, -0.24264038, 0.00312917, -0.00438958, -0.00492762, 0.68376454, -0.29996288, 0.01413471]),
    (1024, 1280), "rational", diagnostics=Diagnostics(coverage_hull=[[1.69, 4.45], [1022.56, 4.45], [1022.56, 1277.2],
                                                                     [1.69, 1277.2]]))
FOLDING = {"gopro-zhang": GOPRO_ZHANG, "charuco-fisheye": CHARUCO_FISHEYE, "decentred-rational": DECENTRED_RATIONAL}


def fold_radius(model) -> float:
    """The distorted radius (focal units) where the radial law stops growing: r_d(r) for
    OpenCV's polynomial, θ_d(θ) for Kannala–Brandt (tangential terms ignored: 1e-4 here)."""
    t = np.linspace(0, 3, 30001)
    k = np.asarray(model.coefficients)
    if isinstance(model, FisheyeModel):
        rd = t * (1 + sum(k[i] * t ** (2 * i + 2) for i in range(4)))
    else:
        rd = t * (1 + k[0] * t**2 + k[1] * t**4 + k[4] * t**6)
    return float(rd[: np.argmax(np.diff(rd) <= 0)].max())


def sources(cal, camera, step: int = 7):
    """Rectified pixels (N, 2) on a grid, their source pixels from the maps (N, 2)."""
    map_x, map_y = undistort_maps(cal, camera)
    vv, uu = np.mgrid[0:camera.height:step, 0:camera.width:step]
    return np.column_stack([uu.ravel(), vv.ravel()]).astype(float), np.column_stack([map_x[vv, uu].ravel(), map_y[vv, uu].ravel()])


def round_trip_angle(cal, camera, rect, src) -> np.ndarray:
    """Angle (rad) between each rectified pixel's ray and the ray its source pixel unprojects to:
    0 on the principal branch, tens of degrees on a folded sheet."""
    xn = camera.normalised(rect)
    want = np.column_stack([xn, np.ones(len(xn))])
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    got = cal.rays(src)
    return np.arccos(np.clip(np.sum(want * got, axis=1), -1.0, 1.0))


@pytest.mark.parametrize("name", list(FOLDING))
def test_the_default_is_the_largest_rectangle_of_valid_pixels_and_says_so(name):
    cal = FOLDING[name]
    camera = rectified_camera(cal)
    assert "folds over" in camera.note and "largest rectangle of valid pixels" in camera.note
    rect, src = sources(cal, camera)
    w, h = cal.image_size
    assert (src[:, 0] >= 0).all() and (src[:, 0] <= w - 1).all() and (src[:, 1] >= 0).all() and (src[:, 1] <= h - 1).all()
    assert round_trip_angle(cal, camera, rect, src).max() < 1e-6  # every source on the principal branch
    # the largest: zoomed out by 3 % (same centre) it would need pixels past the fold or the photo
    wider = fixed_camera(camera.focal * 0.97, camera.size, (camera.cx, camera.cy))
    map_x, map_y = undistort_maps(cal, wider)
    assert ((map_x < 0) | (map_x > w - 1) | (map_y < 0) | (map_y > h - 1)).any()


@pytest.mark.parametrize("name", list(FOLDING))
def test_alpha_one_keeps_every_pixel_the_model_reaches_and_no_ghost(name):
    cal = FOLDING[name]
    camera = rectified_camera(cal, alpha=1.0)
    assert "bounding box" in camera.note
    rect, src = sources(cal, camera)
    valid = src[:, 0] >= 0
    assert 0.05 < (~valid).mean() < 0.6  # past the fold: marked, not painted with the folded sheet
    # float32 maps: 1e-4 px, which near the fold is up to 1e-5 rad; a folded sheet is tens of degrees off
    assert round_trip_angle(cal, camera, rect[valid], src[valid]).max() < 1e-3
    # every photo pixel before the fold lands inside the rectified image
    w, h = cal.image_size
    uu, vv = np.meshgrid(np.linspace(0, w - 1, 40), np.linspace(0, h - 1, 30))
    pixels = np.column_stack([uu.ravel(), vv.ravel()])
    fx, fy, cx, cy, _ = cal.model.intrinsics
    before = np.hypot((pixels[:, 0] - cx) / fx, (pixels[:, 1] - cy) / fy) < 0.95 * fold_radius(cal.model)
    rays = cal.rays(pixels[before])
    q = camera.pixels(rays[:, :2] / rays[:, 2:])
    assert len(q) > 100
    assert (q >= -1).all() and (q[:, 0] <= camera.width).all() and (q[:, 1] <= camera.height).all()


@pytest.mark.parametrize("name", list(FOLDING))
def test_the_covered_crop_shows_only_the_corners_region(name):
    cal = FOLDING[name]
    camera = covered_camera(cal)
    _, src = sources(cal, camera)
    hull = np.array(cal.diagnostics.coverage_hull)
    lo, hi = hull.min(axis=0), hull.max(axis=0)
    assert (src >= lo - 0.5).all() and (src <= hi + 0.5).all()
    assert src[:, 0].max() - src[:, 0].min() > 0.9 * (hi - lo)[0] or src[:, 1].max() - src[:, 1].min() > 0.9 * (hi - lo)[1]


def test_a_lens_whose_border_encloses_a_rectangle_keeps_the_usual_camera():
    cal = calibrate(synthetic("radial").train, "zhang")
    camera = rectified_camera(cal)
    assert camera.note == "" and "note" not in camera.to_json()


@pytest.mark.slow
def test_cli_undistort_and_ros_export_give_a_result_for_a_folding_model(tmp_path, capsys):
    path = tmp_path / "gopro.json"
    GOPRO_ZHANG.save(path)
    assert cli(["undistort", str(path), "-o", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert out.count("note: ") == 1 and "largest rectangle of valid pixels" in out
    assert (tmp_path / "out" / "map_x.tiff").exists()
    assert cli(["export", str(path), "--to", "ros", "-o", str(tmp_path / "ros.yaml")]) == 0
    out = capsys.readouterr().out
    assert "exact" in out and "note: " in out
    assert cli(["export", str(path), "--to", "ros", "--focal", "300", "-o", str(tmp_path / "ros300.yaml")]) == 0
    assert "data: [300.0, 0.0, 499.5, 0.0, 0.0, 300.0, 374.5, 0.0" in (tmp_path / "ros300.yaml").read_text()
    assert cli(["export", str(path), "--to", "colmap", "--alpha", "0.5", "-o", str(tmp_path / "c.txt")]) == 2
    assert "apply to --to ros only" in capsys.readouterr().err
