"""Calibration methods: each turns observations into a fitted model and poses.

A method is a function ``fit(data, image_size, settings, progress) -> Fit``
registered in ``METHODS`` with its settings class; ``auto`` (the default)
chooses among the others by prediction of views left out. ``calibrate.py`` does the
rest (views, outliers, metrics, JSON) the same way for every method.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..fitting.solve import Data
from ..models.base import CameraModel
from .auto import AutoSettings, fit_auto
from .bspline import BSplineSettings, fit_bspline
from .common import Fit, Progress
from .fisheye import FisheyeSettings, fit_fisheye
from .opencv import OpenCVSettings, RationalSettings, fit_opencv
from .residual_fields import MLSSettings, TPSSettings, fit_mls, fit_tps

# fit(data, image_size, settings, progress): each method takes its own settings class.
Method = Callable[[Data, tuple[int, int], Any, Progress], Fit[CameraModel]]

METHODS: dict[str, tuple[Method, type]] = {
    "auto": (fit_auto, AutoSettings),
    "bspline": (fit_bspline, BSplineSettings),
    "zhang": (fit_opencv, OpenCVSettings),
    "rational": (fit_opencv, RationalSettings),
    "fisheye": (fit_fisheye, FisheyeSettings),
    "mls": (fit_mls, MLSSettings),
    "tps": (fit_tps, TPSSettings),
}
