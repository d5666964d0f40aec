"""Kannala–Brandt: ``θd = θ (1 + k1 θ² + … + kn θ^(2n))`` (``formats.md``, ``fisheye``).

Internally the model sits on the equidistant base, ``xn = θ (cos φ, sin φ)``,
so that ``xd = xn · (1 + k1 |xn|² + …)``: identical to the format's pinhole
form (θ = atan r) in front of the camera, and still defined past 90° off axis,
which the initialisation of lenses beyond 180° needs.
Parameters: ``[fx, fy, cx, cy, k1 … kn]`` (skew fixed at 0, as in OpenCV).
"""
from __future__ import annotations

from typing import Any, Self

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

    def radial_profile(self, theta: np.ndarray):
        """θ_d(θ) = θ (1 + k1 θ² + …) and its slope dθ_d/dθ, for angles θ (N,)."""
        poly, dpoly, _ = self._poly(theta**2)
        return theta * poly, poly + 2.0 * theta**2 * dpoly

    def distort_normalised(self, xn: np.ndarray, jacobian: bool = False):
        """xd = xn · (1 + k1 |xn|² + …) (N, 2); with ``jacobian`` also ∂xd/∂xn
        (N, 2, 2) and ∂xd/∂k (N, 2, n)."""
        poly, dpoly, powers = self._poly(np.sum(xn * xn, axis=-1))
        xd = xn * poly[:, None]
        if not jacobian:
            return xd
        d_xn = poly[:, None, None] * np.eye(2) + 2.0 * dpoly[:, None, None] * xn[:, :, None] * xn[:, None, :]
        return xd, d_xn, xn[:, :, None] * powers[:, None, :]

    def distortion_json(self) -> dict[str, Any]:
        return {"type": "fisheye", "coefficients": self.coefficients.tolist()}

    def base_json(self) -> str:
        return "pinhole"  # the format's form, θ = atan r; the equidistant base is how it is computed

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        coeffs = distortion.get("coefficients")
        if not isinstance(coeffs, list) or not coeffs:
            raise FormatError("distortion.coefficients: expected a non-empty list [k1, ..., kn]")
        if base != "pinhole":
            raise FormatError("base: the fisheye distortion type is defined on the pinhole base only")
        return cls(intrinsics, coeffs)
