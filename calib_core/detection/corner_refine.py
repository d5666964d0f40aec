"""Where exactly a corner is: refinement windows that follow the local square, cornerSubPix
with them, and the saddle-point fit every corner ends with. Arrays of N corners at once."""
from __future__ import annotations

import functools

import cv2
import numpy as np
from numba import njit

SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3)


def nearest_corner(e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """Distance (...) px to the nearest other lattice corner, diagonals included, for local
    steps e_col, e_row (..., 2) (NaN where a step is): on a steeply sheared view the diagonal
    neighbour across the acute angle is much nearer than a side."""
    shape = np.shape(e_col)[:-1]
    flat = [np.ascontiguousarray(e, dtype=np.float64).reshape(-1, 2) for e in (e_col, e_row)]
    return _nearest_corner(*flat).reshape(shape)


@njit(cache=True, nogil=True)
def _nearest_corner(e_col, e_row):  # pragma: no cover (compiled; the same numbers as np.linalg.norm, np.min)
    out = np.empty(len(e_col))
    for i in range(len(e_col)):
        cx, cy, rx, ry = e_col[i, 0], e_col[i, 1], e_row[i, 0], e_row[i, 1]
        m = np.sqrt(cx * cx + cy * cy)
        for vx, vy in ((rx, ry), (cx + rx, cy + ry), (cx - rx, cy - ry)):
            d = np.sqrt(vx * vx + vy * vy)
            m = d if np.isnan(d) or d < m else m   # NaN wins, as in np.min
        out[i] = m
    return out


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
# A saddle that can be located: fitted again from where it ended, the fit stays put (every
# re-centred step within the window, the last at most SETTLED px), and the window one px
# smaller puts it within WINDOW_AGREEMENT px. Where a tag's bits, a dim blurred horizon or a
# curved edge shape the surface, the saddle follows the window instead (BabelCalib ov_plane:
# its 3 corners more than 1 px from the authors', 1.1-2.6 px; tried at 0.3/0.75 px too).
SETTLED = 0.1            # px
WINDOW_AGREEMENT = 0.5   # px


# Corners per matrix product of the saddle fits: OpenBLAS runs a product of more than 2^18
# multiplications on all its threads (6 x 441 x 100 here), which took 0.23 ms where 200 corners
# took 0.03 ms on one thread, and up to 16 ms on a busy machine (measured, 2 cores); below that
# it stays on the calling thread, beside the other images' processes.
BLAS_COLUMNS = 64

SADDLE_BLUR_REACH = 7    # px: OpenCV's float kernel for SADDLE_BLUR has round(8 σ + 1) | 1 = 13 taps, radius 6


def smoothed(gray: np.ndarray) -> np.ndarray:
    """The image as float32, lightly blurred: a saddle fit wants a smooth surface."""
    return cv2.GaussianBlur(gray.astype(np.float32), (0, 0), SADDLE_BLUR)


def saddle_points(gray: np.ndarray, pts: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``saddle_fit`` of pts (N, 2) on the image smoothed only where the fits can look: the
    box round the corners, widened by the farthest a fit reaches (its window, re-centred
    SADDLE_STEPS times by at most the window's half each, then twice that for ``located``'s
    fits) and the blur's own reach. Blurring the whole frame cost three times the fits on
    OpenCV's 9x6 photos (a board a third of a VGA frame).

    Returns (saddle points (N, 2), Hessian determinants (N,), located (N,) bool: ``located``)."""
    finite = np.all(np.isfinite(pts), axis=1)
    if not finite.any():
        smooth = smoothed(gray)
        fitted, det = saddle_fit(smooth, pts, half)
        return fitted, det, located(smooth, fitted, half)
    reach = (2 * SADDLE_STEPS + 1) * int(half.max()) + 2 + SADDLE_BLUR_REACH
    h, w = gray.shape[:2]
    x0, y0 = np.maximum(np.floor(pts[finite].min(0)).astype(int) - reach, 0)
    x1, y1 = np.minimum(np.ceil(pts[finite].max(0)).astype(int) + reach + 1, [w, h])
    origin = np.array([x0, y0], np.float64)
    smooth = smoothed(gray[y0:y1, x0:x1])
    fitted, det = saddle_fit(smooth, pts - origin, half)
    return fitted + origin, det, located(smooth, fitted, half)


def located(smooth: np.ndarray, fitted: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(N,) bool: saddle points fitted (N, 2) with half-windows half (N,) that the image
    locates to sub-pixel: the fit started from each again settles where it is (no step
    refused, the last at most SETTLED px), and with a window one px smaller (at least 2) it
    lands within WINDOW_AGREEMENT px. A saddle shaped by what lies inside the window (a tag's
    bits next to the corner, a blurred dim corner at a fisheye's horizon) moves with the
    window; the one cornerSubPix's answer kept because every step of the fit was refused
    (no saddle within reach) does not settle."""
    n = len(fitted)
    # both fits in one pass: each corner's fit is on its own, and a pass costs mostly its calls
    both, _, both_settled = _saddle_iterate(smooth, np.concatenate([fitted, fitted]),
                                            np.concatenate([half, np.maximum(half - 1, 2)]))
    again, smaller = both[:n], both[n:]
    settled, settled_smaller = both_settled[:n], both_settled[n:]
    agree = np.linalg.norm(smaller - fitted, axis=1) <= WINDOW_AGREEMENT
    return settled & settled_smaller & agree & (np.linalg.norm(again - fitted, axis=1) <= SETTLED)


def saddle_fit(smooth: np.ndarray, pts: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Saddle points (N, 2) of a quadratic surface fitted to the smoothed image over each
    corner's window (half (N,)), and the surface's Hessian determinant (N,) (< 0: a saddle).

    A chessboard corner is the saddle of the blurred image: fitting
    z = a x² + b xy + c y² + d x + e y + f and solving ∇z = 0 is unbiased where cornerSubPix
    (which balances gradients across the whole window) is pulled by the curved edges of
    strongly distorted squares. Gaussian weights (σ = half / 2) keep the fit local.
    """
    out, det, _ = _saddle_iterate(smooth, pts, half)
    return out, det


def _saddle_iterate(smooth: np.ndarray, pts: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``saddle_fit``, and (N,) bool: every re-centred step was taken (none refused for
    leaving the window or for a flat surface) and the last moved at most SETTLED px.

    All corners at once, whatever their windows: each is sampled over the largest window
    and fitted with its own window's weighted fit, zero outside it (``_saddle_fits``), so a
    step is one remap and a matrix product per window size (a pass of every step per window
    size, 3-7 of them on OpenCV's 9x6 and GoPro photos, cost its calls several times over)."""
    n = len(pts)
    if n == 0:
        return pts.astype(np.float64).copy(), np.full(0, np.nan), np.zeros(0, bool)
    order = np.argsort(half, kind="stable")          # corners of one window size side by side
    half_s = half[order]
    sizes, starts = np.unique(half_s, return_index=True)
    ends = np.append(starts[1:], n)
    (dx, dy), fits = _saddle_fits(tuple(int(h) for h in sizes))
    p = pts[order].astype(np.float64)
    lim = half_s.astype(np.float64)
    coef = np.empty((6, n))
    taken = np.ones(n, bool)
    step = np.zeros((n, 2))
    dd = np.empty(n)
    mx, my = np.empty((n, dx.size), np.float32), np.empty((n, dx.size), np.float32)
    for _ in range(SADDLE_STEPS):
        _sample_maps(p, dx, dy, mx, my)
        zt = cv2.remap(smooth, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).T.astype(np.float64)
        for fit, s0, s1 in zip(fits, starts, ends, strict=True):
            for c0 in range(s0, s1, BLAS_COLUMNS):
                c1 = min(c0 + BLAS_COLUMNS, s1)
                coef[:, c0:c1] = fit @ zt[:, c0:c1]
        _saddle_step(coef, lim, p, taken, step, dd)
    settled = taken & (np.sqrt(step[:, 0] * step[:, 0] + step[:, 1] * step[:, 1]) <= SETTLED)
    out, det, sure = np.empty_like(p), np.empty(n), np.empty(n, bool)
    out[order], det[order], sure[order] = p, dd, settled
    return out, det, sure


# A step's arithmetic on the fitted coefficients is compiled: as array expressions it was a dozen
# NumPy calls a step on a few dozen corners, each holding the GIL. The kernels do those
# expressions' floating-point operations in their order, so every step is the same to the last bit.


@njit(cache=True, nogil=True)
def _sample_maps(p, dx, dy, mx, my):  # pragma: no cover (compiled)
    """Into mx, my (N, M) float32: the pixels of each corner's window, p (N, 2) plus the offsets
    dx, dy (M,), summed in float64 and rounded once."""
    for i in range(len(p)):
        for m in range(len(dx)):
            mx[i, m] = p[i, 0] + dx[m]
            my[i, m] = p[i, 1] + dy[m]


@njit(cache=True, nogil=True, error_model="numpy")  # a flat surface divides by 0: inf/nan, refused below
def _saddle_step(coef, lim, p, taken, step, dd):  # pragma: no cover (compiled)
    """One re-centred step of every corner from the surfaces' coefficients coef (6, N): the
    Hessian determinants into dd (N,), the step to the saddle into step (N, 2) (0 where refused:
    not finite, or longer than lim (N,) either way), p (N, 2) moved by it, taken (N,) cleared
    where refused."""
    for i in range(len(p)):
        a, b, c, d, e = coef[0, i], coef[1, i], coef[2, i], coef[3, i], coef[4, i]
        dd[i] = 4 * a * c - b * b
        sx = (b * e - 2 * c * d) / dd[i]
        sy = (b * d - 2 * a * e) / dd[i]
        ok = np.isfinite(sx) and np.isfinite(sy) and abs(sx) <= lim[i] and abs(sy) <= lim[i]
        taken[i] = taken[i] and ok
        step[i, 0], step[i, 1] = (sx, sy) if ok else (0.0, 0.0)
        p[i, 0] += step[i, 0]
        p[i, 1] += step[i, 1]


@functools.lru_cache(maxsize=64)
def _saddle_fits(sizes: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """For half-windows ``sizes`` (ascending): the largest window's pixel offsets (2, M) and
    each size's weighted quadratic fit (its pseudo-inverse times the square roots of the
    Gaussian weights) laid on that window, zero outside its own: (len(sizes), 6, M)."""
    big = sizes[-1]
    o = np.arange(-big, big + 1, dtype=np.float64)
    dx, dy = (a.ravel() for a in np.meshgrid(o, o))
    fits = np.zeros((len(sizes), 6, dx.size))
    for k, h in enumerate(sizes):
        (hx, hy), sqrt_wts, pinv = _saddle_design(h)
        at = (hy + big).astype(int) * (2 * big + 1) + (hx + big).astype(int)
        fits[k][:, at] = pinv * sqrt_wts
    return np.stack([dx, dy]), fits


@functools.lru_cache(maxsize=16)
def _saddle_design(h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a (2h+1)² window: its pixel offsets (2, M), the square roots of their Gaussian
    weights (M,) and the weighted quadratic fit's pseudo-inverse (6, M), one for all corners
    (a pseudo-inverse per call cost as much as the fits themselves)."""
    o = np.arange(-h, h + 1, dtype=np.float64)
    dx, dy = (a.ravel() for a in np.meshgrid(o, o))
    wts = np.exp(-(dx ** 2 + dy ** 2) / (2 * (h / 2) ** 2))
    design = np.stack([dx * dx, dx * dy, dy * dy, dx, dy, np.ones_like(dx)], 1) * wts[:, None] ** 0.5
    return np.stack([dx, dy]), wts ** 0.5, np.linalg.pinv(design)


def polish(gray: np.ndarray, pts: np.ndarray, half: np.ndarray, max_shift: float) -> tuple[np.ndarray, np.ndarray]:
    """cornerSubPix then the saddle fit of corners pts (N, 2) with half-windows half (N,);
    (polished (N, 2), kept (N,) bool): a corner is kept where the image is a saddle there
    that it locates (``located``) and the polish moved it at most ``max_shift`` px (further:
    the first estimate was on something else, a marker's edge say, and the corner is
    dropped, not guessed)."""
    refined = refine(gray, pts, half)
    out, det, sure = saddle_points(gray, refined, half)
    return out, (det < 0) & sure & (np.linalg.norm(out - pts, axis=1) <= max_shift)
