"""OpenCV's distortion model (``formats.md``, ``opencv``): exactly ``cv2.projectPoints``.

With r² = x² + y² on pinhole-normalised ``(x, y)``::

    radial = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
    x' = x·radial + 2 p1 x y + p2 (r² + 2x²) + s1 r² + s2 r⁴
    y' = y·radial + p1 (r² + 2y²) + 2 p2 x y + s3 r² + s4 r⁴
    (x'', y'') = tilt(τx, τy)(x', y')      (a projective 3×3 map, OpenCV's
                                           computeTiltProjectionMatrix)
    u = fx x'' + cx,  v = fy y'' + cy

Any prefix of [k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 τx τy] that OpenCV accepts
(4, 5, 8, 12 or 14 values); missing ones are zero. Skew is 0, as in OpenCV.
Parameters: ``[fx, fy, cx, cy, coefficients…]``.
"""
from __future__ import annotations

import math
from typing import Any, Self

import numpy as np
from numba import njit

from ..errors import FormatError
from .base import ParametricModel

ALLOWED_COUNTS = (4, 5, 8, 12, 14)


def tilt_matrix(tx: float, ty: float):
    """OpenCV's tilt projection matrix (3, 3) and its derivatives in τx, τy."""
    cx_, sx_, cy_, sy_ = np.cos(tx), np.sin(tx), np.cos(ty), np.sin(ty)
    rx = np.array([[1, 0, 0], [0, cx_, sx_], [0, -sx_, cx_]])
    ry = np.array([[cy_, 0, -sy_], [0, 1, 0], [sy_, 0, cy_]])
    drx = np.array([[0, 0, 0], [0, -sx_, cx_], [0, -cx_, -sx_]])
    dry = np.array([[-sy_, 0, -cy_], [0, 0, 0], [cy_, 0, -sy_]])

    def proj(rxy):
        return np.array([[rxy[2, 2], 0, -rxy[0, 2]], [0, rxy[2, 2], -rxy[1, 2]], [0, 0, 1.0]])

    def dproj(drxy):  # proj is linear in rxy apart from the constant 1
        return np.array([[drxy[2, 2], 0, -drxy[0, 2]], [0, drxy[2, 2], -drxy[1, 2]], [0, 0, 0.0]])

    rxy = ry @ rx
    drxy_x, drxy_y = ry @ drx, dry @ rx
    m = proj(rxy) @ rxy
    dm_x = dproj(drxy_x) @ rxy + proj(rxy) @ drxy_x
    dm_y = dproj(drxy_y) @ rxy + proj(rxy) @ drxy_y
    return m, dm_x, dm_y


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def _untilted(x, y, k, jacobian):  # pragma: no cover (compiled)
    """``OpenCVModel.distort_normalised`` without the tilt, point by point, each
    expression evaluated in the order of the array code below it."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8], k[9], k[10], k[11]
    n = len(x)
    out = np.empty((n, 2))
    j_p = np.empty((n if jacobian else 0, 2, 2))
    j_k = np.zeros((n if jacobian else 0, 2, 12))
    for i in range(n):
        xi, yi = x[i], y[i]
        r2 = xi * xi + yi * yi
        r4, r6 = r2 * r2, r2 * r2 * r2
        num = 1 + k1 * r2 + k2 * r4 + k3 * r6
        inv_den = 1.0 / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        radial = num * inv_den
        out[i, 0] = xi * radial + 2 * p1 * xi * yi + p2 * (r2 + 2 * xi * xi) + s1 * r2 + s2 * r4
        out[i, 1] = yi * radial + p1 * (r2 + 2 * yi * yi) + 2 * p2 * xi * yi + s3 * r2 + s4 * r4
        if not jacobian:
            continue
        d_num = k1 + 2 * k2 * r2 + 3 * k3 * r4
        d_den = k4 + 2 * k5 * r2 + 3 * k6 * r4
        d_radial = (d_num - radial * d_den) * inv_den
        dxp_dr2 = xi * d_radial + p2 + s1 + 2 * s2 * r2
        dyp_dr2 = yi * d_radial + p1 + s3 + 2 * s4 * r2
        j_p[i, 0, 0] = radial + 2 * p1 * yi + 4 * p2 * xi + 2 * xi * dxp_dr2
        j_p[i, 0, 1] = 2 * p1 * xi + 2 * yi * dxp_dr2
        j_p[i, 1, 0] = 2 * p2 * yi + 2 * xi * dyp_dr2
        j_p[i, 1, 1] = radial + 4 * p1 * yi + 2 * p2 * xi + 2 * yi * dyp_dr2
        j_k[i, 0, 0] = xi * r2 * inv_den
        j_k[i, 1, 0] = yi * r2 * inv_den
        j_k[i, 0, 1] = xi * r4 * inv_den
        j_k[i, 1, 1] = yi * r4 * inv_den
        j_k[i, 0, 4] = xi * r6 * inv_den
        j_k[i, 1, 4] = yi * r6 * inv_den
        j_k[i, 0, 5] = -xi * radial * r2 * inv_den
        j_k[i, 1, 5] = -yi * radial * r2 * inv_den
        j_k[i, 0, 6] = -xi * radial * r4 * inv_den
        j_k[i, 1, 6] = -yi * radial * r4 * inv_den
        j_k[i, 0, 7] = -xi * radial * r6 * inv_den
        j_k[i, 1, 7] = -yi * radial * r6 * inv_den
        j_k[i, 0, 2], j_k[i, 0, 3] = 2 * xi * yi, r2 + 2 * xi * xi
        j_k[i, 1, 2], j_k[i, 1, 3] = r2 + 2 * yi * yi, 2 * xi * yi
        j_k[i, 0, 8], j_k[i, 0, 9] = r2, r4
        j_k[i, 1, 10], j_k[i, 1, 11] = r2, r4
    return out, j_p, j_k


class OpenCVModel(ParametricModel):
    kind = "opencv"

    def __init__(self, intrinsics, coefficients):
        super().__init__(intrinsics, coefficients)
        if len(self.coefficients) not in ALLOWED_COUNTS:
            raise FormatError(f"distortion.coefficients: OpenCV takes 4, 5, 8, 12 or 14 values, got {len(self.coefficients)}")
        self.base = "pinhole"

    def _full(self) -> np.ndarray:
        k = np.zeros(14)
        k[: len(self.coefficients)] = self.coefficients
        return k

    def distort_normalised(self, xn: np.ndarray, jacobian: bool = False):
        """(x'', y'') (N, 2) of pinhole-normalised ``xn`` (N, 2); with ``jacobian``
        also ∂/∂xn (N, 2, 2) and ∂/∂coefficients (N, 2, 12; 14 with the tilt)."""
        if len(self.coefficients) != 14:  # no tilt: one compiled pass, the same arithmetic as below
            out, j_p, j_k = _untilted(np.ascontiguousarray(xn[:, 0]), np.ascontiguousarray(xn[:, 1]), self._full(),
                                      jacobian)
            return (out, j_p, j_k) if jacobian else out
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tx, ty = self._full()
        x, y = xn[:, 0], xn[:, 1]
        r2 = x * x + y * y
        r4, r6 = r2 * r2, r2 * r2 * r2
        num = 1 + k1 * r2 + k2 * r4 + k3 * r6
        inv_den = 1.0 / (1 + k4 * r2 + k5 * r4 + k6 * r6)
        radial = num * inv_den
        xp = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + s1 * r2 + s2 * r4
        yp = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + s3 * r2 + s4 * r4
        tilted = len(self.coefficients) == 14  # fewer: no tilt, and none to differentiate
        if tilted:
            m, dm_x, dm_y = tilt_matrix(tx, ty)
            hom = np.stack([xp, yp, np.ones_like(xp)], axis=-1) @ m.T  # (N, 3)
            w = 1.0 / hom[:, 2]
            out = hom[:, :2] * w[:, None]
        else:
            out = np.stack([xp, yp], axis=-1)
        if not jacobian:
            return out
        n = len(xn)
        # ∂(x', y')/∂r² pieces
        d_num = k1 + 2 * k2 * r2 + 3 * k3 * r4
        d_den = k4 + 2 * k5 * r2 + 3 * k6 * r4
        d_radial = (d_num - radial * d_den) * inv_den  # ∂radial/∂r²
        dxp_dr2 = x * d_radial + p2 + s1 + 2 * s2 * r2
        dyp_dr2 = y * d_radial + p1 + s3 + 2 * s4 * r2
        j_p = np.empty((n, 2, 2))  # ∂(x', y')/∂(x, y)
        j_p[:, 0, 0] = radial + 2 * p1 * y + 4 * p2 * x + 2 * x * dxp_dr2
        j_p[:, 0, 1] = 2 * p1 * x + 2 * y * dxp_dr2
        j_p[:, 1, 0] = 2 * p2 * y + 2 * x * dyp_dr2
        j_p[:, 1, 1] = radial + 4 * p1 * y + 2 * p2 * x + 2 * y * dyp_dr2
        # ∂(x', y')/∂coefficients (first 12)
        j_k = np.zeros((n, 2, 14 if tilted else 12))
        for col, coef in ((0, r2), (1, r4), (4, r6)):
            j_k[:, 0, col] = x * coef * inv_den
            j_k[:, 1, col] = y * coef * inv_den
        for col, coef in ((5, r2), (6, r4), (7, r6)):
            j_k[:, 0, col] = -x * radial * coef * inv_den
            j_k[:, 1, col] = -y * radial * coef * inv_den
        j_k[:, 0, 2], j_k[:, 0, 3] = 2 * x * y, r2 + 2 * x * x
        j_k[:, 1, 2], j_k[:, 1, 3] = r2 + 2 * y * y, 2 * x * y
        j_k[:, 0, 8], j_k[:, 0, 9] = r2, r4
        j_k[:, 1, 10], j_k[:, 1, 11] = r2, r4
        if not tilted:
            return out, j_p, j_k
        # The tilt: out = hom[:2] / hom[2], hom = M (x', y', 1).
        j_h = np.zeros((n, 2, 3))  # ∂out/∂hom
        j_h[:, 0, 0] = j_h[:, 1, 1] = w
        j_h[:, :, 2] = -out * w[:, None]
        j_t = j_h @ m[:, :2]  # ∂out/∂(x', y')
        d_xn = j_t @ j_p
        d_k = j_t @ j_k
        p3 = np.stack([xp, yp, np.ones_like(xp)], axis=-1)
        d_k[:, :, 12] = np.einsum("nij,nj->ni", j_h, p3 @ dm_x.T)
        d_k[:, :, 13] = np.einsum("nij,nj->ni", j_h, p3 @ dm_y.T)
        return out, d_xn, d_k

    def distortion_json(self) -> dict[str, Any]:
        return {"type": "opencv", "coefficients": self.coefficients.tolist()}

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        coeffs = distortion.get("coefficients")
        if not isinstance(coeffs, list) or len(coeffs) not in ALLOWED_COUNTS or not all(
            isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in coeffs
        ):  # NaN or Inf: every pixel would be NaN
            raise FormatError("distortion.coefficients: expected 4, 5, 8, 12 or 14 finite numbers "
                              "[k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4, tx, ty] (a prefix)")
        if base != "pinhole":
            raise FormatError("base: the opencv distortion type is defined on the pinhole base only")
        return cls(intrinsics, coeffs)
