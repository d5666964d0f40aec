"""nerfstudio ``transforms.json``: the camera fields shared by every frame
(``nerfstudio/data/dataparsers/nerfstudio_dataparser.py``): ``camera_model``,
``fl_x``, ``fl_y``, ``cx``, ``cy``, ``w``, ``h``, ``k1``–``k4``, ``p1``, ``p2``,
and an empty ``frames`` list for the capture's poses.

nerfstudio's distortion (``cameras/camera_utils.py``, which inverts it by
Newton's method when it casts rays):

- ``OPENCV``: ``x_d = x d(r²) + 2 p1 x y + p2 (r² + 2x²)``, ``y_d = y d(r²) +
  2 p2 x y + p1 (r² + 2y²)`` with ``d = 1 + k1 r² + k2 r⁴ + k3 r⁶ + k4 r⁸``: a
  polynomial, not OpenCV's rational model, so OpenCV's four and five
  coefficient models are exact and k4 stays 0;
- ``OPENCV_FISHEYE``: the same distortion of ``θ (cos φ, sin φ)`` with no
  tangential terms: Kannala–Brandt.

Pixels are cast from ``index + 0.5`` (``Cameras.get_image_coords``), COLMAP's
convention: the principal point is written half a pixel further on.
"""
from __future__ import annotations

import json
from typing import Any

from .colmap import CORNER_ORIGIN
from .lean_fit import LeanFit
from .text import fit_note

NERFSTUDIO_MODELS = {"opencv4": "OPENCV", "opencv5": "OPENCV", "kb4": "OPENCV_FISHEYE"}


def camera_fields(fit: LeanFit) -> dict[str, Any]:
    """The camera fields of a fit nerfstudio can represent (``NERFSTUDIO_MODELS``)."""
    m = fit.parametric
    fx, fy, cx, cy, _ = m.intrinsics
    c = [float(x) for x in m.coefficients]
    w, h = fit.image_size
    out: dict[str, Any] = {"camera_model": NERFSTUDIO_MODELS[fit.name], "fl_x": float(fx), "fl_y": float(fy),
                           "cx": float(cx) + CORNER_ORIGIN, "cy": float(cy) + CORNER_ORIGIN, "w": int(w), "h": int(h)}
    if fit.name == "kb4":
        out.update(k1=c[0], k2=c[1], k3=c[2], k4=c[3], p1=0.0, p2=0.0)
    else:  # OpenCV's order: k1, k2, p1, p2[, k3]
        out.update(k1=c[0], k2=c[1], k3=c[4] if len(c) > 4 else 0.0, k4=0.0, p1=c[2], p2=c[3])
    return out


def transforms_json(fit: LeanFit) -> str:
    """``transforms.json`` with the camera fields, what freecal exported, and no frames yet."""
    doc = {**camera_fields(fit), "freecal_export": {"note": fit_note(fit), **fit.summary()}, "frames": []}
    return json.dumps(doc, indent=2) + "\n"
