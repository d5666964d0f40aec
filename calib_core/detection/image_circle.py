"""Where a fisheye's image circle ends: the unlit frame around it, and the circle itself.

A corner whose refinement window reaches into the unlit region is not a
corner of the board: its dark quadrants merge with the void and cornerSubPix
snaps onto the circle's rim. ``distance_to_unlit`` gives, per pixel, how far
the nearest unlit pixel is, so that test is one lookup per corner.
"""
from __future__ import annotations

import functools

import cv2
import numpy as np

from ..evaluation.coverage import Circle
from .quantiles import percentiles

BLUR_SIGMA = 2.0
BLUR_REACH = 8      # OpenCV's kernel radius for BLUR_SIGMA: round(8 σ + 1) | 1 taps
UNLIT = 12          # grey level (after a light blur) below which a pixel got no light
MIN_SHARE = 0.002   # unlit regions smaller than this share of the frame are shadows, not the void


def distance_to_unlit(gray: np.ndarray) -> np.ndarray:
    """(H, W) float32 distance (px) from each pixel to the unlit region that touches the
    frame's border (a lens's image circle ends there); very large where there is none."""
    h, w = gray.shape
    if _border_lit(gray):
        return np.full((h, w), 1e9, np.float32)
    dark = (cv2.GaussianBlur(gray, (0, 0), BLUR_SIGMA) < UNLIT).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=8)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    is_void = np.zeros(n, bool)   # per label: a lookup, not a search of every pixel's label
    is_void[[k for k in border if k > 0 and stats[k, cv2.CC_STAT_AREA] >= MIN_SHARE * h * w]] = True
    if not is_void.any():
        return np.full((h, w), 1e9, np.float32)
    lit = (~is_void[labels]).astype(np.uint8)
    return cv2.distanceTransform(lit, cv2.DIST_L2, 5)


class UnlitDistance:
    """``distance_to_unlit(gray)``, computed at its first lookup (``self[y, x]``): most
    grids never look (a board seen whole has no corner left to confirm), and the map costs
    more than the rest of their checks."""

    def __init__(self, gray: np.ndarray):
        self._gray = gray
        self._map: np.ndarray | None = None

    def __getitem__(self, index):
        if self._map is None:
            self._map = distance_to_unlit(self._gray)
        return self._map[index]


def _border_lit(gray: np.ndarray) -> bool:
    """True when no pixel within the blur's reach of the frame's border is unlit: then
    no blurred border pixel is, and no unlit region touches the border (the common,
    rectilinear case, decided without blurring the whole image)."""
    r = BLUR_REACH + 1
    strips = (gray[:r], gray[-r:], gray[:, :r], gray[:, -r:])
    return min(int(s.min()) for s in strips) >= UNLIT


# ---- the image circle itself: where the lens's light ends, as a circle ---------------------------
# (for the coverage advice: ``evaluation.coverage`` counts and names only cells inside it)


CIRCLE_WORK_SIDE = 400   # px: the circle is found on a copy this long, a few px are enough for coverage cells
CIRCLE_RAYS = 180        # directions from the frame's centre in which the outermost lit pixel is looked for
LIT_ABOVE_BLACK = 10     # grey levels above the frame's black that count as light (video black is 16, not 0)
MAX_FRAME_BLACK = 40     # a frame darker than this at its 5th percentile may hold an image circle
MIN_DARK_FRAME = 0.3     # share of the frame's border that must be black: a photo lit to its border has no circle
MIN_RIM_RAYS = 0.25      # share of the rays that must end inside the frame (not leave it lit)
MIN_ON_CIRCLE = 0.5      # share of those rays' ends within RIM_TOLERANCE of the fitted circle
RIM_TOLERANCE = 0.01     # of the radius (at least 1.5 px of the working copy)
MIN_CIRCLE_SHARE = 0.5   # of a set's photos that must show the circle for the set to have one
_FIFTH = np.array([5]) / 100


def find_image_circle(gray: np.ndarray) -> Circle | None:
    """(cx, cy, radius) in pixels of the lit disc of a fisheye whose image circle
    ends inside the frame (black around it), or None for an image lit to its border.

    In each direction from the frame's centre the outermost lit pixel is the rim
    (a dark scene inside the circle does not move it, unlike the edge of the unlit
    region); directions that leave the frame lit are skipped (a circle cut by the
    frame), and a circle is fitted to the rest, ignoring ends off it (a dark rim).
    """
    h, w = gray.shape
    k = min(1.0, CIRCLE_WORK_SIDE / max(h, w))
    size = (round(w * k), round(h * k)) if k < 1 else (w, h)
    # Most photos are decided from the border of the reduced copy alone, which is reduced
    # from the frame's edges (``_Border``): the whole copy costs more than the rest of the search.
    small = None
    border = _Border.of(gray, size)
    if border is None:
        small = _reduced(gray, size)
        border = _Border.unreduced(small)
    frame = border.frame()
    black = float(percentiles(frame.astype(np.float64), _FIFTH)[0])   # np.percentile(frame, 5)
    if black > MAX_FRAME_BLACK or np.mean(frame <= black + LIT_ABOVE_BLACK) < MIN_DARK_FRAME:
        return None
    # A ray whose outermost lit pixel lies within a px of the border leaves the frame lit: when
    # too few rays are left that can end inside it, there is no rim to look for (a dim photo lit
    # to its border; each of OpenCV's 9x6 photos), decided from the border's pixels alone.
    if border.rays_not_surely_leaving(black + LIT_ABOVE_BLACK) < MIN_RIM_RAYS * CIRCLE_RAYS:
        return None
    small = _reduced(gray, size) if small is None else small
    sh, sw = small.shape
    lit = cv2.GaussianBlur(small, (0, 0), 1.0) > black + LIT_ABOVE_BLACK
    ends = _outermost_lit(lit)
    leaves = _leaves(ends, sw, sh)
    ends = ends[~leaves]
    if len(ends) < MIN_RIM_RAYS * CIRCLE_RAYS:
        return None
    cx, cy, r = _robust_circle(ends)
    on = _on_circle(ends, (cx, cy, r))
    if on.mean() < MIN_ON_CIRCLE or r < 0.25 * min(sw, sh) or not (0 <= cx < sw and 0 <= cy < sh):
        return None
    # pixel centres: full = (small + 0.5) / k - 0.5
    return (cx + 0.5) / k - 0.5, (cy + 0.5) / k - 0.5, r / k


def _reduced(gray: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    return gray if size == (gray.shape[1], gray.shape[0]) else cv2.resize(gray, size, interpolation=cv2.INTER_AREA)


BORDER_DEPTH = 5   # rows of the reduced copy by each side: the band a ray leaves through (2) and the blur's reach (3)


class _Border:
    """The reduced copy's strips along the frame's four sides, BORDER_DEPTH (or a few more) deep:
    top, bottom (rows), left, right (columns), as ``_reduced`` gives them.

    INTER_AREA makes each reduced pixel from the frame pixels it covers alone, with weights
    set by the scale; a strip of the frame an exact number of reduced rows deep reduces, at the
    same scale, to those reduced rows (checked equal on every photo of the real sets). Where no
    such strip is shallow (the scale's fraction has a large denominator), there is none."""

    def __init__(self, strips: list[np.ndarray], size: tuple[int, int]):
        self.top, self.bottom, self.left, self.right = strips
        self.size = size

    @classmethod
    def of(cls, gray: np.ndarray, size: tuple[int, int]) -> _Border | None:
        """The border of ``gray`` reduced to ``size``; None where no shallow strip reduces exactly."""
        h, w = gray.shape
        sw, sh = size
        if size == (w, h):
            return cls.unreduced(gray)
        ny, nx = _strip_depth(h, sh), _strip_depth(w, sw)
        if ny is None or nx is None:
            return None
        my, mx = ny * h // sh, nx * w // sw   # frame rows (columns) of ny (nx) reduced ones
        strips = [_reduced(gray[:my], (sw, ny)), _reduced(gray[h - my:], (sw, ny)),
                  _reduced(gray[:, :mx], (nx, sh)), _reduced(gray[:, w - mx:], (nx, sh))]
        return cls(strips, size)

    @classmethod
    def unreduced(cls, gray: np.ndarray) -> _Border:
        h, w = gray.shape
        ny, nx = min(BORDER_DEPTH, h), min(BORDER_DEPTH, w)
        return cls([gray[:ny], gray[h - ny:], gray[:, :nx], gray[:, w - nx:]], (w, h))

    def frame(self) -> np.ndarray:
        """The reduced copy's outermost pixels: its first and last row, first and last column."""
        return np.concatenate([self.top[0], self.bottom[-1], self.left[:, 0], self.right[:, -1]])

    def rays_not_surely_leaving(self, above: float) -> int:
        """How many rays may have their outermost lit pixel (lit: blurred as in
        ``find_image_circle``, brighter than ``above``) away from the border: all rays holding a
        pixel, less those with a lit pixel in their tail (``_ray_tails``), whose outermost lit
        pixel lies there, within a px of the border."""
        sw, sh = self.size
        lit = np.zeros((sh, sw), bool)
        blur = [cv2.GaussianBlur(s, (0, 0), 1.0) > above for s in (self.top, self.bottom, self.left, self.right)]
        lit[:2], lit[-2:], lit[:, :2], lit[:, -2:] = blur[0][:2], blur[1][-2:], blur[2][:, :2], blur[3][:, -2:]
        tails, starts, rays = _ray_tails((sh, sw))
        leaving = int(np.count_nonzero(np.maximum.reduceat(lit.ravel()[tails], starts))) if len(tails) else 0
        return rays - leaving


def _strip_depth(n: int, m: int) -> int | None:
    """Reduced rows (at least BORDER_DEPTH) that n frame rows reduced to m cover exactly, whole
    frame rows: a multiple of m / gcd(n, m); None when that is a sizeable part of the copy."""
    step = m // np.gcd(n, m)
    depth = -(-BORDER_DEPTH // step) * step
    return depth if 4 * depth <= m else None


@functools.lru_cache(maxsize=4)
def _ray_tails(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, int]:
    """For a frame of ``shape``: the flat indices of each ray's tail (its pixels farther from the
    centre than every one of its pixels away from the border: all within a px of it), ray by
    ray, where each nonempty tail starts among them, and how many rays hold a pixel."""
    order, starts, xx, yy = _rays_of(shape)
    band = (xx <= 1) | (yy <= 1) | (xx >= shape[1] - 2) | (yy >= shape[0] - 2)
    sizes = np.diff(np.r_[starts, len(order)])
    ray = np.repeat(np.arange(CIRCLE_RAYS), sizes)
    pos = np.arange(len(order))
    inner = np.full(CIRCLE_RAYS, -1)
    np.maximum.at(inner, ray[~band], pos[~band])   # each ray's farthest pixel away from the border
    tail = pos > inner[ray]
    tail_starts = np.flatnonzero(tail & np.r_[True, ray[1:] != ray[:-1]] | tail & ~np.r_[False, tail[:-1]])
    return order[tail], np.searchsorted(np.flatnonzero(tail), tail_starts), int(np.count_nonzero(sizes))


def common_circle(circles: list[Circle | None]) -> Circle | None:
    """The image circle of a set (one per photo read, None where none was found): the
    median of the photos' circles when at least half of them show one, else None."""
    found = [c for c in circles if c is not None]
    if not circles or len(found) < MIN_CIRCLE_SHARE * len(circles):
        return None
    cx, cy, r = np.median(np.asarray(found, dtype=np.float64), axis=0)
    return float(cx), float(cy), float(r)


def _outermost_lit(lit: np.ndarray) -> np.ndarray:
    """(n, 2) x, y of the lit pixel farthest from the centre in each of CIRCLE_RAYS directions that has one."""
    order, starts, xx, yy = _rays_of(lit.shape)
    on = lit.ravel()[order]
    # in each ray's run (pixels sorted by distance), the last lit one: the largest position holding light
    last = np.maximum.reduceat(np.where(on, np.arange(len(on)), -1), np.minimum(starts, len(on) - 1))
    last[np.diff(np.r_[starts, len(on)]) == 0] = -1   # a ray no pixel lies in (a frame of a few pixels)
    last = last[last >= 0]
    return np.column_stack([xx[last], yy[last]]).astype(np.float64)


def _leaves(ends: np.ndarray, w: int, h: int) -> np.ndarray:
    """(n,) bool: ray ends (n, 2) x, y within a px of the border of a frame w × h."""
    return (ends[:, 0] <= 1) | (ends[:, 1] <= 1) | (ends[:, 0] >= w - 2) | (ends[:, 1] >= h - 2)


@functools.lru_cache(maxsize=4)
def _rays_of(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For a frame of ``shape``: its pixels ordered by ray then distance from the centre, where
    each ray's run starts, and the ordered pixels' x, y (the same for every photo of a set)."""
    yy, xx = np.indices(shape).reshape(2, -1)
    oy, ox = (shape[0] - 1) / 2, (shape[1] - 1) / 2
    ray = ((np.arctan2(yy - oy, xx - ox) + np.pi) / (2 * np.pi) * CIRCLE_RAYS).astype(np.int64) % CIRCLE_RAYS
    order = np.lexsort((np.hypot(xx - ox, yy - oy), ray))
    starts = np.searchsorted(ray[order], np.arange(CIRCLE_RAYS))
    return order, starts, xx[order], yy[order]


def _robust_circle(pts: np.ndarray, trials: int = 200) -> Circle:
    """The circle through most of pts (n, 2): the best of ``trials`` circles through three of
    them (RANSAC, seeded: the same photo gives the same circle), refitted on those it holds.
    A dark stretch of the rim ends its rays short, inside the circle: a least-squares fit to
    all of them would be pulled inwards."""
    rng = np.random.default_rng(0)
    best = np.zeros(len(pts), bool)
    for k in rng.integers(0, len(pts), (trials, 3)):
        try:
            on = _on_circle(pts, _fit_circle(pts[k]))
        except np.linalg.LinAlgError:
            continue
        if on.sum() > best.sum():
            best = on
    return _fit_circle(pts[best] if best.sum() >= 3 else pts)


def _on_circle(pts: np.ndarray, circle: Circle) -> np.ndarray:
    cx, cy, r = circle
    return np.abs(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy) - r) < max(1.5, RIM_TOLERANCE * r)


def _fit_circle(pts: np.ndarray) -> Circle:
    """Least-squares circle through pts (n, 2): x² + y² = 2 cx x + 2 cy y + c (Kåsa's fit)."""
    x, y = pts[:, 0], pts[:, 1]
    sol, *_ = np.linalg.lstsq(np.column_stack([x, y, np.ones_like(x)]), x * x + y * y, rcond=None)
    cx, cy = sol[0] / 2, sol[1] / 2
    return float(cx), float(cy), float(np.sqrt(max(sol[2] + cx * cx + cy * cy, 0.0)))
