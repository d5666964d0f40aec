"""Is there a chessboard X-junction here, with the square colours its id says?

A grown or predicted corner is only kept if the image around it reads as the
corner of four checker squares: two diagonally opposite quadrants bright, the
other two dark, and *which* diagonal is bright fixed by the corner's lattice
parity (the square whose top-left corner is corner (r, c) is bright iff r + c
is even, OpenCV's convention). A point on a straight edge, on the board's
white border, in a tag, or one lattice step off (a wrong id) fails: the last
is the parity test, and it is why a wrong id is rarer than a missing corner.
Each of the four edges leaving the corner must also separate a bright square
from a dark one (``arm_steps``), which a T-junction on the board's outer line
does not. Where the corner then sits exactly is ``corner_refine``'s job.

Everything here works on arrays of N corners at once.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

# Sample points per quadrant in units of the local lattice steps, near the corner: the
# tags of tagged boards (BabelCalib's AprilTags, border 2 of 9 bits) start beyond 0.22
# of a square, so these stay on the squares' plain margins.
_QUARTER = np.array([[0.2, 0.2], [0.12, 0.28], [0.28, 0.12]])
_SIGNS = np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]])  # TL, TR, BL, BR in (along row, down column)
MIN_CONTRAST = 12.0      # grey levels between a corner's bright and dark quadrants
SEPARATION = 0.35        # darkest bright quadrant must exceed the brightest dark one by this share


def quadrant_levels(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray,
                    reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Grey level (N, 4) of the TL, TR, BL, BR quadrants around corners pts (N, 2), the
    quadrants spanned by the local lattice steps e_col (to the next column) and e_row (to the
    next row), (N, 2) each: the median of three samples, so one tag bit or speck cannot flip it.
    reach (N,) scales the samples' distance (1: a fifth of a square along the diagonal)."""
    pts, e_col, e_row = _float64(pts, e_col, e_row)
    r = np.ascontiguousarray(np.broadcast_to(np.asarray(reach, dtype=np.float64), (len(pts),)))
    at = np.empty((len(pts) * _QUADRANT_SAMPLES, 2), np.float32)
    _quadrant_points(pts, e_col, e_row, r, at)
    return _quadrant_medians(_sampled(gray, at), len(pts))


def _float64(*arrays: np.ndarray) -> list[np.ndarray]:
    return [np.ascontiguousarray(a, dtype=np.float64) for a in arrays]


REMAP_ROWS = 32_000   # remap's maps must have fewer than 2^15 rows


def _sampled(gray: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(K,) float64 grey levels at points m (K, 2) float32, bilinear."""
    m = m.reshape(-1, 1, 2)
    vals = [cv2.remap(gray, c[..., 0], c[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(-1)
            for c in (m[k:k + REMAP_ROWS] for k in range(0, len(m), REMAP_ROWS))]
    return np.concatenate(vals).astype(np.float64) if vals else np.zeros(0)


def is_corner(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray, even: np.ndarray,
              half: np.ndarray) -> np.ndarray:
    """(N,) bool: an X-junction of the right colours both a fifth of a square out and within
    the refinement window. The near test matters on large squares: there a point that
    cornerSubPix left on an edge, a window's width from the corner, still has the right
    colours a fifth of a square out."""
    return CornerReading.of(gray, pts, e_col, e_row, half).is_corner(even)


@dataclass
class CornerReading:
    """What the image shows around N corners, read once: the quadrants' grey levels (N, 4) a
    fifth of a square out and within the refinement window, and whether all four arms separate
    bright from dark. Which colours are right (the parity) is asked afterwards, so both
    parities cost one reading."""

    levels: np.ndarray
    near: np.ndarray
    arms_ok: np.ndarray

    @classmethod
    def of(cls, gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray,
           half: np.ndarray) -> CornerReading:
        # the three readings' points in one remap: each point's level is its own, and a call
        # with its conversions cost more than its sampling
        pts, e_col, e_row = _float64(pts, e_col, e_row)
        vals = _sampled(gray, _reading_points(pts, e_col, e_row, np.ascontiguousarray(half, dtype=np.float64)))
        return cls(*_reading(vals, len(pts)))

    def is_corner(self, even: np.ndarray) -> np.ndarray:
        """(N,) bool: ``is_corner`` with the TL and BR squares bright where even (N,)."""
        even = np.ascontiguousarray(even, dtype=np.bool_)
        return _x_junction(self.levels, even) & _x_junction(self.near, even) & self.arms_ok


ARM_AT = 0.25         # of a square along each of the four edges leaving a corner ...
ARM_SIDE = 0.12       # ... sampled this far either side of it (inside a tag's black border)
ARM_CONTRAST = 0.35   # of the corner's contrast, across every arm


def arm_steps(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """(N,) weakest grey-level step across the four edges leaving each corner, halfway to the
    next corner: on a true corner each separates a bright square from a dark one. A corner on the board's outermost line (the white
    margin and a printed frame beyond it: a T-junction that passes the quadrant test) has
    one arm with the same colour on both sides."""
    pts, e_col, e_row = _float64(pts, e_col, e_row)
    at = np.empty((len(pts) * _ARM_SAMPLES, 2), np.float32)
    _arm_points(pts, e_col, e_row, at)
    return _weakest_arms(_sampled(gray, at), len(pts))


def is_x_junction(levels: np.ndarray, even: np.ndarray) -> np.ndarray:
    """(N,) bool: quadrant levels (N, 4) show a checker corner whose TL and BR squares are
    bright where even (N,) (corner (r, c) with r + c even), dark elsewhere."""
    return _x_junction(np.ascontiguousarray(levels, dtype=np.float64), np.ascontiguousarray(even, dtype=np.bool_))


# The readings' arithmetic is compiled: as array expressions it was some fifty NumPy calls on a
# few dozen corners, each holding the GIL (images on threads waited for each other). Each kernel
# does the array expressions' floating-point operations in their order (and np.clip's, np.maximum's
# NaN-propagating comparisons), so the points, levels and decisions are the same to the last bit.

_QUADRANT_SAMPLES = 4 * len(_QUARTER)   # points per corner: three in each quadrant
_ARM_SAMPLES = 8                        # points per corner: both sides of four arms
_OFFSETS = (_SIGNS[:, None, :] * _QUARTER[None, :, :]).reshape(-1, 2)   # (12, 2), quadrant by quadrant


@njit(cache=True, nogil=True, inline="always")
def _maximum(a, b):  # pragma: no cover (compiled)
    """np.maximum of two floats (NaN in a wins)."""
    return a if np.isnan(a) or a > b else b


@njit(cache=True, nogil=True, inline="always")
def _minimum(a, b):  # pragma: no cover (compiled)
    """np.minimum of two floats (NaN in a wins)."""
    return a if np.isnan(a) or a < b else b


@njit(cache=True, nogil=True, inline="always")
def _clip(x, lo, hi):  # pragma: no cover (compiled)
    """np.clip of a float: the minimum of its maximum with lo, and hi (NaN in x wins)."""
    return _minimum(_maximum(x, lo), hi)


@njit(cache=True, nogil=True)
def _reading_points(pts, e_col, e_row, half):  # pragma: no cover (compiled)
    """(N * 32, 2) float32: ``CornerReading.of``'s points, the quadrants' a fifth of a square out
    (N * 12), the quadrants' within the refinement window (N * 12), the arms' (N * 8)."""
    n = len(pts)
    out = np.empty((n * (2 * _QUADRANT_SAMPLES + _ARM_SAMPLES), 2), np.float32)
    near = np.empty(n)
    for c in range(n):
        spacing = _minimum(np.sqrt(e_col[c, 0] * e_col[c, 0] + e_col[c, 1] * e_col[c, 1]),
                           np.sqrt(e_row[c, 0] * e_row[c, 0] + e_row[c, 1] * e_row[c, 1]))
        near[c] = _clip(0.6 * half[c] / _maximum(0.2 * spacing, 1e-9), 0.0, 1.0)
    _quadrant_points(pts, e_col, e_row, np.ones(n), out[:n * _QUADRANT_SAMPLES])
    _quadrant_points(pts, e_col, e_row, near, out[n * _QUADRANT_SAMPLES:2 * n * _QUADRANT_SAMPLES])
    _arm_points(pts, e_col, e_row, out[2 * n * _QUADRANT_SAMPLES:])
    return out


@njit(cache=True, nogil=True)
def _quadrant_points(pts, e_col, e_row, reach, out):  # pragma: no cover (compiled)
    """Into out (N * 12, 2) float32: ``quadrant_levels``' sample points, corner by corner,
    quadrant by quadrant."""
    for c in range(len(pts)):
        for o in range(len(_OFFSETS)):
            ox, oy = _OFFSETS[o, 0], _OFFSETS[o, 1]
            for d in range(2):
                out[c * len(_OFFSETS) + o, d] = pts[c, d] + reach[c] * (ox * e_col[c, d] + oy * e_row[c, d])


@njit(cache=True, nogil=True)
def _arm_points(pts, e_col, e_row, out):  # pragma: no cover (compiled)
    """Into out (N * 8, 2) float32: ``arm_steps``' sample points, corner by corner, arm by arm
    (along e_col, -e_col, e_row, -e_row), side by side (+, - across the arm)."""
    for c in range(len(pts)):
        for a in range(4):
            along = e_col[c] if a < 2 else e_row[c]
            across = e_row[c] if a < 2 else e_col[c]
            sign = 1.0 if a % 2 == 0 else -1.0
            side = np.sqrt(across[0] * across[0] + across[1] * across[1])
            reach = _clip(ARM_SIDE * side, 1.5, 0.2 * side)
            for d in range(2):
                mid = pts[c, d] + ARM_AT * (sign * along[d])
                off = across[d] / _maximum(side, 1e-9) * reach
                out[c * _ARM_SAMPLES + 2 * a, d] = mid + off
                out[c * _ARM_SAMPLES + 2 * a + 1, d] = mid - off


@njit(cache=True, nogil=True, inline="always")
def _median3(a, b, c):  # pragma: no cover (compiled)
    return max(min(a, b), min(max(a, b), c))


@njit(cache=True, nogil=True)
def _quadrant_medians(vals, n):  # pragma: no cover (compiled)
    """(N, 4) the median of each quadrant's three samples, vals (N * 12,) corner by corner."""
    out = np.empty((n, 4))
    for c in range(n):
        for q in range(4):
            k = c * 12 + q * 3
            out[c, q] = _median3(vals[k], vals[k + 1], vals[k + 2])
    return out


@njit(cache=True, nogil=True)
def _weakest_arms(vals, n):  # pragma: no cover (compiled)
    """(N,) the smallest step across the four arms, vals (N * 8,) as ``_arm_points`` lays them."""
    out = np.empty(n)
    for c in range(n):
        w = np.inf
        for a in range(4):
            w = min(w, abs(vals[c * _ARM_SAMPLES + 2 * a] - vals[c * _ARM_SAMPLES + 2 * a + 1]))
        out[c] = w
    return out


@njit(cache=True, nogil=True)
def _reading(vals, n):  # pragma: no cover (compiled)
    """``CornerReading``'s fields from the grey levels at ``_reading_points``."""
    q = n * _QUADRANT_SAMPLES
    levels, near = _quadrant_medians(vals[:q], n), _quadrant_medians(vals[q:2 * q], n)
    weakest = _weakest_arms(vals[2 * q:], n)
    arms_ok = np.empty(n, np.bool_)
    for c in range(n):
        contrast = abs((levels[c, 0] + levels[c, 3]) / 2 - (levels[c, 1] + levels[c, 2]) / 2)
        arms_ok[c] = weakest[c] >= ARM_CONTRAST * contrast
    return levels, near, arms_ok


@njit(cache=True, nogil=True)
def _x_junction(levels, even):  # pragma: no cover (compiled)
    out = np.empty(len(levels), np.bool_)
    for c in range(len(levels)):
        diag0, diag1, anti0, anti1 = levels[c, 0], levels[c, 3], levels[c, 1], levels[c, 2]
        b0, b1, d0, d1 = (diag0, diag1, anti0, anti1) if even[c] else (anti0, anti1, diag0, diag1)
        contrast = (b0 + b1) / 2 - (d0 + d1) / 2
        gap = min(b0, b1) - max(d0, d1)
        out[c] = (contrast >= MIN_CONTRAST) & (gap >= SEPARATION * contrast)
    return out
