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

from typing import Any, Self

import numpy as np
from numba import njit

from .residual_field import ResidualFieldModel, float_array, positive

# Neighbour search: the samples are bucketed in square cells of side ≥ R, so a
# point's neighbours lie in the 3 × 3 cells around its own. At most this many
# cells per axis: a tiny support (any positive value is valid JSON) would
# otherwise ask for an enormous grid.
MAX_CELLS = 1024


@njit(cache=True, nogil=True, error_model="numpy")
def _evaluate(p, samples, offsets, order, cell_start, lo, cell_size, n_x, n_y, sigma, support, ridge):  # pragma: no cover (compiled)
    """Offsets (N, 2) and gradients ∂f/∂p (N, 2, 2) at pixels ``p`` (N, 2).

    Per point the weighted sums S = Σ w g gᵀ, T_k = Σ w u_k g gᵀ, B = Σ w g dᵀ
    and U_k = Σ w u_k g dᵀ (u = (s − p)/R, g = [1, u]) give c = M⁻¹ B with
    M = S + εI, and with ∂w/∂p_k = κ w u_k (κ = R/σ²), ∂g/∂p_k = −e_{k+1}/R:
    ∂c/∂p_k = M⁻¹ (∂B_k − ∂M_k c)."""
    n = len(p)
    off = np.empty((n, 2))
    grad = np.empty((n, 2, 2))
    r2max, half_inv_var, inv_r, kappa = support * support, 0.5 / (sigma * sigma), 1.0 / support, support / (sigma * sigma)
    s_, t_, b_, u_ = np.empty((3, 3)), np.empty((2, 3, 3)), np.empty((3, 2)), np.empty((2, 3, 2))
    g, minv, coef, rhs = np.empty(3), np.empty((3, 3)), np.empty((3, 2)), np.empty((3, 2))
    for a in range(n):
        px, py = p[a, 0], p[a, 1]
        if not (np.isfinite(px) and np.isfinite(py)):
            off[a] = np.nan
            grad[a] = np.nan
            continue
        s_[:] = 0.0
        t_[:] = 0.0
        b_[:] = 0.0
        u_[:] = 0.0
        fx, fy = (px - lo[0]) / cell_size, (py - lo[1]) / cell_size
        if -2.0 < fx < n_x + 1.0 and -2.0 < fy < n_y + 1.0:  # else no sample within R
            cx, cy = int(np.floor(fx)), int(np.floor(fy))
            for ix in range(max(cx - 1, 0), min(cx + 2, n_x)):
                for iy in range(max(cy - 1, 0), min(cy + 2, n_y)):
                    cell = ix * n_y + iy
                    for q in range(cell_start[cell], cell_start[cell + 1]):
                        j = order[q]
                        dx, dy = samples[j, 0] - px, samples[j, 1] - py
                        d2 = dx * dx + dy * dy
                        if d2 > r2max:
                            continue
                        w = np.exp(-d2 * half_inv_var)
                        g[0], g[1], g[2] = 1.0, dx * inv_r, dy * inv_r
                        for i in range(3):
                            wg = w * g[i]
                            for m in range(3):
                                wgg = wg * g[m]
                                s_[i, m] += wgg
                                t_[0, i, m] += wgg * g[1]
                                t_[1, i, m] += wgg * g[2]
                            for c in range(2):
                                wgd = wg * offsets[j, c]
                                b_[i, c] += wgd
                                u_[0, i, c] += wgd * g[1]
                                u_[1, i, c] += wgd * g[2]
        if not _inverse3(s_, ridge, minv):
            off[a] = np.nan
            grad[a] = np.nan
            continue
        for i in range(3):  # coef = M⁻¹ B
            for c in range(2):
                coef[i, c] = minv[i, 0] * b_[0, c] + minv[i, 1] * b_[1, c] + minv[i, 2] * b_[2, c]
        off[a, 0], off[a, 1] = coef[0, 0], coef[0, 1]
        for k in range(2):  # the two pixel axes: only row 0 of M⁻¹ (∂B_k − ∂M_k c) is needed
            for i in range(3):
                for c in range(2):
                    rhs[i, c] = kappa * (u_[k, i, c] - (t_[k, i, 0] * coef[0, c] + t_[k, i, 1] * coef[1, c]
                                                        + t_[k, i, 2] * coef[2, c]))
                    rhs[i, c] += s_[i, 0] * inv_r * coef[k + 1, c]  # −∂M column k+1: −s_[i, 0]/R
            for c in range(2):
                for m in range(3):
                    rhs[k + 1, c] += s_[0, m] * inv_r * coef[m, c]  # −∂M row k+1: −s_[0, m]/R
                rhs[k + 1, c] -= b_[0, c] * inv_r  # ∂B row k+1: −Σ w d / R
            for c in range(2):
                grad[a, c, k] = minv[0, 0] * rhs[0, c] + minv[0, 1] * rhs[1, c] + minv[0, 2] * rhs[2, c]
    return off, grad


@njit(cache=True, nogil=True, error_model="numpy")
def _inverse3(s, ridge, out):  # pragma: no cover (compiled)
    """``out`` = (s + ridge·I)⁻¹ of a symmetric 3 × 3 by cofactors; False if singular."""
    a, b, c = s[0, 0] + ridge, s[0, 1], s[0, 2]
    d, e, f = s[1, 1] + ridge, s[1, 2], s[2, 2] + ridge
    c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * c00 + b * c01 + c * c02
    if not det != 0.0:
        return False
    r = 1.0 / det
    out[0, 0], out[0, 1], out[0, 2] = c00 * r, c01 * r, c02 * r
    out[1, 0], out[1, 1], out[1, 2] = c01 * r, (a * f - c * c) * r, (b * c - a * e) * r
    out[2, 0], out[2, 1], out[2, 2] = c02 * r, (b * c - a * e) * r, (a * d - b * b) * r
    return True


def _buckets(samples: np.ndarray, support: float):
    """The samples bucketed in square cells of side ``size`` ≥ ``support``:
    (order, cell_start, lo, size, n_x, n_y), cell (ix, iy) holding
    ``order[cell_start[ix·n_y + iy] : cell_start[ix·n_y + iy + 1]]``."""
    if not len(samples):
        return np.zeros(0, dtype=np.int64), np.zeros(2, dtype=np.int64), np.zeros(2), support, 1, 1
    lo = samples.min(axis=0)
    size = max(support, float(np.max(samples.max(axis=0) - lo)) / MAX_CELLS)
    ij = np.floor((samples - lo) / size).astype(np.int64)
    n_x, n_y = int(ij[:, 0].max()) + 1, int(ij[:, 1].max()) + 1
    cells = ij[:, 0] * n_y + ij[:, 1]
    order = np.argsort(cells, kind="stable")
    cell_start = np.concatenate([[0], np.cumsum(np.bincount(cells, minlength=n_x * n_y))])
    return order, cell_start, lo, size, n_x, n_y


class MLSField:
    def __init__(self, samples, offsets, sigma: float, support: float | None = None, ridge: float = 1e-3):
        self.samples = np.asarray(samples, dtype=np.float64).reshape(-1, 2)  # (K, 2)
        self.offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)  # (K, 2)
        self.sigma = float(sigma)
        self.support = float(support if support is not None else 3.0 * sigma)
        self.ridge = float(ridge)
        self._buckets = _buckets(self.samples, self.support)

    def evaluate(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 2)
        return _evaluate(p, self.samples, self.offsets, *self._buckets, self.sigma, self.support, self.ridge)

    def to_json(self) -> dict[str, Any]:
        return {"samples": self.samples.tolist(), "offsets_x": self.offsets[:, 0].tolist(),
                "offsets_y": self.offsets[:, 1].tolist(), "sigma": self.sigma, "support": self.support,
                "ridge": self.ridge}


class MLSModel(ResidualFieldModel):
    kind = "mls"

    @classmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        core = cls.parametric_from_json(intrinsics, distortion, base)
        samples = float_array(distortion, "samples", (2,))
        k = len(samples)
        d = np.column_stack([float_array(distortion, "offsets_x", (), k), float_array(distortion, "offsets_y", (), k)])
        sigma = positive(distortion, "sigma")
        support = positive(distortion, "support") if "support" in distortion else 3.0 * sigma
        ridge = float(distortion.get("ridge", 1e-3))
        return cls(core, MLSField(samples, d, sigma, support, ridge))
