"""Rectification: point undistortion for every model type, maps against
undistort_points, and straight board lines after B-spline rectification."""
from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from calib_core.errors import SettingsError
from calib_core.evaluation.quality import geometric_quality, raw_quality
from calib_core.pipeline import calibrate
from calib_core.products.rectify import INVALID, fixed_camera, rectified_camera, rectify_image, undistort_maps
from calib_core.synth.truth import truth_calibration

from ..conftest import synthetic

# method (settings) → the distortion.type it writes
MODEL_TYPES = {("zhang", ()): "opencv", ("rational", ()): "opencv", ("fisheye", ()): "fisheye",
               ("mls", ()): "mls", ("tps", ()): "tps", ("bspline", (("core", "rational"),)): "hybrid",
               ("bspline", ()): "bspline"}


@functools.cache
def cal_of(kind: str, method: str, settings: tuple = ()):
    return calibrate(synthetic(kind).train, method, **dict(settings))


def photo_grid(cal, n: int = 15, margin: float = 2.0) -> np.ndarray:
    w, h = cal.image_size
    uu, vv = np.meshgrid(np.linspace(margin, w - 1 - margin, n), np.linspace(margin, h - 1 - margin, n))
    return np.column_stack([uu.ravel(), vv.ravel()])


@pytest.mark.parametrize("method,settings", list(MODEL_TYPES), ids=[t for t in MODEL_TYPES.values()])
def test_undistort_points_inverts_distort_to_1e6_px(method, settings):
    cal = cal_of("radial", method, settings)
    assert cal.model.kind == MODEL_TYPES[(method, settings)]
    p = photo_grid(cal)
    ideal = cal.undistort_points(p)
    ok = np.all(np.isfinite(ideal), axis=1)
    assert ok.mean() > 0.95
    assert np.abs(cal.distort(ideal[ok]) - p[ok]).max() < 1e-6
    # On the lens's principal branch: the true ray, up to the model error (< 0.5°).
    truth = truth_calibration("radial")
    r_true, r_cal = truth.rays(p[ok]), cal.rays(p[ok])
    # The two camera frames differ by the small rotation their principal points imply: align it out.
    u, _, vt = np.linalg.svd(r_cal.T @ r_true)
    angle = np.degrees(np.arccos(np.clip(np.sum((r_cal @ (u @ vt)) * r_true, axis=1), -1, 1)))
    assert np.median(angle) < 0.5 and angle.max() < 2.0  # a folded-sheet root is tens of degrees off


def test_maps_and_undistort_points_agree_to_0p01_px():
    cal = cal_of("asymmetric", "bspline")
    camera = rectified_camera(cal, alpha=0.0)
    maps = undistort_maps(cal, camera)
    w, h = cal.image_size
    # A photo whose two channels are its own pixel coordinates: the rectified image then holds the
    # source position of every rectified pixel, through the same remap a user's photo goes through.
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    rect = rectify_image(cal, np.dstack([uu, vv, np.zeros_like(uu)]), camera, maps)
    p = photo_grid(cal, 25, margin=120.0)
    ideal = cal.undistort_points(p)
    q = camera.pixels(cal.model.normalised_of_ideal(ideal))
    inside = np.all(np.isfinite(q), axis=1) & (q[:, 0] > 1) & (q[:, 0] < camera.width - 2) \
        & (q[:, 1] > 1) & (q[:, 1] < camera.height - 2)
    assert inside.sum() > 200
    back = np.column_stack([map_coordinates(rect[..., c], [q[inside, 1], q[inside, 0]], order=1) for c in range(2)])
    assert np.abs(back - p[inside]).max() < 0.01


def test_valid_camera_has_a_source_for_every_pixel_and_all_keeps_every_photo_pixel():
    cal = cal_of("radial", "zhang")
    valid = undistort_maps(cal, rectified_camera(cal, 0.0, size=(256, 320)))
    w, h = cal.image_size
    assert (valid[0] >= -0.5).all() and (valid[0] <= w - 0.5).all() and (valid[1] >= -0.5).all() and (valid[1] <= h - 0.5).all()
    every = rectified_camera(cal, 1.0)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1.0]])
    q = every.pixels(cal.model.normalised_of_ideal(cal.undistort_points(corners)))
    assert (q >= -1).all() and (q[:, 0] <= every.width).all() and (q[:, 1] <= every.height).all()
    assert (undistort_maps(cal, every)[0] == INVALID).any()  # outside the photo: no source
    with pytest.raises(SettingsError):
        rectified_camera(cal, 1.5)
    with pytest.raises(SettingsError):
        fixed_camera(-3.0, (10, 10))


@pytest.mark.parametrize("kind", ["radial", "asymmetric"])
def test_bspline_rectification_straightens_board_lines_to_the_noise(kind):
    obs = synthetic(kind).train
    ours = geometric_quality(cal_of(kind, "bspline"), obs, with_smoothness=False)
    truth = geometric_quality(truth_calibration(kind), obs, with_smoothness=False)
    raw = raw_quality(obs)
    assert ours["straightness"] <= 1.5 * truth["straightness"]
    assert truth["straightness"] < 0.3  # σ = 0.3 px per axis: the noise floor
    assert raw["straightness"] > 10 * truth["straightness"]
    assert ours["spacing_cv"] <= 1.5 * truth["spacing_cv"] and ours["orthogonality"] <= 1.5 * truth["orthogonality"]
