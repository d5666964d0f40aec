"""Colour maps as numpy functions (no matplotlib): the same maps the page draws.

``sequential`` (error magnitudes: dark blue → yellow, like viridis),
``diverging`` (signed offsets: blue → white → red), both (N,) → (N, 3) uint8, and
``categorical`` (one distinct colour per board view, 3D view only).
Keep the stops in sync with frontend/js/plots/colormap.js.
"""
from __future__ import annotations

import numpy as np

SEQUENTIAL = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)
DIVERGING = np.array([[33, 102, 172], [146, 197, 222], [247, 247, 247], [244, 165, 130], [178, 24, 43]], float)


def _interp(stops: np.ndarray, t: np.ndarray) -> np.ndarray:
    t = np.clip(np.nan_to_num(np.asarray(t, float), nan=0.0), 0.0, 1.0)
    x = np.linspace(0.0, 1.0, len(stops))
    return np.stack([np.interp(t, x, stops[:, c]) for c in range(3)], axis=-1).round().astype(np.uint8)


def sequential(values: np.ndarray, vmax: float) -> np.ndarray:
    """0 … vmax → dark … bright."""
    return _interp(SEQUENTIAL, np.asarray(values, float) / max(vmax, 1e-12))


def diverging(values: np.ndarray, vabs: float) -> np.ndarray:
    """−vabs … 0 … +vabs → blue … white … red."""
    return _interp(DIVERGING, 0.5 + 0.5 * np.asarray(values, float) / max(vabs, 1e-12))


def categorical(n: int) -> np.ndarray:
    """``n`` colours (n, 3) uint8 that tell views apart: hues evenly around the wheel, two lightnesses
    alternating so neighbours in the list differ even when n is large."""
    hue = np.arange(n) / max(n, 1)
    value = np.where(np.arange(n) % 2 == 0, 0.92, 0.72)
    sat = 0.75
    # HSV → RGB, vectorised (colorsys works on one colour at a time)
    k = (np.array([5.0, 3.0, 1.0])[None, :] + hue[:, None] * 6.0) % 6.0
    rgb = value[:, None] - value[:, None] * sat * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)
    return (rgb * 255).round().astype(np.uint8)
