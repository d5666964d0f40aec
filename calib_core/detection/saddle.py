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
    return _quadrant_medians(_sampled(gray, _quadrant_points(pts, e_col, e_row, reach)), len(pts))


def _quadrant_points(pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray,
                     reach: np.ndarray | float = 1.0) -> np.ndarray:
    """(N * 12, 2) float32: ``quadrant_levels``' sample points, corner by corner, quadrant by quadrant."""
    offs = (_SIGNS[:, None, :] * _QUARTER[None, :, :]).reshape(-1, 2)        # (12, 2)
    r = np.broadcast_to(np.asarray(reach, dtype=np.float64), (len(pts),))[:, None, None]
    at = pts[:, None, :] + r * (offs[None, :, :1] * e_col[:, None, :] + offs[None, :, 1:] * e_row[:, None, :])
    return at.astype(np.float32).reshape(-1, 2)


REMAP_ROWS = 32_000   # remap's maps must have fewer than 2^15 rows


def _sampled(gray: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(K,) float64 grey levels at points m (K, 2) float32, bilinear."""
    m = m.reshape(-1, 1, 2)
    vals = [cv2.remap(gray, c[..., 0], c[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(-1)
            for c in (m[k:k + REMAP_ROWS] for k in range(0, len(m), REMAP_ROWS))]
    return np.concatenate(vals).astype(np.float64) if vals else np.zeros(0)


def _quadrant_medians(vals: np.ndarray, n: int) -> np.ndarray:
    return np.sort(vals.reshape(n, 4, len(_QUARTER)), axis=2)[..., 1]  # the median of 3


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
        spacing = np.minimum(np.linalg.norm(e_col, axis=1), np.linalg.norm(e_row, axis=1))
        near = np.clip(0.6 * half / np.maximum(0.2 * spacing, 1e-9), 0.0, 1.0)
        # the three readings' points in one remap: each point's level is its own, and a call
        # with its conversions cost more than its sampling
        n = len(pts)
        vals = _sampled(gray, np.concatenate([_quadrant_points(pts, e_col, e_row),
                                              _quadrant_points(pts, e_col, e_row, near),
                                              _arm_points(pts, e_col, e_row)]))
        levels, near_levels = _quadrant_medians(vals[:12 * n], n), _quadrant_medians(vals[12 * n:24 * n], n)
        contrast = np.abs(levels[:, [0, 3]].mean(1) - levels[:, [1, 2]].mean(1))
        arms_ok = _weakest_arm(vals[24 * n:], n) >= ARM_CONTRAST * contrast
        return cls(levels, near_levels, arms_ok)

    def is_corner(self, even: np.ndarray) -> np.ndarray:
        """(N,) bool: ``is_corner`` with the TL and BR squares bright where even (N,)."""
        return is_x_junction(self.levels, even) & is_x_junction(self.near, even) & self.arms_ok


ARM_AT = 0.25         # of a square along each of the four edges leaving a corner ...
ARM_SIDE = 0.12       # ... sampled this far either side of it (inside a tag's black border)
ARM_CONTRAST = 0.35   # of the corner's contrast, across every arm


def arm_steps(gray: np.ndarray, pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """(N,) weakest grey-level step across the four edges leaving each corner, halfway to the
    next corner: on a true corner each separates a bright square from a dark one. A corner on the board's outermost line (the white
    margin and a printed frame beyond it: a T-junction that passes the quadrant test) has
    one arm with the same colour on both sides."""
    return _weakest_arm(_sampled(gray, _arm_points(pts, e_col, e_row)), len(pts))


def _arm_points(pts: np.ndarray, e_col: np.ndarray, e_row: np.ndarray) -> np.ndarray:
    """(N * 8, 2) float32: ``arm_steps``' sample points, corner by corner, arm by arm, side by side."""
    arms = np.stack([e_col, -e_col, e_row, -e_row], 1)                 # (N, 4, 2)
    across = np.stack([e_row, e_row, e_col, e_col], 1)
    side = np.linalg.norm(across, axis=-1, keepdims=True)
    off = across / np.maximum(side, 1e-9) * np.clip(ARM_SIDE * side, 1.5, 0.2 * side)
    mid = pts[:, None, :] + ARM_AT * arms
    return np.stack([mid + off, mid - off], 2).astype(np.float32).reshape(-1, 2)


def _weakest_arm(vals: np.ndarray, n: int) -> np.ndarray:
    v = vals.reshape(n, 4, 2)
    return np.abs(v[..., 0] - v[..., 1]).min(1)


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
