"""Photo pixel → normalised coordinates on the lens's principal branch.

Newton's method from the undistorted guess (``CameraModel.normalised_of_pixel``)
finds *a* preimage; wide rational or polynomial models fold back beyond their
data, and near the image corners Newton can land on the folded sheet: a ray
30° off, with a pixel error of 1e-9. Here the start is chosen on the
principal branch instead: a polar grid of rays is projected; along each
azimuth the branch runs from the axis up to the first sample where the map
stops being a local diffeomorphism (det ∂uv/∂xn ≤ 0); each pixel starts from
the nearest projected sample of that branch, then damped Newton
(``refine_preimage``) refines it to ``tol`` px.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import camera
from .base import CameraModel, refine_preimage

N_THETA, N_PHI = 160, 192  # ~0.6° × 1.9° polar grid: start within a fraction of a cell
MAX_THETA: dict[str, float] = {"pinhole": np.radians(88.0), "equidistant": np.radians(120.0), "stereographic": np.radians(150.0)}


def principal_branch(model: CameraModel, n_theta: int = N_THETA, n_phi: int = N_PHI):
    """The principal branch on a polar grid of rays: ``theta`` (n_theta,) and
    ``phi`` (n_phi,) angles, normalised coordinates ``xn`` and pixels ``uv``
    (n_phi, n_theta, 2), and ``branch`` (n_phi, n_theta) bool, True from the axis
    up to the first fold along each azimuth (a prefix of every row)."""
    theta = np.linspace(0.0, MAX_THETA.get(model.base, MAX_THETA["pinhole"]), n_theta)
    phi = np.linspace(-np.pi, np.pi, n_phi, endpoint=False)
    tt, pp = np.meshgrid(theta, phi)  # (n_phi, n_theta): one azimuth per row
    rays = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], axis=-1).reshape(-1, 3)
    xn = camera.normalise(rays, model.base)
    with np.errstate(all="ignore"):
        uv, d_uv, _, _ = model.pixel_of(xn, jacobian=True)
        det = d_uv[:, 0, 0] * d_uv[:, 1, 1] - d_uv[:, 0, 1] * d_uv[:, 1, 0]
    ok = (np.isfinite(det) & (det > 0) & np.all(np.isfinite(uv), axis=1)).reshape(n_phi, n_theta)
    # The branch also ends where the pixel stops moving away from the axis's
    # pixel: a rational denominator's pole flips the image through infinity
    # with det > 0 on both sides, which the fold test alone cannot see.
    radius = np.linalg.norm(uv.reshape(n_phi, n_theta, 2) - uv.reshape(n_phi, n_theta, 2)[:, :1], axis=-1)
    with np.errstate(invalid="ignore"):
        ok[:, 1:] &= np.diff(radius, axis=1) > 0
    branch = np.cumprod(ok, axis=1).astype(bool)  # up to the first fold along each azimuth
    return theta, phi, xn.reshape(n_phi, n_theta, 2), uv.reshape(n_phi, n_theta, 2), branch


def principal_samples(model: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Normalised coordinates (M, 2) on the principal branch and their pixels (M, 2)."""
    _, _, xn, uv, branch = principal_branch(model)
    return xn[branch], uv[branch]


def normalised_of_pixel(model: CameraModel, uv: np.ndarray, tol: float = 1e-9,
                        max_iterations: int = 60) -> np.ndarray:
    """Normalised coordinates (N, 2) of pixels (N, 2) on the principal branch;
    NaN where Newton does not reach ``tol`` px or ends on a folded sheet."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    xs, us = principal_samples(model)
    if len(xs) == 0:
        return model.normalised_of_pixel(uv, tol, max_iterations)
    _, nearest = cKDTree(us).query(np.where(np.isfinite(uv), uv, 0.0))
    xn, err = refine_preimage(model, xs[nearest], uv, tol, max_iterations)
    with np.errstate(all="ignore"):
        _, d_uv, _, _ = model.pixel_of(np.nan_to_num(xn), jacobian=True)
    det = d_uv[:, 0, 0] * d_uv[:, 1, 1] - d_uv[:, 0, 1] * d_uv[:, 1, 0]
    xn[(np.linalg.norm(err, axis=-1) > max(100 * tol, 1e-6)) | ~(det > 0) | ~np.all(np.isfinite(uv), axis=1)] = np.nan
    return xn

