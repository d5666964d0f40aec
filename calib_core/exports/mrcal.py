"""mrcal ``.cameramodel``: a Python-literal dict (mrcal reads it with
``ast.literal_eval``) with ``lensmodel``, ``intrinsics`` (fx, fy, cx, cy, then
the distortion: OpenCV's coefficients in OpenCV's order, or the splined
model's control points, ``splined.py``), ``valid_intrinsics_region`` (the
covered region: the convex hull of the corners, a closed polygon in pixels),
``rt_cam_ref`` and ``extrinsics`` (the same identity pose: mrcal 2.5 names it
the first way, earlier versions the second) and ``imagersize`` [width, height].

mrcal's models that freecal writes: ``LENSMODEL_OPENCV4/5/8/12`` (exact for an
OpenCV calibration with that many coefficients) and
``LENSMODEL_SPLINED_STEREOGRAPHIC_…`` (fitted to anything else). mrcal has no
tilted (14-coefficient) OpenCV model and no Kannala–Brandt model.
"""
from __future__ import annotations

import ast
from typing import Any

import numpy as np

from ..errors import SettingsError
from .lean_fit import LeanFit
from .splined import SplinedStereographic
from .text import fit_note

MRCAL_MODELS = {"opencv4": "LENSMODEL_OPENCV4", "opencv5": "LENSMODEL_OPENCV5",
                "opencv8": "LENSMODEL_OPENCV8", "opencv12": "LENSMODEL_OPENCV12",
                "splined": "LENSMODEL_SPLINED_STEREOGRAPHIC"}


def lensmodel(fit: LeanFit) -> str:
    """The full lensmodel string (with the splined model's configuration)."""
    return fit.model.lensmodel if isinstance(fit.model, SplinedStereographic) else MRCAL_MODELS[fit.name]


def cameramodel(fit: LeanFit) -> str:
    """The ``.cameramodel`` text of a fit mrcal can represent (``MRCAL_MODELS``)."""
    if fit.name not in MRCAL_MODELS:
        raise SettingsError(f"mrcal has no {fit.name} lens model; one of {sorted(MRCAL_MODELS)}")
    if isinstance(fit.model, SplinedStereographic):
        values = fit.model.intrinsics
    else:
        m = fit.parametric
        values = np.concatenate([m.intrinsics[:4], np.asarray(m.coefficients, dtype=np.float64)])
    w, h = fit.image_size
    nums = ", ".join(f"{float(x):.17g}" for x in values)
    head = f"# {fit_note(fit)}\n"
    region = ""
    if fit.region is not None:
        closed = np.vstack([fit.region, fit.region[:1]])
        region = ("    # the region the calibration's corners covered (their convex hull), pixels\n"
                  "    'valid_intrinsics_region': [\n"
                  + "".join(f"        [ {x:.17g}, {y:.17g} ],\n" for x, y in closed) + "    ],\n")
    return (head + "{\n"
            f"    'lensmodel': '{lensmodel(fit)}',\n"
            "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n"
            f"    'intrinsics': [ {nums} ],\n"
            + region +
            "    'rt_cam_ref': [ 0, 0, 0, 0, 0, 0 ],\n"
            "    'extrinsics': [ 0, 0, 0, 0, 0, 0 ],  # the same, for mrcal < 2.5\n"
            f"    'imagersize': [ {int(w)}, {int(h)} ],\n"
            "}\n")


def read_cameramodel(text: str) -> dict[str, Any]:
    """Parse the text the way mrcal does (``ast.literal_eval``, comments dropped first)."""
    body = "\n".join(line.split("#", 1)[0] for line in text.splitlines())
    return ast.literal_eval(body)
