"""mrcal ``.cameramodel``: a Python-literal dict (mrcal reads it with
``ast.literal_eval``) with ``lensmodel``, ``intrinsics`` (fx, fy, cx, cy, then
the distortion in OpenCV's order), ``extrinsics`` (rt_fromref; identity here)
and ``imagersize`` [width, height].

mrcal's OpenCV models are ``LENSMODEL_OPENCV4/5/8/12``; it has no tilted
(14-coefficient) OpenCV model and no Kannala–Brandt model, so those fits are
refused rather than approximated again.
"""
from __future__ import annotations

import ast
from typing import Any

import numpy as np

from ..errors import SettingsError
from .lean_fit import LeanFit

MRCAL_MODELS = {"opencv4": "LENSMODEL_OPENCV4", "opencv5": "LENSMODEL_OPENCV5",
                "opencv8": "LENSMODEL_OPENCV8", "opencv12": "LENSMODEL_OPENCV12"}


def cameramodel(fit: LeanFit) -> str:
    """The ``.cameramodel`` text of a lean fit mrcal can represent (``MRCAL_MODELS``)."""
    if fit.name not in MRCAL_MODELS:
        raise SettingsError(f"mrcal has no {fit.name} lens model; use one of {sorted(MRCAL_MODELS)}")
    m = fit.model
    values = np.concatenate([m.intrinsics[:4], np.asarray(m.coefficients, dtype=np.float64)])
    w, h = fit.calibration.image_size
    nums = ", ".join(f"{float(x):.17g}" for x in values)
    return ("# freecal export: " f"{fit.name} fitted to the calibration; fit error rms {fit.rms:.4g} px, max {fit.max:.4g} px\n"
            "{\n"
            f"    'lensmodel': '{MRCAL_MODELS[fit.name]}',\n"
            "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n"
            f"    'intrinsics': [ {nums} ],\n"
            "    # extrinsics are rt_fromref\n"
            "    'extrinsics': [ 0, 0, 0, 0, 0, 0 ],\n"
            f"    'imagersize': [ {int(w)}, {int(h)} ],\n"
            "}\n")


def read_cameramodel(text: str) -> dict[str, Any]:
    """Parse the text the way mrcal does (``ast.literal_eval``, comments dropped first)."""
    body = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
    return ast.literal_eval(body)
