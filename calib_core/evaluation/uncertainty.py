"""Projection uncertainty: how far would the projection of a direction move if
the corners were measured again with the same noise? (mrcal's idea, for any
model of ``models/``, in particular the B-spline.)

Linearised at the solution ``x̂ = argmin ‖r(x)‖² + ‖p(x)‖²`` (observation rows
r, prior rows p: regularisers and gauge constraints), noise ε of σ per axis on
the observations moves the solution by ``δx = −H⁻¹ J_dᵀ ε`` with
``H = J_dᵀJ_d + J_pᵀJ_p``. Hence ``Cov(x̂) = σ² H⁻¹ (J_dᵀJ_d) H⁻¹`` (the
sandwich: the prior rows shape H but carry no noise). The poses are nuisance
parameters: we only need the model columns of H⁻¹, which the Schur complement
``S = H_mm − H_mp H_pp⁻¹ H_pm`` (H_pp block-diagonal, 6 × 6 per view) gives:
``[H⁻¹]_{·,m} = [S⁻¹; −H_pp⁻¹ H_pm S⁻¹]``. σ² is estimated from the
residuals with the effective number of parameters ``tr(H⁻¹ J_dᵀJ_d)``.
Parameters a fit of the model holds (``free_mask``, e.g. a hybrid core's
distortion coefficients, which trade places with the field along a near-flat
valley) are held here too: they carry no noise, and counting them free would
predict the spread of a fit nobody runs (measured: up to 5× too much at the
edge of the corners on the fisheye lens).

For a direction v (a camera-frame ray), ``frame="camera"`` gives
``Cov(uv) = J_v Cov(x̂_m) J_vᵀ`` with ``J_v = ∂π(v; x)/∂x_m``. But the camera
frame itself is poorly determined (a common rotation of every pose is nearly
absorbed by the intrinsics and the field), so, like mrcal, the default
``frame="boards"`` fixes the direction in the boards' frames instead: the
projection is the mean over views k of ``π(x_m, R'_k R_kᵀ v)`` (a point at
infinity), whose Jacobian also has pose columns; then the full covariance
``σ² H⁻¹ (J_dᵀJ_d) H⁻¹`` is used. Reported over a grid of pixels (their rays
under the fitted model) as the worst-direction standard deviation
sqrt(λ_max) and the per-axis rms sqrt(tr/2), in pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..fitting.gram import gram
from ..fitting.solve import Data, SolveSettings, _assemble
from ..models import camera
from ..models.base import CameraModel


@dataclass
class UncertaintyMap:
    u: np.ndarray  # (nu,) grid pixel columns
    v: np.ndarray  # (nv,) grid pixel rows
    rays: np.ndarray  # (nv, nu, 3) the directions whose projection is measured
    cov: np.ndarray  # (nv, nu, 2, 2) pixel covariance of their projection
    covered: np.ndarray  # (nv, nu) bool: within ``coverage_radius`` of an observed corner
    sigma: float  # per-axis observation noise, estimated from the residuals (or given)
    dof: float  # effective number of fitted parameters

    @property
    def std_worst(self) -> np.ndarray:
        """(nv, nu) sqrt of the largest eigenvalue: the worst-direction spread, pixels."""
        return np.sqrt(np.linalg.eigvalsh(self.cov)[..., -1])

    @property
    def std_rms(self) -> np.ndarray:
        """(nv, nu) sqrt(trace / 2): the per-axis rms spread, pixels."""
        return np.sqrt(0.5 * np.trace(self.cov, axis1=-2, axis2=-1))

    def to_json(self) -> dict:
        return {"u": self.u.tolist(), "v": self.v.tolist(), "sigma": self.sigma, "dof": self.dof,
                "std_worst": np.where(np.isfinite(self.std_worst), self.std_worst, -1).tolist(),
                "std_rms": np.where(np.isfinite(self.std_rms), self.std_rms, -1).tolist(),
                "covered": self.covered.tolist(), "units": "pixels; -1 where undefined"}


def _embed(cov: np.ndarray, free: np.ndarray | None, n_params: int, n_extra: int = 0) -> np.ndarray:
    """Covariance over the free model parameters (+ ``n_extra`` pose columns)
    back on every model parameter: held ones get zero rows and columns."""
    if free is None:
        return cov
    idx = np.concatenate([np.flatnonzero(free), n_params + np.arange(n_extra)])
    out = np.zeros((n_params + n_extra,) * 2)
    out[np.ix_(idx, idx)] = cov
    return out


def inlier_data(cal, obs) -> tuple[Data, np.ndarray]:
    """The corners a calibration was fitted to (its views, outliers dropped) and its
    poses (V, 6), in the solver's form: what its covariance is computed from."""
    from ..pipeline import to_data

    data, names, local = to_data(obs.select([v.name for v in cal.views]))
    outliers = {(n, i) for n in names for i in cal.view(n).outliers}
    if outliers:
        keep = np.array([(names[k], int(i)) not in outliers for k, i in zip(data.view_index, local, strict=True)])
        data = data.points(keep)
    return data, np.array([cal.view(n).pose for n in names])


def model_covariance(model: CameraModel, poses: np.ndarray, data: Data, sigma: float | None = None):
    """Cov(x̂_m) (n_m, n_m) of the model parameters, poses marginalised; with σ and the dof."""
    free = model.free_mask()  # the parameters the fit moved, as the solver asks for them
    r, jac = _assemble(model, poses, data, SolveSettings(free_params=free))
    n_rows, n_views = 2 * data.n_points, data.n_views
    n_m = model.n_params if free is None else int(np.sum(free))
    jd = jac[:n_rows]
    h = gram(jac)
    m_data = (jd.T @ jd).toarray()
    h_mm, h_mp = h[:n_m, :n_m], h[:n_m, n_m:]
    idx = np.arange(6)
    blocks = np.stack([h[n_m + 6 * k + idx[:, None], n_m + 6 * k + idx] for k in range(n_views)])  # (V, 6, 6)
    inv_pp = np.linalg.inv(blocks)
    # H_pp⁻¹ H_pm, block by block: (V, 6, n_m) → (6V, n_m)
    pp_pm = np.einsum("vij,vjm->vim", inv_pp, h_mp.T.reshape(n_views, 6, n_m)).reshape(6 * n_views, n_m)
    schur = h_mm - h_mp @ pp_pm
    s_inv = _inverse(schur)
    z = np.vstack([s_inv, -pp_pm @ s_inv])  # the model columns of H⁻¹
    dof = _effective_dof(h, m_data)
    if sigma is None:
        rd = r[:n_rows]
        sigma = float(np.sqrt(np.sum(rd * rd) / max(n_rows - dof, 1.0)))
    a = np.asarray(jd @ z)  # (2N, n_m): AᵀA stays positive semi-definite
    cov = sigma**2 * a.T @ a
    return _embed(0.5 * (cov + cov.T), free, model.n_params), sigma, dof


def _inverse(h: np.ndarray) -> np.ndarray:
    """H⁻¹ (symmetrised). H is badly conditioned (gauge rows of weight 1e4 against
    weakly determined directions); LU with pivoting copes with that better than
    Jacobi-scaled inversion did here, and the covariance is then formed as
    AᵀA (A = J_d H⁻¹), which stays positive semi-definite whatever the rounding."""
    inv = np.linalg.inv(h)
    return 0.5 * (inv + inv.T)


def _effective_dof(h: np.ndarray, m_data: np.ndarray) -> float:
    """tr(H⁻¹ J_dᵀJ_d): the number of parameters the data actually fit."""
    return float(np.trace(np.linalg.solve(h, m_data)))


def full_covariance(model: CameraModel, poses: np.ndarray, data: Data, sigma: float | None = None):
    """Cov(x̂) over [model | poses] (n, n) by the sandwich formula; with σ and the dof."""
    free = model.free_mask()  # the parameters the fit moved, as the solver asks for them
    r, jac = _assemble(model, poses, data, SolveSettings(free_params=free))
    n_rows = 2 * data.n_points
    jd = jac[:n_rows]
    h = gram(jac)
    m_data = (jd.T @ jd).toarray()
    h_inv = _inverse(h)
    dof = float(np.sum(h_inv * m_data.T))  # tr(H⁻¹ M)
    if sigma is None:
        rd = r[:n_rows]
        sigma = float(np.sqrt(np.sum(rd * rd) / max(n_rows - dof, 1.0)))
    a = np.asarray(jd @ h_inv)  # (2N, n): written as AᵀA the covariance stays positive semi-definite
    cov = sigma**2 * a.T @ a
    return _embed(0.5 * (cov + cov.T), free, model.n_params, 6 * data.n_views), sigma, dof


def _param_rows(cols: np.ndarray, vals: np.ndarray, n: int) -> np.ndarray:
    """Dense (G, 2, n) from the sparse parameter Jacobian rows (G, 2, c)."""
    g = len(cols)
    out = np.zeros((g, 2, n))
    rows = np.arange(g)[:, None]
    for c in range(2):  # the two pixel axes
        np.add.at(out[:, c], (rows, cols[:, c]), vals[:, c])
    return out


def projection_uncertainty(model, poses: np.ndarray, data: Data, image_size, step: float = 32.0,
                           sigma: float | None = None, coverage_radius: float | None = None,
                           frame: str = "boards", covariance: tuple[np.ndarray, float, float] | None = None
                           ) -> UncertaintyMap:
    """Per-pixel projection uncertainty on a grid of pixels ``step`` apart
    (``frame``: "boards", mrcal-like, or "camera", see the module text).
    ``covariance``: ``full_covariance``'s answer when the caller has it already
    (frame "boards" only)."""
    w, h = image_size
    u = np.arange(0.0, w, step)
    v = np.arange(0.0, h, step)
    grid = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
    rays = model.rays(grid)  # (G, 3), NaN where the model cannot invert
    ok = np.all(np.isfinite(rays), axis=1)
    if model.base == "pinhole":
        ok &= np.where(ok, rays[:, 2], 0.0) > 1e-6
    cov = np.full((len(grid), 2, 2), np.nan)
    n_m = model.n_params
    if frame == "camera":
        cov_x, sigma, dof = model_covariance(model, poses, data, sigma)
    elif frame == "boards":
        cov_x, sigma, dof = covariance or full_covariance(model, poses, data, sigma)
    else:
        raise ValueError(f"frame: expected 'boards' or 'camera', got {frame!r}")
    if ok.any():
        _, d_pc, cols, vals = model.project(rays[ok], jacobian=True)
        jv = _param_rows(cols, vals, n_m)
        if frame == "boards":
            # q = mean_k π(R'_k R_kᵀ v): at the solution every term is π(v); a left
            # rotation ω_k of pose k moves v by ω_k × v, ∂v/∂ω = −[v]×.
            d_rot = np.einsum("gij,gjk->gik", d_pc, camera.d_transform(rays[ok])[:, :, :3])  # (G, 2, 3)
            n_views = len(poses)
            jp = np.zeros((len(jv), 2, n_views, 6))
            jp[:, :, :, :3] = d_rot[:, :, None, :] / n_views
            jv = np.concatenate([jv, jp.reshape(len(jv), 2, 6 * n_views)], axis=2)
        # (J C) then its rows against J: one BLAS product, not a three-operand
        # einsum (which loops over all of g, i, j, m, n at once: seconds for a field)
        cov[ok] = np.einsum("gin,gjn->gij", jv @ cov_x, jv)
    radius = coverage_radius if coverage_radius is not None else 1.5 * step
    dist = cKDTree(data.image_points).query(grid)[0]
    covered = (dist <= radius) & ok
    nv, nu = len(v), len(u)
    return UncertaintyMap(u, v, rays.reshape(nv, nu, 3), cov.reshape(nv, nu, 2, 2), covered.reshape(nv, nu), sigma, dof)


def aligned_projection(model, poses: np.ndarray, ref_poses: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Pixels (G, 2) of directions ``rays`` (G, 3) fixed in the boards' frames of
    ``ref_poses``, seen through ``model`` and ``poses``: mean_k π(R_k R_ref,kᵀ v).
    The quantity whose spread ``projection_uncertainty(frame="boards")`` predicts."""
    from scipy.spatial.transform import Rotation

    out = np.zeros((len(rays), 2))
    for k in range(len(poses)):  # a handful of views, not points
        rel = Rotation.from_rotvec(poses[k, :3]) * Rotation.from_rotvec(ref_poses[k, :3]).inv()
        out += model.project(rel.apply(rays))
    return out / len(poses)
