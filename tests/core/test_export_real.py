"""The exports on real photo sets (slow: each detects and calibrates a set):
the calibration that used to be refused now exports and rectifies, and a
B-spline calibration of a GoPro reaches mrcal and COLMAP within the error
they report."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core.exports import export
from calib_core.products.rectify import undistort_maps

from . import consumers, mrcal_run, real_sets
from .test_export_consumers import check_against

pytestmark = pytest.mark.slow


# OpenCV's ChArUco sample under ``fisheye`` folded over too, but its four views are now refused as
# degenerate before a calibration is made; its coefficients are test_rectify_fallback's CHARUCO_FISHEYE.
@pytest.mark.parametrize("name,method,distortion", [("gopro", "zhang", "plumb_bob")])
def test_ros_and_undistort_of_the_calibrations_once_refused(name, method, distortion, tmp_path, capsys):
    cal = real_sets.calibration(name, method)
    done = export(cal, "ros")
    assert done.fit.exact and "folds over" in done.camera.note
    info = consumers.ros_camera_info(done.text)
    assert info["distortion_model"] == distortion
    k, d, r, p = (info[n] for n in ("camera_matrix", "distortion_coefficients", "rectification_matrix", "projection_matrix"))
    size = tuple(cal.image_size)
    if distortion == "equidistant":
        maps = cv2.fisheye.initUndistortRectifyMap(k, d.ravel(), r, p[:, :3], size, cv2.CV_32FC1)
    else:
        maps = cv2.initUndistortRectifyMap(k, d.ravel(), r, p, size, cv2.CV_32FC1)
    # inside the rectified image every pixel has a source on the lens's principal branch: OpenCV's
    # map with ROS's P (image_proc's) agrees with freecal's and stays inside the photo
    ours = undistort_maps(cal, done.camera)
    for theirs, mine, n in zip(maps, ours, size, strict=True):
        assert np.abs(theirs - mine).max() < 2e-3 and mine.min() >= -0.5 and mine.max() <= n - 0.5
    path = tmp_path / "cal.json"
    cal.save(path)
    assert cli(["undistort", str(path), "-o", str(tmp_path / "out")]) == 0
    assert "note: " in capsys.readouterr().out


def test_a_gopro_bspline_calibration_reaches_mrcal_and_colmap_within_its_reported_error(tmp_path):
    cal = real_sets.calibration("gopro", "bspline")
    done = export(cal, "mrcal")
    assert done.fit.name == "splined" and done.fit.covered.max < 0.05
    path = tmp_path / "gopro.cameramodel"
    path.write_text(done.text)
    check_against(cal, done.fit, lambda rays: mrcal_run.project(path, rays, tmp_path)["q"])
    colmap = export(cal, "colmap")
    camera = consumers.colmap_cameras(colmap.text)[1]
    check_against(cal, colmap.fit, lambda rays: consumers.colmap_project(camera, rays))
    assert colmap.fit.covered.rms > 20 * done.fit.covered.rms  # what a lean model loses on this lens
