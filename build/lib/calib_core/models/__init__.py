"""Distortion models, one module each, behind the interface of ``base.py``."""
from __future__ import annotations

from .base import CameraModel
from .bspline import BSplineModel
from .fisheye import FisheyeModel
from .hybrid import HybridModel
from .mls import MLSModel
from .opencv import OpenCVModel
from .tps import TPSModel

# distortion.type → the class that reads it (``from_json(intrinsics, distortion, base)``)
MODEL_TYPES: dict[str, type[CameraModel]] = {
    "bspline": BSplineModel,
    "fisheye": FisheyeModel,
    "hybrid": HybridModel,
    "opencv": OpenCVModel,
    "tps": TPSModel,
    "mls": MLSModel,
}

__all__ = ["CameraModel", "BSplineModel", "FisheyeModel", "OpenCVModel", "TPSModel", "MLSModel", "MODEL_TYPES"]
