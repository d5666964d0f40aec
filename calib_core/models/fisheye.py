"""Kannala–Brandt: ``θd = θ (1 + k1 θ² + … + kn θ^(2n))`` (``formats.md``, ``fisheye``).

Internally the model sits on the equidistant base, ``xn = θ (cos φ, sin φ)``,
so that ``xd = xn · (1 + k1 |xn|² + …)``: identical to the format's pinhole
form (θ = atan r) in front of the camera, and still defined past 90° off axis,
which the initialisation of lenses beyond 180° needs.
Parameters: ``[fx, fy, cx, cy, k1 … kn]`` (skew held: 0 in a fit, as in OpenCV).
"""
from __future__ import annotations

import math
from typing import Any, Self

import numpy as np
from numba import njit

from ..errors import FormatError
from .base import ParametricModel


class FisheyeModel(ParametricModel):
    kind = "fisheye"

    def __init__(self, intrinsics, coefficients):
        super().__init__(intrinsics, coefficients)
        self.base = "equidistant"

    def radial_profile(self, theta: np.ndarray):
        """θ_d(θ) = θ (1 + k1 θ² + …) and its slope dθ_d/dθ, for angles θ (N,):
        the distortion along the x axis, where xn = (θ, 0)."""
        theta = np.asarray(theta, dtype=np.float64)
        xd, d_xn, _ = _distorted(np.column_stack([theta, np.zeros_like(theta)]), self.coefficients, True)
        return xd[:, 0], d_xn[:, 0, 0]

    def distort_normalised(self, xn: np.ndarray, jacobian: bool = False):
        """xd = xn · (1 + k1 |xn|² + …) (N, 2); with ``jacobian`` also ∂xd/∂xn
        (N, 2, 2) and ∂xd/∂k (N, 2, n)."""
        xd, d_xn, d_k = _distorted(np.ascontiguousarray(xn, dtype=np.float64), self.coefficients, jacobian)
        return (xd, d_xn, d_k) if jacobian else xd

    def distortion_json(self) -> dict[str, Any]:
        return {"type": "fisheye", "coefficients": self.coefficients.tolist()}

    def base_json(self) -> str:
        return "pinhole"  # the format's form, θ = atan r; the equidistant base is how it is computed

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        coeffs = distortion.get("coefficients")
        if not isinstance(coeffs, list) or not coeffs or not all(  # NaN or Inf: every pixel would be NaN
                isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in coeffs):
            raise FormatError("distortion.coefficients: expected a non-empty list of finite numbers [k1, ..., kn]")
        if base != "pinhole":
            raise FormatError("base: the fisheye distortion type is defined on the pinhole base only")
        return cls(intrinsics, coeffs)


@njit(cache=True, nogil=True)
def _distorted(xn, k, jacobian):  # pragma: no cover (compiled)
    """``FisheyeModel.distort_normalised`` (with ``jacobian``, its Jacobians), point by point:
    xd = xn · poly(q), q = |xn|², ∂xd/∂xn = poly I + 2 poly'(q) xn xnᵀ,
    ∂xd/∂k_j = xn q^j."""
    n, nk = len(xn), len(k)
    xd = np.empty((n, 2))
    d_xn = np.empty((n if jacobian else 0, 2, 2))
    d_k = np.empty((n if jacobian else 0, 2, nk))
    for i in range(n):
        x, y = xn[i, 0], xn[i, 1]
        q = x * x + y * y
        poly, dpoly, power = 1.0, 0.0, 1.0  # power: q^(j-1)
        for j in range(nk):
            dpoly += (j + 1) * k[j] * power
            power *= q
            poly += k[j] * power
            if jacobian:
                d_k[i, 0, j] = x * power
                d_k[i, 1, j] = y * power
        xd[i, 0], xd[i, 1] = x * poly, y * poly
        if not jacobian:
            continue
        d_xn[i, 0, 0] = poly + 2.0 * dpoly * x * x
        d_xn[i, 0, 1] = d_xn[i, 1, 0] = 2.0 * dpoly * x * y
        d_xn[i, 1, 1] = poly + 2.0 * dpoly * y * y
    return xd, d_xn, d_k

