"""ROS ``camera_info`` YAML (the ``camera_calibration_parsers`` layout:
``image_width``, ``image_height``, ``camera_name``, ``camera_matrix``,
``distortion_model``, ``distortion_coefficients``, ``rectification_matrix``,
``projection_matrix``, each matrix as ``rows``, ``cols``, ``data``).

ROS knows three distortion models: ``plumb_bob`` (OpenCV, 5 coefficients),
``rational_polynomial`` (OpenCV, 8) and ``equidistant`` (Kannala–Brandt, 4, as
``cv2.fisheye``). The projection matrix P is a rectified camera of the
exported model (``products.rectify``: by default ``alpha = 0``, valid pixels
only, like ROS's own calibrator, with its fallback where the model folds over
inside the photo), the rectification matrix the identity (monocular).
"""
from __future__ import annotations

import numpy as np

from ..errors import SettingsError
from ..products.rectify import RectifiedCamera, rectified_camera
from .lean_fit import LeanFit
from .text import fit_note, numbers

ROS_MODELS = {"opencv4": "plumb_bob", "opencv5": "plumb_bob", "opencv8": "rational_polynomial", "kb4": "equidistant"}


def _matrix(name: str, m: np.ndarray) -> str:
    rows, cols = m.shape
    return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: {numbers(m)}\n"


def ros_yaml(fit: LeanFit, camera_name: str = "freecal", camera: RectifiedCamera | None = None) -> str:
    """camera_info YAML of a lean fit whose model ROS knows (``ROS_MODELS``); P is
    ``camera`` (the photo's size), by default ``rectified_camera(alpha=0)``."""
    if fit.name not in ROS_MODELS:
        raise SettingsError(f"ROS camera_info has no {fit.name} model; use one of {sorted(ROS_MODELS)}")
    cal = fit.calibration
    w, h = cal.image_size
    camera = camera or rectified_camera(cal, alpha=0.0)
    if camera.size != (w, h):
        raise SettingsError(f"ROS's projection matrix is for the photo's size {w} x {h}, not {camera.width} x {camera.height}")
    fx, fy, cx, cy, _ = cal.model.intrinsics
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    P = np.hstack([camera.matrix, np.zeros((3, 1))])
    coeffs = np.asarray(fit.parametric.coefficients, dtype=np.float64)
    if fit.name == "opencv4":  # plumb_bob's five, k3 = 0: the same model exactly
        coeffs = np.append(coeffs, 0.0)
    coeffs = coeffs.reshape(1, -1)
    note = f"# rectified camera (P): {camera.note}\n" if camera.note else ""
    return (f"# {fit_note(fit)}\n" + note +
            f"image_width: {w}\nimage_height: {h}\ncamera_name: {camera_name}\n"
            + _matrix("camera_matrix", K)
            + f"distortion_model: {ROS_MODELS[fit.name]}\n"
            + _matrix("distortion_coefficients", coeffs)
            + _matrix("rectification_matrix", np.eye(3))
            + _matrix("projection_matrix", P))
