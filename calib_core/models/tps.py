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

from typing import Any

import numpy as np

from .residual_field import ResidualFieldModel, float_array, positive

CHUNK = 4096  # evaluation rows per block: bounds memory at CHUNK × M


def kernel(r: np.ndarray) -> np.ndarray:
    """φ(r) = r² ln r, 0 at r = 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r > 0, r * r * np.log(np.where(r > 0, r, 1.0)), 0.0)


def affine_basis(p: np.ndarray, scale: float) -> np.ndarray:
    """[1, u/S, v/S] (N, 3)."""
    return np.column_stack([np.ones(len(p)), p / scale])


class TPSField:
    def __init__(self, centers, weights, affine, scale: float, smoothing: float):
        self.centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)  # (M, 2)
        self.weights = np.asarray(weights, dtype=np.float64).reshape(-1, 2)  # (M, 2)
        self.affine = np.asarray(affine, dtype=np.float64).reshape(3, 2)  # (3, 2)
        self.scale = float(scale)
        self.smoothing = float(smoothing)

    def evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        s = self.scale
        off = np.empty((len(p), 2))
        grad = np.empty((len(p), 2, 2))
        for start in range(0, len(p), CHUNK):  # blocks of points, not a loop per point
            q = p[start : start + CHUNK]
            d = (q[:, None, :] - self.centers[None]) / s  # (n, M, 2)
            r = np.linalg.norm(d, axis=-1)
            off[start : start + CHUNK] = kernel(r) @ self.weights + affine_basis(q, s) @ self.affine
            with np.errstate(divide="ignore", invalid="ignore"):
                g = np.where(r > 0, 2 * np.log(np.where(r > 0, r, 1.0)) + 1, 0.0)  # ∂φ/∂p = g (p − c)/S²
            # grad[n, comp, k] = Σ_i w_i,comp g_ni d_nik / S + affine[1 + k, comp] / S
            grad[start : start + CHUNK] = (np.einsum("ni,nik,ic->nck", g, d, self.weights) + self.affine[1:].T[None]) / s
        return off, grad

    def to_json(self) -> dict[str, Any]:
        return {"centers": self.centers.tolist(), "scale": self.scale,
                "weights_x": self.weights[:, 0].tolist(), "weights_y": self.weights[:, 1].tolist(),
                "affine_x": self.affine[:, 0].tolist(), "affine_y": self.affine[:, 1].tolist(),
                "smoothing": self.smoothing}


class TPSModel(ResidualFieldModel):
    kind = "tps"

    @classmethod
    def from_json(cls, intrinsics, distortion: dict[str, Any], base: str) -> "TPSModel":
        core = cls.parametric_from_json(intrinsics, distortion, base)
        centers = float_array(distortion, "centers", (2,))
        m = len(centers)
        w = np.column_stack([float_array(distortion, "weights_x", (), m), float_array(distortion, "weights_y", (), m)])
        a = np.column_stack([float_array(distortion, "affine_x", (), 3), float_array(distortion, "affine_y", (), 3)])
        smoothing = float(distortion.get("smoothing", 0.0) or 0.0)
        return cls(core, TPSField(centers, w, a, positive(distortion, "scale"), smoothing))
