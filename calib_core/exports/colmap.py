"""COLMAP ``cameras.txt`` (``doc/format.rst``): one line ``CAMERA_ID MODEL
WIDTH HEIGHT PARAMS[]`` per camera, ``#`` comments ignored.

The models and their parameters (``src/colmap/sensor/models.h``):

- ``OPENCV``: fx, fy, cx, cy, k1, k2, p1, p2 (OpenCV's four-coefficient model);
- ``FULL_OPENCV``: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 (OpenCV's
  rational model; a five-coefficient one is it with k4 = k5 = k6 = 0, exactly);
- ``OPENCV_FISHEYE``: fx, fy, cx, cy, k1, k2, k3, k4 (Kannala–Brandt, θ = atan r
  of x/z: in front of the camera only).

COLMAP's pixel convention puts the centre of the top-left pixel at (0.5, 0.5)
(``doc/cameras.rst``), OpenCV's and freecal's at (0, 0): the principal point
is written half a pixel further on.
"""
from __future__ import annotations

import numpy as np

from .lean_fit import LeanFit
from .text import fit_note, number

COLMAP_MODELS = {"opencv4": "OPENCV", "opencv5": "FULL_OPENCV", "opencv8": "FULL_OPENCV", "kb4": "OPENCV_FISHEYE"}
CORNER_ORIGIN = 0.5  # COLMAP's (and nerfstudio's) pixel coordinate of the top-left pixel's centre
N_PARAMS = {"OPENCV": 4, "FULL_OPENCV": 8, "OPENCV_FISHEYE": 4}


def params(fit: LeanFit) -> tuple[str, np.ndarray]:
    """COLMAP's model name and its parameter list for a fit it can represent."""
    model = COLMAP_MODELS[fit.name]
    m = fit.parametric
    fx, fy, cx, cy, _ = m.intrinsics
    coefficients = np.zeros(N_PARAMS[model])
    coefficients[: len(m.coefficients)] = m.coefficients  # OpenCV's order is COLMAP's; padding is exact
    return model, np.concatenate([[fx, fy, cx + CORNER_ORIGIN, cy + CORNER_ORIGIN], coefficients])


def cameras_txt(fit: LeanFit, camera_id: int = 1) -> str:
    """The ``cameras.txt`` text of one camera."""
    model, values = params(fit)
    w, h = fit.image_size
    return (f"# {fit_note(fit)}\n"
            "# Camera list with one line of data per camera:\n"
            "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
            "# Number of cameras: 1\n"
            f"{camera_id} {model} {int(w)} {int(h)} " + " ".join(number(x) for x in values) + "\n")
