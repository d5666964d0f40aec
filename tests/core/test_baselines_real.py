"""Baselines on real corners: ``zhang`` must reproduce cv2.calibrateCamera.

Corners come from cv2.findChessboardCornersSB here (a test helper), so the
test does not depend on the project's detector."""
from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from calib_core import Calibration, calibrate
from calib_core.observations import Observations, View

from ..conftest import shared_data


@functools.cache
def stereo_left() -> Observations:
    folder = shared_data("opencv-stereo-9x6")
    cols, rows = 9, 6
    obj = np.zeros((rows * cols, 3))
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * 25.0
    views, size = [], None
    for path in sorted(folder.glob("left*.jpg")):
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        ok, corners = cv2.findChessboardCornersSB(img, (cols, rows), flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        if ok:
            views.append(View(path.name, obj.copy(), corners.reshape(-1, 2).astype(np.float64), np.arange(rows * cols)))
        size = (img.shape[1], img.shape[0])
    return Observations(size, views, {"type": "chessboard", "cols": cols, "rows": rows, "square_size": 25.0, "units": "mm"})


@pytest.mark.slow
def test_zhang_matches_cv2_calibrate_camera_on_the_same_corners():
    obs = stereo_left()
    assert len(obs.views) >= 10
    cal = calibrate(obs, "zhang", outlier_sigma=0)
    obj = [v.object_points.astype(np.float32) for v in obs.views]
    img = [v.image_points.astype(np.float32) for v in obs.views]
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 1000, 1e-15)  # OpenCV's default (30 its) stops early
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, img, obs.image_size, None, None, criteria=criteria)
    # cv2 projects float32 corners; our rmse is over float64 copies of the same values.
    assert abs(cal.metrics.rmse - rms) < 1e-6
    fx, fy, cx, cy, _ = cal.model.intrinsics
    assert np.allclose([fx, fy, cx, cy], [k[0, 0], k[1, 1], k[0, 2], k[1, 2]], rtol=1e-5)
    assert np.allclose(cal.model.coefficients, dist.ravel()[:5], atol=1e-4)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rational", "fisheye", "tps", "mls"])
def test_every_baseline_converges_on_real_corners(method):
    obs = stereo_left()
    cal = calibrate(obs, method)
    assert cal.diagnostics.solver.status in ("converged", "stalled")
    assert cal.metrics.rmse < 0.5  # corners of a mild lens at sub-pixel accuracy
    back = Calibration.from_json(cal.to_json())
    pts = np.array([[0.0, 0.0, 500.0], [100.0, -50.0, 600.0]])
    assert np.allclose(back.project(pts), cal.project(pts), atol=1e-9)
