"""OpenCV's calibration-sample layout, written by ``cv2.FileStorage``:
``image_width``, ``image_height``, ``camera_matrix`` (3×3), ``distortion_coefficients``
(1×n), ``distortion_model`` (``opencv`` → ``cv2.projectPoints``, ``fisheye`` →
``cv2.fisheye.projectPoints``) and, when known, ``avg_reprojection_error``.

``opencv_yaml(cal)`` is the document the service's job artefacts write
(``backend/queue/artefacts.py``), for parametric calibrations as they are;
``lean_yaml(fit)`` writes a lean-model fit of any calibration and records its
fit error, so a reader knows what was lost.
"""
from __future__ import annotations

import math

import numpy as np

from ..calibration import Calibration
from .lean_fit import LeanFit, parametric_part


def _storage_string(cal: Calibration, extra: dict[str, float | str] | None = None) -> str:
    import cv2

    doc = cal.to_json()
    k = doc["intrinsics"]
    K = np.array([[k["fx"], k["skew"], k["cx"]], [0, k["fy"], k["cy"]], [0, 0, 1]], dtype=np.float64)
    fs = cv2.FileStorage("calibration.yaml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", int(cal.image_size[0]))
    fs.write("image_height", int(cal.image_size[1]))
    fs.write("distortion_model", doc["distortion"]["type"])
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.asarray(doc["distortion"]["coefficients"], dtype=np.float64).reshape(1, -1))
    if cal.metrics is not None and math.isfinite(cal.metrics.rmse):
        fs.write("avg_reprojection_error", cal.metrics.rmse)
    for key, val in (extra or {}).items():
        fs.write(key, val)
    return fs.releaseAndGetString()


def opencv_yaml(cal: Calibration) -> str | None:
    """The FileStorage YAML of a parametric calibration (see ``parametric_part``), else None."""
    parametric = parametric_part(cal)
    return None if parametric is None else _storage_string(parametric)


def lean_yaml(fit: LeanFit, source: Calibration) -> str:
    """The FileStorage YAML of a lean fit, with ``fitted_to`` and its fit errors (px) over
    the covered region (``fit_*``) and the whole image (``fit_image_*``)."""
    lean = source if fit.exact else fit.calibration
    return _storage_string(lean, {"lean_model": fit.name, "fitted_to": source.method,
                                  "fit_rms_error_px": fit.rms, "fit_max_error_px": fit.max,
                                  "fit_image_rms_error_px": fit.image.rms, "fit_image_max_error_px": fit.image.max})


def read_opencv_yaml(text_or_path: str) -> dict[str, object]:
    """Read it back with ``cv2.FileStorage``: K (3, 3), dist (n,), model, size."""
    import cv2

    memory = "\n" in text_or_path
    fs = cv2.FileStorage(text_or_path, cv2.FILE_STORAGE_READ | (cv2.FILE_STORAGE_MEMORY if memory else 0))
    out = {"camera_matrix": fs.getNode("camera_matrix").mat(),
           "distortion_coefficients": fs.getNode("distortion_coefficients").mat().ravel(),
           "distortion_model": fs.getNode("distortion_model").string(),
           "image_size": (int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))}
    fs.release()
    return out
