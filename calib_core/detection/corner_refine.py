"""Where exactly a corner is: refinement windows that follow the local square, cornerSubPix
with them, and the saddle-point fit every corner ends with. Arrays of N corners at once."""
from __future__ import annotations

import cv2
import numpy as np

SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3)


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


SADDLE_BLUR = 1.5        # px, Gaussian pre-smoothing of the image for the saddle fit
SADDLE_STEPS = 3         # re-centred fits
MAX_SADDLE_SHIFT = 1.5   # px the fit may move from cornerSubPix's answer; a corner whose saddle lies further is dropped


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


def polish(gray: np.ndarray, pts: np.ndarray, half: np.ndarray, max_shift: float) -> tuple[np.ndarray, np.ndarray]:
    """cornerSubPix then the saddle fit of corners pts (N, 2) with half-windows half (N,);
    (polished (N, 2), kept (N,) bool): a corner is kept where the image is a saddle there
    and the polish moved it at most ``max_shift`` px (further: the first estimate was on
    something else, a marker's edge say, and the corner is dropped, not guessed)."""
    refined = refine(gray, pts, half)
    out, det = saddle_fit(smoothed(gray), refined, half)
    return out, (det < 0) & (np.linalg.norm(out - pts, axis=1) <= max_shift)
