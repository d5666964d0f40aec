"""Kannala–Brandt: ``θd = θ (1 + k1 θ² + … + kn θ^(2n))`` (``formats.md``, ``fisheye``).

Internally the model sits on the equidistant base, ``xn = θ (cos φ, sin φ)``,
so that ``xd = xn · (1 + k1 |xn|² + …)``: identical to the format's pinhole
form (θ = atan r) in front of the camera, and still defined past 90° off axis,
which the initialisation of lenses beyond 180° needs.
Parameters: ``[fx, fy, cx, cy, k1 … kn]`` (skew fixed at 0, as in OpenCV).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import FormatError
from .base import ParametricModel


class FisheyeModel(ParametricModel):
    kind = "fisheye"

    def __init__(self, intrinsics, coefficients):
        super().__init__(intrinsics, coefficients)
        self.base = "equidistant"

    def _poly(self, q: np.ndarray):
        """1 + Σ k_i q^i and its derivative in q, for q = θ²."""
        k = self.coefficients
        powers = q[:, None] ** np.arange(1, len(k) + 1)  # q, q², …
        poly = 1.0 + powers @ k
        dpoly = (np.arange(1, len(k) + 1) * k * np.hstack([np.ones((len(q), 1)), powers[:, :-1]])).sum(axis=1)
        return poly, dpoly, powers

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        fx, fy, cx, cy, _ = self.intrinsics
        q = np.sum(xn * xn, axis=-1)
        poly, dpoly, powers = self._poly(q)
        xd = xn * poly[:, None]
        uv = np.stack([fx * xd[:, 0] + cx, fy * xd[:, 1] + cy], axis=-1)
        if not jacobian:
            return uv
        n, nk = len(xn), len(self.coefficients)
        m = poly[:, None, None] * np.eye(2) + 2.0 * dpoly[:, None, None] * xn[:, :, None] * xn[:, None, :]
        d_xn = np.array([fx, fy])[None, :, None] * m
        cols = np.empty((n, 2, 2 + nk), dtype=np.int64)
        vals = np.empty((n, 2, 2 + nk))
        cols[:, 0, :2], cols[:, 1, :2] = (0, 2), (1, 3)
        cols[:, :, 2:] = 4 + np.arange(nk)
        vals[:, 0, 0], vals[:, 0, 1] = xd[:, 0], 1.0
        vals[:, 1, 0], vals[:, 1, 1] = xd[:, 1], 1.0
        vals[:, 0, 2:] = fx * xn[:, :1] * powers
        vals[:, 1, 2:] = fy * xn[:, 1:] * powers
        return uv, d_xn, cols, vals

    def distortion_json(self) -> dict[str, Any]:
        return {"type": "fisheye", "coefficients": self.coefficients.tolist()}

    @classmethod
    def from_json(cls, intrinsics, distortion: dict[str, Any], base: str) -> "FisheyeModel":
        coeffs = distortion.get("coefficients")
        if not isinstance(coeffs, list) or not coeffs:
            raise FormatError("distortion.coefficients: expected a non-empty list [k1, ..., kn]")
        if base != "pinhole":
            raise FormatError("base: the fisheye distortion type is defined on the pinhole base only")
        return cls(intrinsics, coeffs)
