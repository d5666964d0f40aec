"""Moving-least-squares residual field (baseline ``mls``), on an OpenCV core.

JSON (``distortion``)::

    {"type": "mls", "parametric": {"type": "opencv", "coefficients": [...]},
     "samples": [[u, v], ...],            # K pixels (parametric pixels of the training corners)
     "offsets_x": [...], "offsets_y": [...],   # K: observed minus parametric pixel
     "sigma": σ,                          # Gaussian width, pixels
     "support": R,                        # samples farther than R (= 3σ) are ignored
     "ridge": ε}                          # small Tikhonov term, keeps the local fit defined

At the parametric pixel ``p``: with ``δ_j = s_j − p``, ``w_j = exp(−|δ_j|²/(2σ²))``
for ``|δ_j| ≤ R`` (else 0) and ``g_j = [1, δ_jx/R, δ_jy/R]``, solve the
first-order local fit ``c = (Σ w_j g_j g_jᵀ + ε I)⁻¹ Σ w_j g_j d_jᵀ`` (3 × 2)
and take its value at ``p``: ``f(p) = c[0]``. Far from every sample the ridge
makes ``f`` fade to 0 (the parametric model alone). Distorted pixel = ``p + f(p)``.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .residual_field import ResidualFieldModel, float_array, positive

CHUNK = 4096  # evaluation points per block: bounds the neighbour pairs held at once

# Monomial exponents (a, b) with a + b ≤ order, and their columns in the raw-moment matrix.
_EXPONENTS = {o: [(a, t - a) for t in range(o + 1) for a in range(t, -1, -1)] for o in (2, 3)}
_RAW = {e: i for i, e in enumerate(_EXPONENTS[3])}
_RAWD = {e: 10 + 2 * i for i, e in enumerate(_EXPONENTS[2])}


def _binom(n: int, k: int) -> int:
    return 1 if k in (0, n) else n  # n ≤ 3: C(n, k) for 0 < k < n is n


class MLSField:
    def __init__(self, samples, offsets, sigma: float, support: float | None = None, ridge: float = 1e-3):
        self.samples = np.asarray(samples, dtype=np.float64).reshape(-1, 2)  # (K, 2)
        self.offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)  # (K, 2)
        self.sigma = float(sigma)
        self.support = float(support if support is not None else 3.0 * sigma)
        self.ridge = float(ridge)
        self._tree = cKDTree(self.samples)
        self._mono = None

    def evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(p, dtype=np.float64).reshape(-1, 2)
        off = np.zeros((len(p), 2))
        grad = np.zeros((len(p), 2, 2))
        ok = np.all(np.isfinite(p), axis=1)
        idx = np.flatnonzero(ok)
        for start in range(0, len(idx), CHUNK):  # blocks of points, not a loop per point
            sel = idx[start : start + CHUNK]
            off[sel], grad[sel] = self._block(p[sel])
        off[~ok] = np.nan
        grad[~ok] = np.nan
        return off, grad

    def _block(self, p: np.ndarray):
        """Offsets (n, 2) and gradients (n, 2, 2) at pixels ``p`` (n, 2).

        Every sum Σ_j w_j u_j^α (d_j) with u_j = (s_j − p)/R is a central moment
        about p; we get them from raw moments about the image origin, which are
        one sparse (n × K) · (K × 22) product: no per-pair 3 × 3 arrays."""
        n, big_r = len(p), self.support
        pairs = cKDTree(p).sparse_distance_matrix(self._tree, big_r, output_type="ndarray")
        w = np.exp(-0.5 * pairs["v"] ** 2 / self.sigma**2)
        wmat = sp.csr_matrix((w, (pairs["i"], pairs["j"])), shape=(n, len(self.samples)))
        raw = np.asarray(wmat @ self._monomials)  # (n, 22)
        q = (p - self._origin) / big_r  # the evaluation points in the same units
        cm = {}  # central moments c(a, b) = Σ w u1^a u2^b, and e(a, b) = Σ w u1^a u2^b d (2,)
        for a, b in _EXPONENTS[3]:
            cm[a, b] = sum(_binom(a, i) * _binom(b, j) * (-q[:, 0]) ** (a - i) * (-q[:, 1]) ** (b - j) * raw[:, _RAW[i, j]]
                           for i in range(a + 1) for j in range(b + 1))
        em = {}
        for a, b in _EXPONENTS[2]:
            em[a, b] = sum((_binom(a, i) * _binom(b, j) * (-q[:, 0]) ** (a - i) * (-q[:, 1]) ** (b - j))[:, None]
                           * raw[:, _RAWD[i, j] : _RAWD[i, j] + 2] for i in range(a + 1) for j in range(b + 1))
        unit = [(0, 0), (1, 0), (0, 1)]  # exponents of g = [1, u1, u2]

        def add(*es):
            return tuple(map(sum, zip(*es)))

        m = np.stack([np.stack([cm[add(unit[i], unit[j])] for j in range(3)], -1) for i in range(3)], -2)
        m += self.ridge * np.eye(3)
        bvec = np.stack([em[unit[i]] for i in range(3)], axis=1)  # (n, 3, 2)
        c = np.linalg.solve(m, bvec)
        kappa = big_r / self.sigma**2  # ∂w/∂p_k = κ w u_k;  ∂g_i/∂p_k = −[i = k+1]/R
        grad = np.empty((n, 2, 2))
        for k in range(2):  # the two pixel axes
            ek = unit[k + 1]
            dm = kappa * np.stack([np.stack([cm[add(unit[i], unit[j], ek)] for j in range(3)], -1) for i in range(3)], -2)
            dm[:, k + 1, :] -= np.stack([cm[unit[j]] for j in range(3)], -1) / big_r
            dm[:, :, k + 1] -= np.stack([cm[unit[i]] for i in range(3)], -1) / big_r
            db = kappa * np.stack([em[add(unit[i], ek)] for i in range(3)], axis=1)
            db[:, k + 1, :] -= em[0, 0] / big_r
            grad[:, :, k] = np.linalg.solve(m, db - dm @ c)[:, 0, :]
        return c[:, 0, :], grad

    @property
    def _origin(self) -> np.ndarray:
        return self.samples.mean(axis=0)

    @property
    def _monomials(self) -> np.ndarray:
        """(K, 22): t^α for |α| ≤ 3 (10 columns), then t^α d for |α| ≤ 2 (6 × 2), t = (s − origin)/R."""
        if getattr(self, "_mono", None) is None:
            t = (self.samples - self._origin) / self.support
            cols = [t[:, 0] ** a * t[:, 1] ** b for a, b in _EXPONENTS[3]]
            for a, b in _EXPONENTS[2]:
                cols += [t[:, 0] ** a * t[:, 1] ** b * self.offsets[:, 0], t[:, 0] ** a * t[:, 1] ** b * self.offsets[:, 1]]
            self._mono = np.column_stack(cols)
        return self._mono

    def to_json(self) -> dict[str, Any]:
        return {"samples": self.samples.tolist(), "offsets_x": self.offsets[:, 0].tolist(),
                "offsets_y": self.offsets[:, 1].tolist(), "sigma": self.sigma, "support": self.support,
                "ridge": self.ridge}


class MLSModel(ResidualFieldModel):
    kind = "mls"

    @classmethod
    def from_json(cls, intrinsics, distortion: dict[str, Any], base: str) -> "MLSModel":
        core = cls.parametric_from_json(intrinsics, distortion, base)
        samples = float_array(distortion, "samples", (2,))
        k = len(samples)
        d = np.column_stack([float_array(distortion, "offsets_x", (), k), float_array(distortion, "offsets_y", (), k)])
        sigma = positive(distortion, "sigma")
        support = positive(distortion, "support") if "support" in distortion else 3.0 * sigma
        ridge = float(distortion.get("ridge", 1e-3))
        return cls(core, MLSField(samples, d, sigma, support, ridge))
