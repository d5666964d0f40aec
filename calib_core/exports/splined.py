"""mrcal's ``LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=…_Ny=…_fov_x_deg=…``,
and its fit to any calibration, so that B-spline, hybrid, Kannala–Brandt (and
every other) calibrations reach mrcal as its own rich model.

The projection, as mrcal computes it (``mrcal.c``, ``_project_point_splined``;
docs ``lensmodels.org`` and ``splined-models.org``):

- ``u = 2 p_xy / (|p| + p_z)``: the normalised stereographic projection;
- a cubic B-spline surface on a regular ``Nx × Ny`` knot grid in ``u`` gives
  ``Δu(u)``; the knots sit at ``(i − (Nx − 1)/2) / s`` with ``s`` =
  ``segments_per_u = (Nx − 3) / (2 u_edge)``, ``u_edge = 2 tan(fov_x/4)``, the
  same spacing down (``fov_y`` follows from ``Ny``); a point between knots
  ``i0`` and ``i0 + 1`` (``i0 = ⌊ix⌋`` clamped to ``[1, Nx − 3]``) takes the 4 × 4
  control points from ``i0 − 1`` with the uniform cubic weights;
- ``q = f (u + Δu) + c``.

The intrinsics vector is ``fx, fy, cx, cy`` then the control points row by row
(``y`` outer), ``Δu_x, Δu_y`` interleaved: ``4 + 2 (iy Nx + ix) + k``.

The fit keeps the calibration's focal lengths and principal point as the core
and solves for the control points by linear least squares (the projection is
linear in them), on a dense grid of the whole image, with a light
second-difference penalty that only decides knots no sample reaches. The field
of view spans every ray of the image up to 20° past the covered region's (``fov_x_deg``
is whole degrees: rounded up), and the knot density is the first of ``DENSITIES`` that fits the covered
region to ``TARGET_MAX_PX``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..calibration import Calibration
from .lean_fit import REACH_DEG, LeanFit, LeanFitError, covered_pixels, evaluate, reachable, sample_grid

DENSITIES = (12, 16, 20, 26, 32, 40)  # knots across (Nx) tried in turn
TARGET_MAX_PX = 0.01  # the first density that fits the covered region this well is kept
SAMPLES_PER_INTERVAL = 5  # fit samples per knot interval, each way
SMOOTHING = 1e-6  # weight of the second differences of the control points (decides unsupported knots)
EXTRAPOLATED_DEG = 20.0  # the knots reach this far off axis past the covered region's rays, at most
NAME = "splined"


def weights(t: np.ndarray) -> np.ndarray:
    """Uniform cubic B-spline weights (N, 4) at t ∈ [0, 1) (mrcal's get_sample_coeffs__cubic)."""
    t2, t3 = t * t, t * t * t
    return np.column_stack([(-t3 + 3 * t2 - 3 * t + 1) / 6, (1.5 * t3 - 3 * t2 + 2) / 3,
                            (-3 * t3 + 3 * t2 + 3 * t + 1) / 6, t3 / 6])


def stereographic(rays: np.ndarray) -> np.ndarray:
    """u (N, 2) = 2 p_xy / (|p| + p_z)."""
    p = np.asarray(rays, dtype=np.float64).reshape(-1, 3)
    return 2.0 * p[:, :2] / (np.linalg.norm(p, axis=1) + p[:, 2])[:, None]


@dataclass(frozen=True)
class SplinedStereographic:
    """``core`` (fx, fy, cx, cy) and ``control`` (Ny, Nx, 2): the Δu at each knot."""

    core: np.ndarray
    control: np.ndarray
    fov_x_deg: int

    @property
    def nx(self) -> int:
        return int(self.control.shape[1])

    @property
    def ny(self) -> int:
        return int(self.control.shape[0])

    @property
    def lensmodel(self) -> str:
        return f"LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx={self.nx}_Ny={self.ny}_fov_x_deg={self.fov_x_deg}"

    @property
    def intrinsics(self) -> np.ndarray:
        return np.concatenate([self.core, self.control.ravel()])

    @property
    def segments_per_u(self) -> float:
        return segments_per_u(self.nx, self.fov_x_deg)

    def design(self, u: np.ndarray) -> sp.csr_matrix:
        """(N, Ny·Nx): Δu = design @ control.reshape(-1, 2), for stereographic u (N, 2)."""
        return design(u, self.nx, self.ny, self.segments_per_u)

    def project(self, rays: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of camera-frame rays (N, 3)."""
        u = stereographic(rays)
        du = self.design(u) @ self.control.reshape(-1, 2)
        return (u + du) * self.core[:2] + self.core[2:4]


def segments_per_u(nx: int, fov_x_deg: float) -> float:
    u_edge = 2.0 * np.tan(np.radians(fov_x_deg) / 4.0)  # tan(θ_edge / 2) · 2, θ_edge = fov_x / 2
    return (nx - 3) / (2.0 * u_edge)


def design(u: np.ndarray, nx: int, ny: int, spu: float) -> sp.csr_matrix:
    """The B-spline weights of every sample on the knot grid, as mrcal indexes them."""
    ix = u[:, 0] * spu + (nx - 1) / 2.0
    iy = u[:, 1] * spu + (ny - 1) / 2.0
    # out of bounds: the nearest valid segment (the polynomial extrapolates, continuously)
    ix0 = np.clip(np.floor(ix), 1, nx - 3).astype(np.int64)
    iy0 = np.clip(np.floor(iy), 1, ny - 3).astype(np.int64)
    wx, wy = weights(ix - ix0), weights(iy - iy0)  # (N, 4) each
    cols = (iy0[:, None, None] - 1 + np.arange(4)[None, :, None]) * nx + (ix0[:, None, None] - 1 + np.arange(4)[None, None, :])
    vals = wy[:, :, None] * wx[:, None, :]  # (N, 4 rows, 4 columns)
    rows = np.repeat(np.arange(len(u)), 16)
    return sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(len(u), nx * ny))


def _second_differences(nx: int, ny: int) -> sp.csr_matrix:
    """Rows of the second differences of a (ny, nx) grid along x and along y."""
    def d2(n: int) -> sp.csr_matrix:
        return sp.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2], shape=(n - 2, n))

    return sp.vstack([sp.kron(sp.eye(ny), d2(nx)), sp.kron(d2(ny), sp.eye(nx))]).tocsr()


def fit_splined(cal: Calibration, covered: np.ndarray | None = None) -> LeanFit:
    """The splined model closest to ``cal`` (module text), scored like every export."""
    best: LeanFit | None = None
    limit = _angle_limit(cal, covered_pixels(cal, covered))
    for nx in DENSITIES:
        fit = evaluate(_fit_density(cal, nx, limit), cal, NAME, limit, covered=covered)  # no knots past the limit
        if best is None or fit.covered.rms < best.covered.rms:
            best = fit
        if fit.covered.max <= TARGET_MAX_PX:
            break
    assert best is not None
    return best


def _angle_limit(cal: Calibration, covered: np.ndarray | None) -> float:
    """How far off axis (degrees) the knots reach: every ray of the image, but no further than
    EXTRAPOLATED_DEG past the covered region's. Outside a fisheye's image circle a calibration
    extrapolates its rays to 176-179° (a 200° lens): knots spread that wide left its lit disc
    about one interval (74 px rms)."""
    if covered is None:
        return REACH_DEG[NAME]
    u, v, rays, ok = sample_grid(cal, covered=covered, max_angle_deg=REACH_DEG[NAME])
    if not ok.any():
        return REACH_DEG[NAME]
    seen = float(np.degrees(np.arccos(np.clip(rays[ok, 2], -1.0, 1.0))).max())
    return min(REACH_DEG[NAME], seen + EXTRAPOLATED_DEG)


def _fit_density(cal: Calibration, nx: int, max_angle_deg: float = REACH_DEG[NAME]) -> SplinedStereographic:
    w, h = cal.image_size
    n_samples = SAMPLES_PER_INTERVAL * (nx - 3)
    gu = max(n_samples, 64)
    gv = max(int(round(gu * h / w)), 48)
    uu, vv = np.meshgrid(np.linspace(0, w - 1, gu), np.linspace(0, h - 1, gv))
    pixels = np.column_stack([uu.ravel(), vv.ravel()])
    rays = cal.rays(pixels)
    ok = reachable(rays, max_angle_deg)
    if ok.sum() < 100:
        raise LeanFitError(f"only {int(ok.sum())} rays of the image could be unprojected; too few to fit mrcal's "
                           "splined model")
    pixels, rays = pixels[ok], rays[ok]
    u = stereographic(rays)
    reach = np.abs(u).max(axis=0)  # the knots must cover every ray of the image, both ways from the axis
    fov = int(np.ceil(np.degrees(4.0 * np.arctan(reach[0] / 2.0)) + 0.5))
    if fov >= 360:
        raise LeanFitError("the image's rays reach round past 180° off axis; mrcal's splined model cannot hold them")
    spu = segments_per_u(nx, fov)
    ny = max(4, int(np.ceil(2.0 * reach[1] * spu)) + 3)
    core = np.asarray(cal.model.intrinsics[:4], dtype=np.float64)
    target = (pixels - core[2:4]) / core[:2] - u  # the Δu each sample asks for
    a = design(u, nx, ny, spu)
    reg = _second_differences(nx, ny)
    # Normal equations: the system is small (Nx·Ny ≤ 40·30 unknowns per axis) and sparse.
    lhs = (a.T @ a + SMOOTHING * (reg.T @ reg)).tocsc()
    solve = spla.factorized(lhs)
    rhs = a.T @ target
    control = np.column_stack([solve(rhs[:, 0]), solve(rhs[:, 1])]).reshape(ny, nx, 2)
    return SplinedStereographic(core, control, fov)
