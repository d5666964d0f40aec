"""Distortion models, one module each, behind the interface of ``base.py``."""
from __future__ import annotations

from .base import CameraModel
from .bspline import BSplineModel
from .fisheye import FisheyeModel

# distortion.type → the class that reads it (``from_json(intrinsics, distortion, base)``)
MODEL_TYPES: dict[str, type[CameraModel]] = {
    "bspline": BSplineModel,
    "fisheye": FisheyeModel,
}

__all__ = ["CameraModel", "BSplineModel", "FisheyeModel", "MODEL_TYPES"]
