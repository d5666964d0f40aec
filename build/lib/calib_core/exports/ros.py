"""ROS ``camera_info`` YAML (the ``camera_calibration_parsers`` layout).

ROS knows three distortion models: ``plumb_bob`` (OpenCV, 5 coefficients),
``rational_polynomial`` (OpenCV, 8) and ``equidistant`` (Kannala–Brandt, 4, as
``cv2.fisheye``). The projection matrix P is the rectified camera of
``rectify.rectified_camera(alpha=0)`` (valid pixels only, like ROS's own
calibrator), the rectification matrix the identity (monocular).
"""
from __future__ import annotations

import numpy as np

from ..errors import SettingsError
from ..products.rectify import rectified_camera
from .lean_fit import LeanFit

ROS_MODELS = {"opencv5": "plumb_bob", "opencv8": "rational_polynomial", "kb4": "equidistant"}


def _matrix(name: str, m: np.ndarray) -> str:
    rows, cols = m.shape
    data = ", ".join(f"{float(x):.17g}" for x in m.ravel())
    return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"


def ros_yaml(fit: LeanFit, camera_name: str = "freecal") -> str:
    """camera_info YAML of a lean fit whose model ROS knows (``ROS_MODELS``)."""
    if fit.name not in ROS_MODELS:
        raise SettingsError(f"ROS camera_info has no {fit.name} model; use one of {sorted(ROS_MODELS)}")
    cal = fit.calibration
    fx, fy, cx, cy, _ = cal.model.intrinsics
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    P = np.hstack([rectified_camera(cal, alpha=0.0).matrix, np.zeros((3, 1))])
    w, h = cal.image_size
    coeffs = np.asarray(fit.model.coefficients, dtype=np.float64).reshape(1, -1)
    return (f"# freecal export: {fit.name} fitted to the calibration, fit error rms {fit.rms:.4g} px, "
            f"max {fit.max:.4g} px\n"
            f"image_width: {w}\nimage_height: {h}\ncamera_name: {camera_name}\n"
            + _matrix("camera_matrix", K)
            + f"distortion_model: {ROS_MODELS[fit.name]}\n"
            + _matrix("distortion_coefficients", coeffs)
            + _matrix("rectification_matrix", np.eye(3))
            + _matrix("projection_matrix", P))
