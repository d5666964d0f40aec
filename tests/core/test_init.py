"""The initial camera: a lens over the whole image, not a polynomial that folds."""
import numpy as np
import pytest

from calib_core import calibrate
from calib_core.board import BoardSpec
from calib_core.detection.detect import detect_images
from calib_core.errors import DegenerateViews
from calib_core.fitting.init import folds_inside_image, initialise
from calib_core.fitting.solve import Data
from calib_core.models import camera
from calib_core.models.fisheye import FisheyeModel
from calib_core.pipeline import to_data
from calib_core.synth.opencv_lenses import around

from ..conftest import shared_data


def rays_up_to(angle: float) -> Data:
    """Camera-frame points (identity pose) at off-axis angles up to ``angle``."""
    theta = np.linspace(0.0, angle, 20)
    pts = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    return Data(pts, np.zeros((len(pts), 2)), np.zeros(len(pts), dtype=int), 1)


@pytest.mark.parametrize("coefficients, intrinsics, size, seen, folds", [
    # an overfit on a narrow set (corners to 22°): θ_d turns back at 31°, the image corners sit at 41°
    ([0.655, -5.45, 40.1, -101.0], [471, 474, 318, 266, 0], (640, 480), 0.39, True),
    # a wide-angle action camera: monotonic over the image
    ([0.04, 0.037, -0.028, 0.007], [437, 437, 493, 379, 0], (1000, 750), 1.1, False),
    # a circular fisheye (black corners no ray reaches): data to 69°, the polynomial turns back at 77°
    ([0.0, 0.0, 0.0, -0.01], [200, 200, 640, 400, 0], (1280, 800), 1.2, False),
])
def test_a_kannala_brandt_camera_that_folds_inside_the_image_is_detected(coefficients, intrinsics, size, seen, folds):
    model = FisheyeModel(intrinsics, np.array(coefficients))
    assert folds_inside_image(model, np.zeros((1, 6)), rays_up_to(seen), size) is folds


@pytest.mark.slow
def test_a_narrow_real_set_gets_an_initial_camera_without_a_fold():
    """OpenCV's ChArUco sample (5 views, 110 corners, 22° off axis at most): all four
    Kannala–Brandt coefficients free folded the lens inside the image, and the
    paper's model, started from that camera, diverged (rmse 25 px). Its boards are
    all tilted the same way (normals within about 2°), so the focal length is not
    determined: cv2.calibrateCameraExtended gives fx 405 ± 130 px without distortion,
    467 ± 15 with five coefficients. A calibration is refused, saying what to shoot."""
    folder = shared_data("opencv-charuco-5x7")
    obs = detect_images(folder, BoardSpec.parse("charuco:5x7:40mm:20mm:DICT_6X6_250")).observations
    data, _, _ = to_data(obs)
    init = initialise(data, obs.image_size)
    assert not folds_inside_image(init.model, init.poses, data, obs.image_size)
    assert init.rmse < 0.5
    with pytest.raises(DegenerateViews, match="tilted the same way"):
        calibrate(obs, "bspline", core="none")


def test_boards_seen_up_to_100_degrees_off_axis_are_posed():
    """A ~200° lens with boards all round it: a view whose corners all lie more
    than ~80° off axis has no usable homography onto the plane Z = 1; turned
    to face it first, every view gets a pose and the initial camera fits."""
    obs = around(16, seed=0, sigma=0.2)
    data, _, _ = to_data(obs)
    init = initialise(data, obs.image_size)
    assert init.poses.shape == (16, 6) and init.rmse < 1.0
    pc = camera.transform(init.poses, data.view_index, data.object_points)
    assert np.degrees(np.arctan2(np.hypot(pc[:, 0], pc[:, 1]), pc[:, 2])).max() > 90.0
