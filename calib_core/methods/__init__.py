"""Calibration methods: each turns observations into a fitted model and poses.

A method is a function ``fit(data, image_size, settings, progress) -> Fit``
registered in ``METHODS`` with its settings class. ``calibrate.py`` does the
rest (views, outliers, metrics, JSON) the same way for every method.
"""
from __future__ import annotations

from .bspline import BSplineSettings, fit_bspline

METHODS = {
    "bspline": (fit_bspline, BSplineSettings),
}
