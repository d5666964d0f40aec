"""Kalibr camchain YAML (``kalibr_common/ConfigReader.py``, wiki "Yaml
formats"): ``cam0`` with ``camera_model: pinhole``, ``intrinsics`` [fu, fv,
pu, pv], ``distortion_model`` and ``distortion_coeffs``, ``resolution`` [w, h],
``rostopic`` and ``cam_overlaps``.

Kalibr's ``pinhole-radtan`` is ``radtan`` [k1, k2, r1, r2] (OpenCV's four
coefficients), ``pinhole-equi`` is ``equidistant`` [k1, k2, k3, k4]
(Kannala–Brandt with θ = atan r of x/z, ``EquidistantDistortion.hpp``). Its
reader insists on floats for the intrinsics (``500.0``, not ``500``) and ints
for the resolution; pixels as OpenCV's (the centre of the top-left at (0, 0)).
"""
from __future__ import annotations

import json

import numpy as np

from .lean_fit import LeanFit
from .text import fit_note, numbers

KALIBR_MODELS = {"opencv4": "radtan", "kb4": "equidistant"}


def camchain_yaml(fit: LeanFit, rostopic: str = "/cam0/image_raw") -> str:
    """The camchain text of one camera (``cam0``)."""
    return f"# {fit_note(fit)}\n" + camera_entry(0, fit, rostopic)


def camera_entry(index: int, fit: LeanFit, rostopic: str, overlaps: list[int] | None = None,
                 t_cn_cnm1: np.ndarray | None = None) -> str:
    """``cam{index}``'s block of a camchain; ``t_cn_cnm1``: the 4 × 4 transform
    from the previous camera's frame into this one's (Kalibr's name), for every
    camera but the first."""
    m = fit.parametric
    fx, fy, cx, cy, _ = m.intrinsics
    w, h = fit.image_size
    text = (f"cam{index}:\n"
            "  camera_model: pinhole\n"
            f"  intrinsics: {numbers([fx, fy, cx, cy])}\n"
            f"  distortion_model: {KALIBR_MODELS[fit.name]}\n"
            f"  distortion_coeffs: {numbers(m.coefficients)}\n"
            f"  resolution: [{int(w)}, {int(h)}]\n"
            f"  cam_overlaps: [{', '.join(str(k) for k in overlaps or [])}]\n"
            f"  rostopic: {json.dumps(rostopic)}\n")  # a JSON string is a YAML one: a camera's name can't break it
    if t_cn_cnm1 is not None:
        text += "  T_cn_cnm1:\n" + "".join(f"  - {numbers(row)}\n" for row in t_cn_cnm1)
    return text
