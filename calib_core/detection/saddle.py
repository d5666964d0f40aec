"""Is there a chessboard X-junction here, with the square colours its id says?

A grown or predicted corner is only kept if the image around it reads as the
corner of four checker squares: two diagonally opposite quadrants bright, the
other two dark, and *which* diagonal is bright fixed by the corner's lattice
parity (the square whose top-left corner is corner (r, c) is bright iff r + c
is even, OpenCV's convention). A point on a straight edge, on the board's
white border, in a tag, or one lattice step off (a wrong id) fails: the last
is the parity test, and it is why a wrong id is rarer than a missing corner.

Everything here works on arrays of N corners at once.
"""
from __future__ import annotations

import cv2
import numpy as np

SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3)
# Sample points per quadrant in units of the local lattice steps, near the corner: the
# tags of tagged boards (BabelCalib's AprilTags, border 2 of 9 bits) start beyond 0.22
# of a square, so these stay on the squares' plain margins.
_QUARTER = np.array([[0.2, 0.2], [0.12, 0.28], [0.28, 0.12]])
_SIGNS = np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]])  # TL, TR, BL, BR in (along row, down column)
MIN_CONTRAST = 12.0      # grey levels between a corner's bright and dark quadrants
SEPARATION = 0.35        # darkest bright quadrant must exceed the brightest dark one by this share


def nearest_corner(e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """Distance (N,) px to the nearest other lattice corner, diagonals included: on a steeply
    sheared view the diagonal neighbour across the acute angle is much nearer than a side."""
    return np.min([np.linalg.norm(v, axis=-1) for v in (e_col, e_row, e_col + e_row, e_col - e_row)], axis=0)


def window_holds_one_corner(spacing: np.ndarray) -> np.ndarray:
    """(N,) bool: the refinement window (half_window) of a corner whose nearest other corner is
    spacing (N,) px away holds no other corner. At a fisheye's horizon squares shrink to a few
    px and the diagonal neighbour falls inside even the smallest window: no fit can separate them."""
    return spacing > np.sqrt(2) * half_window(spacing) + 1


def half_window(spacing: np.ndarray) -> np.ndarray:
    """cornerSubPix half-window (N,) int for local lattice steps (N,) px: a quarter square,
    2..10 px. Larger windows reach across curved edges of distorted squares and into tags;
    a window wider than half a square reaches the next corner."""
    return np.clip(np.rint(np.nan_to_num(spacing, nan=8.0) / 4), 2, 10).astype(int)


def capture_window(spacing: np.ndarray) -> np.ndarray:
    """A wider first window (N,) for predictions that may be a few px off on large squares:
    a third of a square (up to 20 px) still keeps the neighbouring corners out."""
    return np.clip(np.rint(np.nan_to_num(spacing, nan=8.0) / 3), 2, 20).astype(int)


def refine(gray: np.ndarray, pts: np.ndarray, half: np.ndarray) -> np.ndarray:
    """cornerSubPix of pts (N, 2), each with its own half-window half (N,); one call per size."""
    out = pts.astype(np.float64).copy()
    for h in np.unique(half):
        sel = half == h
        p = pts[sel].astype(np.float32).reshape(-1, 1, 2)
        out[sel] = cv2.cornerSubPix(gray, p, (int(h), int(h)), (-1, -1), SUBPIX).reshape(-1, 2)
    return out


def quadrant_levels(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray,
                    reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Grey level (N, 4) of the TL, TR, BL, BR quadrants around corners pts (N, 2), the
    quadrants spanned by the local lattice steps e_col (to the next column) and e_row (to the
    next row), (N, 2) each: the median of three samples, so one tag bit or speck cannot flip it.
    reach (N,) scales the samples' distance (1: a fifth of a square along the diagonal)."""
    offs = (_SIGNS[:, None, :] * _QUARTER[None, :, :]).reshape(-1, 2)        # (12, 2)
    r = np.broadcast_to(np.asarray(reach, dtype=np.float64), (len(pts),))[:, None, None]
    at = pts[:, None, :] + r * (offs[None, :, :1] * e_col[:, None, :] + offs[None, :, 1:] * e_row[:, None, :])
    m = at.astype(np.float32).reshape(-1, 1, 2)
    vals = cv2.remap(gray, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return np.median(vals.reshape(len(pts), 4, len(_QUARTER)).astype(np.float64), axis=2)


def is_corner(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray, even: np.ndarray,
              half: np.ndarray) -> np.ndarray:
    """(N,) bool: an X-junction of the right colours both a fifth of a square out and within
    the refinement window. The near test matters on large squares: there a point that
    cornerSubPix left on an edge, a window's width from the corner, still has the right
    colours a fifth of a square out."""
    spacing = np.minimum(np.linalg.norm(e_col, axis=1), np.linalg.norm(e_row, axis=1))
    near = np.clip(0.6 * half / np.maximum(0.2 * spacing, 1e-9), 0.0, 1.0)
    levels = quadrant_levels(gray, pts, e_col, e_row)
    contrast = np.abs(levels[:, [0, 3]].mean(1) - levels[:, [1, 2]].mean(1))
    step = arm_steps(gray, pts, e_col, e_row)
    return (is_x_junction(levels, even) & is_x_junction(quadrant_levels(gray, pts, e_col, e_row, near), even)
            & (step >= ARM_CONTRAST * contrast))


ARM_AT = 0.25         # of a square along each of the four edges leaving a corner ...
ARM_SIDE = 0.12       # ... sampled this far either side of it (inside a tag's black border)
ARM_CONTRAST = 0.35   # of the corner's contrast, across every arm


def arm_steps(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """(N,) weakest grey-level step across the four edges leaving each corner, halfway to the
    next corner: on a true corner each separates a bright square from a dark one. A corner on the board's outermost line (the white
    margin and a printed frame beyond it: a T-junction that passes the quadrant test) has
    one arm with the same colour on both sides."""
    arms = np.stack([e_col, -e_col, e_row, -e_row], 1)                 # (N, 4, 2)
    across = np.stack([e_row, e_row, e_col, e_col], 1)
    side = np.linalg.norm(across, axis=-1, keepdims=True)
    off = across / np.maximum(side, 1e-9) * np.clip(ARM_SIDE * side, 1.5, 0.2 * side)
    mid = pts[:, None, :] + ARM_AT * arms
    m = np.stack([mid + off, mid - off], 2).astype(np.float32).reshape(-1, 1, 2)
    v = cv2.remap(gray, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    v = v.reshape(len(pts), 4, 2).astype(np.float64)
    step = np.abs(v[..., 0] - v[..., 1]).min(1)
    return step


def is_x_junction(levels: np.ndarray, even: np.ndarray) -> np.ndarray:
    """(N,) bool: quadrant levels (N, 4) show a checker corner whose TL and BR squares are
    bright where even (N,) (corner (r, c) with r + c even), dark elsewhere."""
    diag = levels[:, [0, 3]]       # TL, BR
    anti = levels[:, [1, 2]]       # TR, BL
    bright = np.where(even[:, None], diag, anti)
    dark = np.where(even[:, None], anti, diag)
    contrast = bright.mean(1) - dark.mean(1)
    gap = bright.min(1) - dark.max(1)
    return (contrast >= MIN_CONTRAST) & (gap >= SEPARATION * contrast)


SADDLE_BLUR = 1.5        # px, Gaussian pre-smoothing of the image for the saddle fit
SADDLE_STEPS = 3         # re-centred fits
MAX_SADDLE_SHIFT = 1.5   # px the fit may move from cornerSubPix's answer; further is left to cornerSubPix


def smoothed(gray: np.ndarray) -> np.ndarray:
    """The image as float32, lightly blurred: a saddle fit wants a smooth surface."""
    return cv2.GaussianBlur(gray.astype(np.float32), (0, 0), SADDLE_BLUR)


def saddle_fit(smooth: np.ndarray, pts: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Saddle points (N, 2) of a quadratic surface fitted to the smoothed image over each
    corner's window (half (N,)), and the surface's Hessian determinant (N,) (< 0: a saddle).

    A chessboard corner is the saddle of the blurred image: fitting
    z = a x² + b xy + c y² + d x + e y + f and solving ∇z = 0 is unbiased where cornerSubPix
    (which balances gradients across the whole window) is pulled by the curved edges of
    strongly distorted squares. Gaussian weights (σ = half / 2) keep the fit local.
    """
    out, det = pts.astype(np.float64).copy(), np.full(len(pts), np.nan)
    for h in np.unique(half):
        sel = np.flatnonzero(half == h)
        o = np.arange(-h, h + 1, dtype=np.float64)
        dx, dy = (a.ravel() for a in np.meshgrid(o, o))
        wts = np.exp(-(dx ** 2 + dy ** 2) / (2 * (h / 2) ** 2))
        design = np.stack([dx * dx, dx * dy, dy * dy, dx, dy, np.ones_like(dx)], 1) * wts[:, None] ** 0.5
        pinv = np.linalg.pinv(design)                                      # (6, M): one fit matrix for all
        p = out[sel]
        for _ in range(SADDLE_STEPS):
            m = (p[:, None, :] + np.stack([dx, dy], 1)[None]).astype(np.float32)
            z = cv2.remap(smooth, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            a, b, c, d, e, _ = pinv @ (z.reshape(len(sel), -1) * wts ** 0.5).T   # (6, n)
            dd = 4 * a * c - b * b
            with np.errstate(all="ignore"):
                step = np.stack([(b * e - 2 * c * d) / dd, (b * d - 2 * a * e) / dd], 1)
            step = np.where(np.isfinite(step) & (np.abs(step) <= h), step, 0.0)
            p = p + step
        out[sel], det[sel] = p, dd
    return out, det
