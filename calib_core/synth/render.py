"""Photo-like chessboard images through the synthetic lenses, with exact corners.

Rendering is by inverse mapping, all vectorised:

1. every pixel centre is taken back through the true lens: its distorted
   normalised coordinates are inverted by Newton's method on ``true_distort``
   (smooth, so a few steps from the undistorted guess suffice). The result
   depends only on the lens and the image size, so it is cached and shared by
   all views;
2. the ray meets the board plane (Z = 0 in the board frame) at board
   coordinates b(u, v);
3. the board is shaded analytically (checker squares, a white border, a grey
   backdrop) at 4 × 4 sub-pixel samples placed with the local Jacobian of
   b(u, v): a box filter over the pixel, exact up to the map's curvature
   inside one pixel;
4. then Gaussian blur (optics) and Gaussian noise (sensor), 8 bit.

Pixel convention as in formats.md: pixel (row i, column j) is centred on
(x, y) = (j, i). Corner ``row*cols + col`` sits at board (col, row)·square and
the square whose top-left corner is corner (r, c) is bright iff r + c is even
(OpenCV's convention).
"""
from __future__ import annotations

import functools

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.spatial.transform import Rotation

from .. import synth
from ..observations import Observations, View

BLACK, WHITE, BACKDROP = 35.0, 215.0, 110.0  # grey levels: printed ink, paper, the room behind
BORDER_SQUARES = 1       # white paper around the outer squares, in squares (whole: every edge
                        # then lies on an integer line of the square lattice)
SUPERSAMPLE = 4         # samples per pixel along each axis
BLUR_SIGMA = 0.7        # px
NOISE_SIGMA = 2.0       # grey levels
NEWTON_STEPS = 30      # on the coarse lattice only


def pixel_rays(kind: str, image_size: tuple[int, int] = synth.IMAGE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised coordinates (H, W, 2) of every pixel centre, and a mask (H, W)
    of the pixels the lens covers (a fisheye's image circle ends before the frame's corners)."""
    return _pixel_rays(kind, tuple(int(n) for n in image_size))


@functools.lru_cache(maxsize=4)
def _pixel_rays(kind: str, image_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    w, h = image_size
    fx, fy, cx, cy = synth.INTRINSICS
    # Newton to convergence on a coarse lattice, a bicubic spline in between, then one
    # Newton step per pixel: the spline's error (~1e-6 px) squared is nothing, at a
    # fraction of the cost of iterating on every pixel.
    us, vs = _coarse(w), _coarse(h)
    cu, cv = np.meshgrid(us, vs)
    coarse = _invert_distortion(kind, np.stack([(cu.ravel() - cx) / fx, (cv.ravel() - cy) / fy], -1))
    coarse = _fill_nan(coarse.reshape(len(vs), len(us), 2))
    x = np.stack([RectBivariateSpline(vs, us, coarse[..., k])(np.arange(h), np.arange(w)) for k in (0, 1)], -1)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    target = np.stack([(u.ravel() - cx) / fx, (v.ravel() - cy) / fy], axis=-1)  # (N, 2)
    x = x.reshape(-1, 2)
    f, jx, jy = _residual_and_jacobian(kind, x, target)
    x = x - _solve2(jx, jy, f)
    ok = np.all(np.isfinite(x), axis=1)
    ok[ok] &= np.abs(synth.true_distort(kind, x[ok]) - target[ok]).max(axis=1) < 1e-10
    x[~ok] = 0.0
    return x.reshape(h, w, 2), ok.reshape(h, w)


def unit_rays(kind: str, image_size: tuple[int, int] = synth.IMAGE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Unit rays (H, W, 3) of every pixel centre and the mask (H, W) of the pixels the lens
    covers; a lens past 180° (``synth.WIDE_KINDS``) has rays behind the camera's plane too."""
    return _unit_rays(kind, tuple(int(n) for n in image_size))


@functools.lru_cache(maxsize=4)
def _unit_rays(kind: str, image_size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    w, h = image_size
    if kind in synth.WIDE_KINDS:
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        rays = synth.true_rays(kind, np.stack([u.ravel(), v.ravel()], axis=-1)).reshape(h, w, 3)
        covered = np.all(np.isfinite(rays), axis=-1)
        rays[~covered] = [0.0, 0.0, 1.0]
        return rays, covered
    xn, covered = pixel_rays(kind, image_size)
    rays = np.concatenate([xn, np.ones(xn.shape[:2] + (1,))], axis=-1)
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True), covered


def _coarse(n: int, stride: int = 4) -> np.ndarray:
    """Lattice 0, stride, ..., n-1 (both ends included)."""
    return np.unique(np.append(np.arange(0, n, stride), n - 1)).astype(np.float64)


def _fill_nan(a: np.ndarray) -> np.ndarray:
    """Grid (h, w, 2) with NaNs (no inverse: outside a fisheye's circle) replaced by the
    nearest finite value along rows, so the spline stays finite; those pixels are masked later."""
    bad = ~np.isfinite(a[..., 0])
    if bad.any():
        idx = np.where(~bad, np.arange(a.shape[1]), 0)
        np.maximum.accumulate(idx, axis=1, out=idx)
        a = np.take_along_axis(a, idx[..., None], axis=1)
        bad = ~np.isfinite(a[..., 0])
        a[bad] = 0.0
    return a


def _residual_and_jacobian(kind: str, x: np.ndarray, target: np.ndarray, eps: float = 1e-7):
    """f = distort(x) - target (N, 2) and the Jacobian's columns d/dx, d/dy (N, 2) each."""
    f = synth.true_distort(kind, x) - target
    # Forward differences: two extra lens evaluations, no derivative code per lens.
    jx = (synth.true_distort(kind, x + [eps, 0.0]) - target - f) / eps
    jy = (synth.true_distort(kind, x + [0.0, eps]) - target - f) / eps
    return f, jx, jy


def _solve2(jx: np.ndarray, jy: np.ndarray, f: np.ndarray) -> np.ndarray:
    """J^-1 f for 2 × 2 Jacobians given by columns (N, 2); NaN where J is singular."""
    det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
    det = np.where(np.abs(det) > 1e-12, det, np.nan)
    return np.stack([(jy[:, 1] * f[:, 0] - jy[:, 0] * f[:, 1]) / det,
                     (-jx[:, 1] * f[:, 0] + jx[:, 0] * f[:, 1]) / det], axis=-1)


def _invert_distortion(kind: str, target: np.ndarray) -> np.ndarray:
    """x (N, 2) with true_distort(kind, x) = target (N, 2); NaN where Newton fails."""
    x = target.copy()
    active = np.arange(len(x))
    for _ in range(NEWTON_STEPS):
        xa = x[active]
        f, jx, jy = _residual_and_jacobian(kind, xa, target[active])
        step = _solve2(jx, jy, f)
        # Damp steps that would jump across the lens (beyond a fisheye's horizon the map folds).
        n = np.linalg.norm(step, axis=1, keepdims=True)
        step *= np.minimum(1.0, 0.5 * (1.0 + np.linalg.norm(xa, axis=1, keepdims=True)) / np.maximum(n, 1e-300))
        x[active] = xa - step
        done = np.abs(f).max(axis=1) < 1e-12  # ~3e-10 px
        x[active[~np.isfinite(step[:, 0])]] = np.nan
        active = active[~done & np.isfinite(step[:, 0])]
        if active.size == 0:
            break
    x[active] = np.nan  # not converged
    return x


def board_coordinates(rays: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Board-plane points (H, W, 2), in mm, seen along rays from ``pose`` = [rvec | tvec]
    (board → camera): normalised coordinates (H, W, 2) or directions (H, W, 3); NaN where
    the ray misses the plane."""
    r = Rotation.from_rotvec(pose[:3]).as_matrix()
    centre = -r.T @ pose[3:]                                   # camera centre, board frame
    if rays.shape[-1] == 2:
        rays = np.concatenate([rays, np.ones(rays.shape[:2] + (1,))], axis=-1)
    d = rays @ r                                               # = R^T d, (H, W, 3)
    s = -centre[2] / d[..., 2]
    s = np.where(s > 0, s, np.nan)
    return centre[:2] + s[..., None] * d[..., :2]


def shade(b: np.ndarray, cols: int, rows: int, square: float) -> np.ndarray:
    """Reflectance (same shape as b[..., 0]) at board points b (..., 2) in mm."""
    q = b / square                                              # square units, corner 0 at (0, 0)
    i, j = np.floor(q[..., 0]), np.floor(q[..., 1])
    checker = np.where((i + j) % 2 == 0, WHITE, BLACK)
    on_squares = (q[..., 0] >= -1) & (q[..., 0] < cols) & (q[..., 1] >= -1) & (q[..., 1] < rows)
    m = BORDER_SQUARES
    on_paper = (q[..., 0] >= -1 - m) & (q[..., 0] < cols + m) & (q[..., 1] >= -1 - m) & (q[..., 1] < rows + m)
    out = np.where(on_squares, checker, np.where(on_paper, WHITE, BACKDROP))
    return np.where(np.isfinite(q[..., 0]), out, BACKDROP)


def render_view(kind: str, pose: np.ndarray, board: tuple[int, int] = synth.TRAIN_BOARD,
                square: float = synth.SQUARE, image_size: tuple[int, int] = synth.IMAGE_SIZE,
                rng: np.random.Generator | None = None, blur: float = BLUR_SIGMA,
                noise: float = NOISE_SIGMA) -> np.ndarray:
    """8-bit greyscale image (H, W) of a cols × rows (inner corners) chessboard at ``pose``."""
    rays, covered = unit_rays(kind, (image_size[0], image_size[1]))
    b = board_coordinates(rays, np.asarray(pose, dtype=np.float64))  # (H, W, 2)
    b[~covered] = np.nan
    # Local Jacobian of the pixel → board map (central differences = the best affine fit
    # over the pixel); the sub-pixel samples are placed with it.
    du = np.gradient(b, axis=1)
    dv = np.gradient(b, axis=0)
    cols, rows = board
    img = shade(b, cols, rows, square)
    # Only pixels whose footprint reaches an edge (an integer line of the square lattice)
    # are not uniform: those alone get the SUPERSAMPLE² box-filter samples.
    q = b / square
    reach = 0.5 * (np.abs(du) + np.abs(dv)) / square               # half footprint, (H, W, 2)
    gap = np.abs(q - np.rint(q))                                    # to the nearest line
    edge = np.any(~(gap > reach), axis=-1) & covered                # NaN counts as an edge
    bb, ddu, ddv = b[edge], du[edge], dv[edge]
    acc = np.zeros(len(bb))
    offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    for oy in offsets:          # 16 passes over the edge pixels, not a loop over pixels
        for ox in offsets:
            acc += shade(bb + ox * ddu + oy * ddv, cols, rows, square)
    img[edge] = acc / SUPERSAMPLE**2
    # Where one pixel spans more than a square (grazing views), samples alias: fade to the mean.
    footprint = np.maximum(np.linalg.norm(du, axis=-1), np.linalg.norm(dv, axis=-1)) / square
    fade = np.clip(np.nan_to_num(footprint, nan=0.0) - 0.5, 0.0, 1.0)
    fade[img == BACKDROP] = 0.0  # the plain backdrop has nothing to alias
    img = (1 - fade) * img + fade * 0.5 * (BLACK + WHITE)
    img[~covered] = 0.0  # outside a fisheye's image circle: no light
    if blur > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    if noise > 0:
        img = img + (rng or np.random.default_rng(0)).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def true_corners(kind: str, pose: np.ndarray, board: tuple[int, int] = synth.TRAIN_BOARD,
                 square: float = synth.SQUARE, image_size: tuple[int, int] = synth.IMAGE_SIZE,
                 margin: float = 2.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact, noise-free corners of a view: ids (N,), board points (N, 3), pixels (N, 2).

    Keeps the corners the lens sees (``synth.in_view``), inside the image by ``margin`` px and
    inside the lens's coverage (unlike ``synth.generate``, no 80° cut: a detector may
    well find those).
    """
    cols, rows = board
    pts = synth.board_points(cols, rows, square)
    pc = Rotation.from_rotvec(pose[:3]).apply(pts) + pose[3:]
    ok = synth.in_view(kind, pc)
    uv = np.full((len(pts), 2), np.nan)
    uv[ok] = synth.true_project(kind, pc[ok])
    w, h = image_size
    ok &= np.all(np.isfinite(uv), axis=1)
    ok &= (uv[:, 0] >= margin) & (uv[:, 0] <= w - 1 - margin) & (uv[:, 1] >= margin) & (uv[:, 1] <= h - 1 - margin)
    _, covered = unit_rays(kind, (image_size[0], image_size[1]))
    ok[ok] &= covered[np.rint(uv[ok, 1]).astype(int), np.rint(uv[ok, 0]).astype(int)]
    ids = np.flatnonzero(ok)
    return ids, pts[ids], uv[ids]


def render_set(kind: str, poses: list[tuple[str, np.ndarray]], seed: int = 0,
               board: tuple[int, int] = synth.TRAIN_BOARD, square: float = synth.SQUARE
               ) -> tuple[list[tuple[str, np.ndarray]], Observations]:
    """Images [(file name, (H, W) uint8)] of named poses and their exact corners
    (freecal.observations/1, views named like the files)."""
    rng = np.random.default_rng(seed)
    images, views = [], []
    for name, pose in poses:
        fname = f"{name}.png"
        images.append((fname, render_view(kind, pose, board, square, rng=rng)))
        ids, obj, uv = true_corners(kind, pose, board, square)
        views.append(View(fname, obj, uv, ids))
    cols, rows = board
    doc = {"type": "chessboard", "cols": cols, "rows": rows, "square_size": float(square), "units": "mm"}
    return images, Observations(synth.IMAGE_SIZE, views, doc)
