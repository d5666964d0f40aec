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

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..observations import Circle
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


def principal_samples(model: CameraModel, n_theta: int = N_THETA, n_phi: int = N_PHI) -> tuple[np.ndarray, np.ndarray]:
    """Normalised coordinates (M, 2) on the principal branch and their pixels (M, 2)."""
    _, _, xn, uv, branch = principal_branch(model, n_theta, n_phi)
    return xn[branch], uv[branch]


def normalised_of_pixel(model: CameraModel, uv: np.ndarray, tol: float = 1e-9,
                        max_iterations: int = 60, grid: tuple[int, int] = (N_THETA, N_PHI)) -> np.ndarray:
    """Normalised coordinates (N, 2) of pixels (N, 2) on the principal branch;
    NaN where Newton does not reach ``tol`` px or ends on a folded sheet. ``grid``:
    the polar grid of rays (θ, φ) Newton starts from."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    xs, us = principal_samples(model, *grid)
    if len(xs) == 0:
        return model.normalised_of_pixel(uv, tol, max_iterations)
    _, nearest = cKDTree(us).query(np.where(np.isfinite(uv), uv, 0.0))
    xn, err = refine_preimage(model, xs[nearest], uv, tol, max_iterations)
    with np.errstate(all="ignore"):
        _, d_uv, _, _ = model.pixel_of(np.nan_to_num(xn), jacobian=True)
    det = d_uv[:, 0, 0] * d_uv[:, 1, 1] - d_uv[:, 0, 1] * d_uv[:, 1, 0]
    xn[(np.linalg.norm(err, axis=-1) > max(100 * tol, 1e-6)) | ~(det > 0) | ~np.all(np.isfinite(uv), axis=1)] = np.nan
    return xn


def frame_border(image_size: tuple[int, int], n: int = 200) -> np.ndarray:
    """The image border as a closed polygon (4n, 2), clockwise from the top-left."""
    w, h = image_size
    t = np.linspace(0, 1, n, endpoint=False)
    return np.concatenate([
        np.column_stack([t * (w - 1), np.zeros_like(t)]), np.column_stack([np.full_like(t, w - 1), t * (h - 1)]),
        np.column_stack([(1 - t) * (w - 1), np.full_like(t, h - 1)]), np.column_stack([np.zeros_like(t), (1 - t) * (h - 1)]),
    ])


def edge_pixels(image_size: tuple[int, int], circle: Circle | None = None, per_side: int = 64) -> np.ndarray:
    """Pixels (M, 2) along the edge of what the lens images: the frame's border, or where
    its image circle (cx, cy, radius) ends inside the frame, the rim of the disc a few px
    in, with the stretches of the border inside the disc."""
    w, h = image_size
    border = frame_border(image_size, per_side)
    if circle is None:
        return border
    cx, cy, r = circle
    inner = r - max(2.0, 0.01 * r)  # the rim itself is half lit
    a = np.linspace(-np.pi, np.pi, 4 * per_side, endpoint=False)
    rim = np.c_[cx + inner * np.cos(a), cy + inner * np.sin(a)]
    in_frame = np.all((rim >= 0) & (rim <= [w - 1, h - 1]), axis=1)
    in_disc = np.hypot(border[:, 0] - cx, border[:, 1] - cy) <= inner
    return np.concatenate([rim[in_frame], border[in_disc]])


# The outermost tenth of the way from the lit image's centre to its edge: the frame's
# corners, which few boards reach. A fold there can be the saturation of a model that
# holds everywhere else; the folds that mislead reach further in (docs/model-choice.md,
# step 3).
FOLD_MARGIN = 0.1


@dataclass(frozen=True)
class LitEdge:
    """Pixels along the edge of what the lens images (``edge_pixels``), and the same
    FOLD_MARGIN of the way in towards its centre."""

    rim: np.ndarray
    inside: np.ndarray

    def folds(self, model: CameraModel) -> tuple[float, float]:
        """(share of ``rim``, share of ``inside``) the model maps no ray to."""
        at_rim = unmapped_share(model, self.rim)
        return at_rim, 0.0 if at_rim == 0 else unmapped_share(model, self.inside)


def lit_edge(image_size: tuple[int, int], circle: Circle | None, wide: bool,
             first: CameraModel | None = None) -> LitEdge | None:
    """The pixels a model must map rays to (``LitEdge``), or None where that is not known
    (no image circle recorded): past the pinhole's reach (``wide``), a lens's image circle
    often ends inside the frame and leaves its corners unlit. Where the ``first`` camera
    (the initialisation's) maps no ray to part of the frame's border, the lens images a
    disc short of the frame's corners (a fisheye whose image circle the frame cuts), which
    no right model maps past: the edge is that disc's (``imaged_disc``)."""
    if circle is None and wide:
        return None
    rim = edge_pixels(image_size, circle)
    if circle is None and first is not None and unmapped_share(first, rim) > 0:
        circle = imaged_disc(first)
        rim = edge_pixels(image_size, circle)
    w, h = image_size
    centre = np.array([(w - 1) / 2, (h - 1) / 2] if circle is None else circle[:2])
    return LitEdge(rim, centre + (1.0 - FOLD_MARGIN) * (rim - centre))


def imaged_disc(model: CameraModel) -> Circle:
    """(cx, cy, radius) px: the disc about the axis's pixel that ``model`` maps rays to,
    to where its principal branch ends first (``principal_branch``), a twentieth in: its
    fold is where Newton's steps stall."""
    _, _, _, uv, branch = principal_branch(model, N_THETA // 2, N_PHI // 2)
    centre = uv[0, 0]
    last = np.maximum(branch.sum(axis=1) - 1, 0)  # each azimuth's last sample on the branch
    radius = np.linalg.norm(uv[np.arange(len(last)), last] - centre, axis=-1)
    return float(centre[0]), float(centre[1]), 0.95 * float(radius.min())


def unmapped_share(model: CameraModel, pixels: np.ndarray) -> float:
    """The share of ``pixels`` (M, 2) the model maps no ray to on its principal branch
    (past a fold or a pole of its distortion)."""
    xn = normalised_of_pixel(model, pixels, grid=(N_THETA // 2, N_PHI // 2))  # whether, not where to 1e-9: a coarser start
    return float(np.mean(~np.all(np.isfinite(xn), axis=1))) if len(xn) else 0.0
