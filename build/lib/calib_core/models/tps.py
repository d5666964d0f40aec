"""Thin-plate-spline residual field (baseline ``tps``), on an OpenCV core.

JSON (``distortion``)::

    {"type": "tps", "parametric": {"type": "opencv", "coefficients": [...]},
     "centers": [[u, v], ...],          # M pixels
     "scale": S,                         # pixels: distances are measured in units of S
     "weights_x": [...], "weights_y": [...],          # M each
     "affine_x": [a0, a1, a2], "affine_y": [b0, b1, b2],
     "smoothing": λ}                     # recorded; not needed to project

At the parametric pixel ``p = (u, v)``::

    f_x(p) = a0 + a1 u/S + a2 v/S + Σ_i weights_x[i] φ(|p − c_i| / S),
    φ(r) = r² ln r  (φ(0) = 0),  f_y likewise;  distorted pixel = p + f(p).
"""
from __future__ import annotations

from typing import Any, Self

import numpy as np
from numba import njit

from .residual_field import ResidualFieldModel, float_array, positive


@njit(cache=True, nogil=True, error_model="numpy")
def kernel_matrix(p, centers, scale):  # pragma: no cover (compiled)
    """φ(|p_a − c_i| / S) (N, M), φ(r) = r² ln r = ½ r² ln r², 0 at r = 0."""
    out = np.empty((len(p), len(centers)))
    inv = 1.0 / scale
    for a in range(len(p)):
        for i in range(len(centers)):
            du, dv = (p[a, 0] - centers[i, 0]) * inv, (p[a, 1] - centers[i, 1]) * inv
            r2 = du * du + dv * dv
            out[a, i] = 0.5 * r2 * np.log(r2) if r2 > 0.0 else 0.0
    return out


def affine_basis(p: np.ndarray, scale: float) -> np.ndarray:
    """[1, u/S, v/S] (N, 3)."""
    return np.column_stack([np.ones(len(p)), p / scale])


@njit(cache=True, nogil=True, error_model="numpy")
def _evaluate(p, centers, weights, affine, scale):  # pragma: no cover (compiled)
    """Offsets (N, 2) and gradients ∂f/∂p (N, 2, 2) at pixels ``p``: one pass
    over the N × M point-centre pairs, no (N, M) temporaries (a hold-out set of
    50 000 corners against 600 centres: 1.1 s in numpy, a fraction compiled).
    With d = (p − c)/S and r² = |d|²: φ = ½ r² ln r², ∂φ/∂p = (ln r² + 1) d / S."""
    n, m = len(p), len(centers)
    off = np.empty((n, 2))
    grad = np.empty((n, 2, 2))
    inv = 1.0 / scale
    for a in range(n):
        fx = fy = 0.0
        gxu = gxv = gyu = gyv = 0.0
        for i in range(m):
            du = (p[a, 0] - centers[i, 0]) * inv
            dv = (p[a, 1] - centers[i, 1]) * inv
            r2 = du * du + dv * dv
            if r2 > 0.0:
                lg = np.log(r2)
                phi = 0.5 * r2 * lg
                g = lg + 1.0
                wx, wy = weights[i, 0], weights[i, 1]
                fx += wx * phi
                fy += wy * phi
                gxu += wx * g * du
                gxv += wx * g * dv
                gyu += wy * g * du
                gyv += wy * g * dv
        u, v = p[a, 0] * inv, p[a, 1] * inv
        off[a, 0] = fx + affine[0, 0] + affine[1, 0] * u + affine[2, 0] * v
        off[a, 1] = fy + affine[0, 1] + affine[1, 1] * u + affine[2, 1] * v
        grad[a, 0, 0] = (gxu + affine[1, 0]) * inv
        grad[a, 0, 1] = (gxv + affine[2, 0]) * inv
        grad[a, 1, 0] = (gyu + affine[1, 1]) * inv
        grad[a, 1, 1] = (gyv + affine[2, 1]) * inv
        if not (np.isfinite(u) and np.isfinite(v)):
            grad[a] = np.nan  # no pair term was summed: the affine part alone would look finite
    return off, grad


class TPSField:
    def __init__(self, centers, weights, affine, scale: float, smoothing: float):
        self.centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)  # (M, 2)
        self.weights = np.asarray(weights, dtype=np.float64).reshape(-1, 2)  # (M, 2)
        self.affine = np.asarray(affine, dtype=np.float64).reshape(3, 2)  # (3, 2)
        self.scale = float(scale)
        self.smoothing = float(smoothing)

    def evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 2)
        return _evaluate(p, self.centers, self.weights, self.affine, self.scale)

    def to_json(self) -> dict[str, Any]:
        return {"centers": self.centers.tolist(), "scale": self.scale,
                "weights_x": self.weights[:, 0].tolist(), "weights_y": self.weights[:, 1].tolist(),
                "affine_x": self.affine[:, 0].tolist(), "affine_y": self.affine[:, 1].tolist(),
                "smoothing": self.smoothing}


class TPSModel(ResidualFieldModel):
    kind = "tps"

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        core = cls.parametric_from_json(intrinsics, distortion, base)
        centers = float_array(distortion, "centers", (2,))
        m = len(centers)
        w = np.column_stack([float_array(distortion, "weights_x", (), m), float_array(distortion, "weights_y", (), m)])
        a = np.column_stack([float_array(distortion, "affine_x", (), 3), float_array(distortion, "affine_y", (), 3)])
        smoothing = float(distortion.get("smoothing", 0.0) or 0.0)
        return cls(core, TPSField(centers, w, a, positive(distortion, "scale"), smoothing))
