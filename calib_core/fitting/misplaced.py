"""Corners that do not sit where their board neighbours put them.

A corner labelled with the wrong id, or thrown far off by the program that
found it, wrecks the first camera every method starts from: the homographies
that pose the views are least-squares fits, and one corner thousands of pixels
off moves them more than the whole lens does. The outlier rounds that follow a
fit would then judge residuals of a wrong camera.

What is asked of a corner needs no camera: over its nearest board neighbours
(a square and a half around it) any lens, however wide, maps the board nearly
as a homography does, so the homography fitted to the neighbours predicts the
corner to a small share of the local square. A corner missing that prediction by
more than ``MAX_MISS`` of the square is misplaced. One misplaced corner also spoils its
neighbours' predictions, so each round takes only the worst corner of each
neighbourhood, and the predictions are made again without it.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

# Share of the local square (pixels per nearest-neighbour board distance) a corner may
# miss its neighbours' prediction by. Clean corners beyond the noise floor missed by 0.29
# at most (the 200° fisheye's train views; docs/method.md, "Misplaced corners"); a corner
# given its neighbour's id misses by a whole square.
MAX_MISS = 0.4
NEIGHBOURHOOD = 1.6   # board distance searched, in nearest-neighbour spacings: the 3 x 3 ring
MIN_NEIGHBOURS = 5    # a homography needs 4; fewer than 5 (a board's corner) leave nothing to check it
MAX_ROUNDS = 6
# The homography's square over its neighbours' RMS spread: 0.26-1.3 on clean corners (0.1st-99.9th
# percentiles over every synthetic kind); a ring outside these bounds is not judged.
SPREAD_AGREEMENT = (0.25, 4.0)
OUTSIDE = 0.1         # share of the image's diagonal a corner may lie beyond its frame (a lens seen to the border)
RING_SPREAD = 4.0      # a neighbour this many times the ring's median distance from its median is left out
SPACING_SAMPLE = 64   # corners of a view whose nearest neighbours give its spacing
NOISE_MULTIPLE = 10.0  # times the set's median miss, which noise alone sets (about 1.2 sigma)


def misplaced_corners(object_points: np.ndarray, image_points: np.ndarray, view_index: np.ndarray,
                      image_size: tuple[int, int]) -> np.ndarray:
    """(N,) bool: corners beyond the image by more than ``OUTSIDE`` of its diagonal
    (no camera saw them there), and corners of planar views (Z = 0) that miss their
    board neighbours' homography prediction by more than ``MAX_MISS`` of the local
    square and by more than ``NOISE_MULTIPLE`` times the median corner's miss (noisy
    corners on small squares are noise, not misplaced). Views of a 3-D object are
    judged by the image alone (their neighbours may lie on another face)."""
    w, h = image_size
    margin = OUTSIDE * float(np.hypot(w, h))
    with np.errstate(invalid="ignore"):
        outside = ~np.all((image_points >= -margin) & (image_points <= np.array([w - 1, h - 1]) + margin), axis=1)
    if len(object_points) <= MIN_NEIGHBOURS:
        return outside
    planar = np.ones(int(view_index.max()) + 1, dtype=bool)  # views of a 3-D object: judged by the image alone
    np.logical_and.at(planar, view_index, object_points[:, 2] == 0)
    ring = _Rings(object_points[:, :2], view_index, planar[view_index])
    missed = ring.miss(image_points, outside)
    judged = missed[0][np.isfinite(missed[0])]
    if not len(judged):
        return outside
    return ring.misplaced(image_points, NOISE_MULTIPLE * float(np.median(judged)), outside, missed)


class _Rings:
    """Every corner's board neighbours within ``NEIGHBOURHOOD`` spacings (its view's median
    nearest-neighbour distance) in its own view, all views at once (one tree, views set apart)."""

    def __init__(self, board: np.ndarray, view_index: np.ndarray, judged: np.ndarray):
        apart = np.column_stack([board, view_index * 10.0 * (float(np.ptp(board)) + 1.0)])  # views set apart
        tree = cKDTree(apart)
        # Each view's spacing: the median distance to the nearest other corner, over its first
        # SPACING_SAMPLE corners (the distance is the same all over a board; a query per corner
        # cost 19 ms at 100 views).
        order = np.argsort(view_index, kind="stable")
        rank = np.empty(len(board), dtype=np.int64)
        rank[order] = np.arange(len(board)) - np.searchsorted(view_index[order], view_index[order])
        sample = np.flatnonzero(rank < SPACING_SAMPLE)
        dist, _ = tree.query(apart[sample], k=3)  # the nearest other corner: the second, or the third past a twin
        nearest = np.where(dist[:, 1] > 0, dist[:, 1], dist[:, 2])  # a corner given twice is no spacing
        spacing = _group_medians(nearest, view_index[sample], np.isfinite(nearest) & (nearest > 0),
                                 int(view_index.max()) + 1)
        self.judged = judged & (spacing[view_index] > 0)
        self.board = board / np.where(spacing > 0, spacing, 1.0)[view_index, None]  # in spacings
        k = min(len(board), 13)  # the 3 x 3 ring and some, self included
        dist, nbr = tree.query(apart, k=k, distance_upper_bound=NEIGHBOURHOOD * max(float(spacing.max()), 1e-300))
        dist, nbr = dist[:, 1:], nbr[:, 1:]
        self.found = (dist > 0) & (dist <= NEIGHBOURHOOD * spacing[view_index, None]) & self.judged[:, None]
        self.nbr = np.where(self.found, nbr, 0)
        self.found &= self.judged[self.nbr]

    def miss(self, pixels: np.ndarray, flagged: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(miss px, square px, neighbours used) of each corner not ``flagged``, its flagged
        neighbours left out (NaN where fewer than ``MIN_NEIGHBOURS`` remain)."""
        use = self.found & ~flagged[self.nbr] & np.all(np.isfinite(pixels), axis=1)[self.nbr]
        # Neighbours far from the ring's median are left out of its homography: two misplaced
        # corners side by side would otherwise each spoil the other's neighbourhood, and
        # neither be judged.
        around = pixels[self.nbr]
        centre = np.stack([_row_median(around[..., c], use) for c in range(2)], axis=1)
        spread = np.linalg.norm(around - centre[:, None], axis=2)
        use &= ~(spread > RING_SPREAD * _row_median(spread, use)[:, None])
        miss, square = _miss(self.board, pixels, self.nbr, use)
        enough = (use.sum(axis=1) >= MIN_NEIGHBOURS) & ~flagged & self.judged
        return np.where(enough, miss, np.nan), square, use

    def misplaced(self, pixels: np.ndarray, floor: float, outside: np.ndarray, first: tuple) -> np.ndarray:
        """The corners misplaced, ``first`` the misses with only those ``outside`` left out."""
        flagged = outside.copy()
        for round_ in range(MAX_ROUNDS):
            miss, square, use = first if round_ == 0 else self.miss(pixels, flagged)
            over = np.nan_to_num(miss) > np.maximum(MAX_MISS * np.nan_to_num(square, nan=np.inf), floor)
            if not over.any():
                break
            # The worst of each neighbourhood only: its neighbours' misses are partly its doing.
            rival = np.where(use & over[self.nbr], np.nan_to_num(miss)[self.nbr], 0.0).max(axis=1)
            flagged |= over & (miss >= rival)
        return flagged


def _group_medians(values: np.ndarray, group: np.ndarray, valid: np.ndarray, n_groups: int) -> np.ndarray:
    """(n_groups,) the median of each group's ``valid`` values (0 where none), by one sort."""
    order = np.lexsort((values, group))
    order = order[valid[order]]
    g, v = group[order], values[order]
    counts = np.bincount(g, minlength=n_groups)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    has = counts > 0
    low = v[(starts + (counts - 1) // 2)[has]]
    high = v[(starts + counts // 2)[has]]
    out = np.zeros(n_groups)
    out[has] = 0.5 * (low + high)
    return out


def _row_median(a: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(N,) the median of each row's ``valid`` entries of ``a`` (N, k) (0 where none):
    a sort of a dozen values a row, where ``np.nanmedian`` took most of this module's time."""
    ordered = np.sort(np.where(valid, a, np.inf), axis=1)
    n = valid.sum(axis=1)
    low = np.take_along_axis(ordered, np.maximum((n - 1) // 2, 0)[:, None], axis=1)[:, 0]
    high = np.take_along_axis(ordered, np.maximum(n // 2, 0)[:, None], axis=1)[:, 0]
    return np.where(n > 0, 0.5 * (low + high), 0.0)


def _miss(board: np.ndarray, pixels: np.ndarray, nbr: np.ndarray, use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) each corner's distance (px) from its neighbours' homography prediction, and
    (N,) the local square (px per board spacing; ``board`` is in spacings); NaN where the
    neighbours fix none.
    A homography, not an affine map: a board seen steeply shrinks its squares along the
    tilt, which an affine map over a 3 x 3 ring misreads by half a square (measured on
    the synthetic hold-out views). Board offsets are taken from the corner itself, so
    the homography's last entry is the prediction's denominator there, and is set to 1
    (``_ring_homographies``)."""
    x = board[nbr] - board[:, None]                                  # (N, k, 2) board offsets, in spacings
    n_use = np.maximum(use.sum(axis=1), 1)
    centre = np.where(use[..., None], pixels[nbr], 0.0).sum(axis=1) / n_use[:, None]
    du = np.where(use[..., None], pixels[nbr] - centre[:, None], 0.0)
    scale = np.sqrt(np.sum(du**2, axis=(1, 2)) / n_use)
    u = du / np.maximum(scale, 1e-12)[:, None, None]                 # (N, k, 2) pixel offsets, unit spread
    h = _ring_homographies(x, u, use)                                # (N, 8)
    jac = np.stack([h[:, [0, 1]] - h[:, 2:3] * h[:, [6, 7]], h[:, [3, 4]] - h[:, 5:6] * h[:, [6, 7]]], axis=1)
    square = scale * np.sqrt(np.abs(np.linalg.det(jac)))                # pixels per board spacing at the corner
    predicted = centre + scale[:, None] * h[:, [2, 5]]
    # A homography from a one-sided ring of noisy corners can be wild (a board's edge: two
    # columns of corners); its square then disagrees with the neighbours' own spread.
    good = (square > SPREAD_AGREEMENT[0] * scale) & (square < SPREAD_AGREEMENT[1] * scale)
    return np.where(good, np.linalg.norm(pixels - predicted, axis=1), np.nan), np.where(good, square, np.nan)


@njit(cache=True, nogil=True)
def _ring_homographies(x: np.ndarray, u: np.ndarray, use: np.ndarray) -> np.ndarray:
    """(N, 8) each ring's homography, its last entry 1: u (h7 x + h8 y + 1) = h1 x + h2 y + h3
    and the same for v with h4, h5, h6, least squares over the ring's ``use``d neighbours
    (offsets ``x``, pixels ``u``). A ridge of 1e-9 of the trace keeps every system solvable;
    where the neighbours leave a direction free (on one line) its entries stay near 0, and
    the caller's check of the square rejects the fit. Compiled: a dozen neighbours a corner,
    where NumPy's stacked arrays cost 40 times the arithmetic."""
    n, k = use.shape
    out = np.zeros((n, 8))
    a = np.zeros((8, 8))
    b = np.zeros(8)
    row = np.zeros(8)
    for i in range(n):
        a[:] = 0.0
        b[:] = 0.0
        for j in range(k):
            if not use[i, j]:
                continue
            for c in range(2):
                row[:] = 0.0
                row[3 * c], row[3 * c + 1], row[3 * c + 2] = x[i, j, 0], x[i, j, 1], 1.0
                row[6], row[7] = -u[i, j, c] * x[i, j, 0], -u[i, j, c] * x[i, j, 1]
                for p in range(8):
                    b[p] += row[p] * u[i, j, c]
                    for q in range(8):
                        a[p, q] += row[p] * row[q]
        ridge = 0.0
        for p in range(8):
            ridge += a[p, p]
        for p in range(8):
            a[p, p] += 1e-9 * ridge + 1e-300
        out[i] = _solve8(a, b)
    return out


@njit(cache=True, nogil=True)
def _solve8(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b by Gaussian elimination with partial pivoting (a and b are overwritten)."""
    m = len(b)
    for c in range(m):
        pivot = c
        for r in range(c + 1, m):
            if abs(a[r, c]) > abs(a[pivot, c]):
                pivot = r
        if pivot != c:
            for q in range(m):
                a[c, q], a[pivot, q] = a[pivot, q], a[c, q]
            b[c], b[pivot] = b[pivot], b[c]
        for r in range(c + 1, m):
            f = a[r, c] / a[c, c]
            for q in range(c, m):
                a[r, q] -= f * a[c, q]
            b[r] -= f * b[c]
    x = np.zeros(m)
    for r in range(m - 1, -1, -1):
        acc = b[r]
        for q in range(r + 1, m):
            acc -= a[r, q] * x[q]
        x[r] = acc / a[r, r]
    return x

