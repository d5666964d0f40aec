"""Corners that do not sit where their board neighbours put them.

A corner labelled with the wrong id, or thrown far off by the program that
found it, wrecks the first camera every method starts from: the homographies
that pose the views are least-squares fits, and one corner 5 000 px off moves
them more than the whole lens does. The outlier rounds that follow a fit then
judge residuals of a wrong camera (a fisheye set with a tenth of one view so
thrown: 70 px rms, returned as a calibration).

What is asked of a corner needs no camera: over its nearest board neighbours
(a square and a half around it) any lens, however wide, maps the board nearly
as a homography does, so the homography fitted to the neighbours predicts the
corner to a small share of the local square. A corner missing that prediction by more than
``MAX_MISS`` of the square is misplaced. One misplaced corner also spoils its
neighbours' predictions, so each round takes only the worst corner of each
neighbourhood, and the predictions are made again without it.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

# Share of the local square (pixels per nearest-neighbour board distance) a corner may
# miss its neighbours' prediction by. Clean corners beyond the noise floor missed by 0.29
# at most (the 200° fisheye's train views; docs/method.md, "Misplaced corners"); a corner
# given its neighbour's id misses by a whole square.
MAX_MISS = 0.4
NEIGHBOURHOOD = 1.6   # board distance searched, in nearest-neighbour spacings: the 3 x 3 ring
MIN_NEIGHBOURS = 5    # a homography needs 4; fewer than 5 (a board's corner) leave nothing to check it
MAX_ROUNDS = 6
SPREAD_AGREEMENT = (0.25, 4.0)  # the homography's square over the neighbours' RMS spread (px), clean: 0.6-1.5
OUTSIDE = 0.1         # share of the image's diagonal a corner may lie beyond its frame (a lens seen to the border)
RING_SPREAD = 4.0      # a neighbour this many times the ring's median distance from its median is left out
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
    views = []
    for v in np.unique(view_index):
        idx = np.flatnonzero(view_index == v)
        obj = object_points[idx]
        if len(idx) > MIN_NEIGHBOURS and np.all(obj[:, 2] == 0):
            neighbours = _Neighbours(obj[:, :2])
            if neighbours.spacing > 0:
                views.append((idx, neighbours))
    first = [n.miss(image_points[idx], outside[idx]) for idx, n in views]
    judged = np.concatenate([miss for miss, _, _ in first] + [np.zeros(0)])
    judged = judged[np.isfinite(judged)]
    out = outside.copy()
    if not len(judged):
        return out
    floor = NOISE_MULTIPLE * float(np.median(judged))
    for (idx, n), missed in zip(views, first, strict=True):
        out[idx] = n.misplaced(image_points[idx], floor, outside[idx], missed)
    return out


class _Neighbours:
    """A view's corners' board neighbours (within ``NEIGHBOURHOOD`` spacings)."""

    def __init__(self, board: np.ndarray):
        self.board = board
        tree = cKDTree(board)
        nearest = tree.query(board, k=2)[0][:, 1]
        nearest = nearest[np.isfinite(nearest) & (nearest > 0)]  # a corner given twice is no spacing
        self.spacing = float(np.median(nearest)) if len(nearest) else 0.0
        dist, nbr = tree.query(board, k=min(len(board), 13), distance_upper_bound=NEIGHBOURHOOD * self.spacing)
        self.found = np.isfinite(dist[:, 1:]) & (dist[:, 1:] > 0)  # self excluded; 13: the 3 x 3 ring and some
        self.nbr = np.where(self.found, nbr[:, 1:], 0)

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
        miss, square = _miss(self.board, pixels, self.nbr, use, self.spacing)
        enough = (use.sum(axis=1) >= MIN_NEIGHBOURS) & ~flagged
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


def _row_median(a: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(N,) the median of each row's ``valid`` entries of ``a`` (N, k) (0 where none):
    a sort of a dozen values a row, where ``np.nanmedian`` took most of this module's time."""
    ordered = np.sort(np.where(valid, a, np.inf), axis=1)
    n = valid.sum(axis=1)
    low = np.take_along_axis(ordered, np.maximum((n - 1) // 2, 0)[:, None], axis=1)[:, 0]
    high = np.take_along_axis(ordered, np.maximum(n // 2, 0)[:, None], axis=1)[:, 0]
    return np.where(n > 0, 0.5 * (low + high), 0.0)


def _miss(board: np.ndarray, pixels: np.ndarray, nbr: np.ndarray, use: np.ndarray,
          spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) each corner's distance (px) from its neighbours' homography prediction, and
    (N,) the local square (px per board spacing); NaN where the neighbours fix none.
    A homography, not an affine map: a board seen steeply shrinks its squares along the
    tilt, which an affine map over a 3 x 3 ring misreads by half a square (measured on
    the synthetic hold-out views). Board offsets are taken from the corner itself, so
    the homography's last entry is the prediction's denominator there, and is set to 1
    (8 unknowns, normal equations solved for every corner at once)."""
    x = (board[nbr] - board[:, None]) / spacing                      # (N, k, 2) board offsets
    n_use = np.maximum(use.sum(axis=1), 1)
    centre = np.where(use[..., None], pixels[nbr], 0.0).sum(axis=1) / n_use[:, None]
    du = np.where(use[..., None], pixels[nbr] - centre[:, None], 0.0)
    scale = np.sqrt(np.sum(du**2, axis=(1, 2)) / n_use)
    u = du / np.maximum(scale, 1e-12)[:, None, None]                 # (N, k, 2) pixel offsets, unit spread
    one, zero = use.astype(float), np.zeros(x.shape[:2])
    xw, yw = x[..., 0] * one, x[..., 1] * one
    # u (h31 x + h32 y + 1) = h11 x + h12 y + h13, and the same for v with h21, h22, h23.
    rows = np.concatenate([
        np.stack([xw, yw, one, zero, zero, zero, -u[..., 0] * xw, -u[..., 0] * yw], axis=2),
        np.stack([zero, zero, zero, xw, yw, one, -u[..., 1] * xw, -u[..., 1] * yw], axis=2)], axis=1)
    rhs = np.concatenate([u[..., 0], u[..., 1]], axis=1)              # unused rows are zero on both sides
    ata = np.matmul(rows.transpose(0, 2, 1), rows)
    atb = np.matmul(rows.transpose(0, 2, 1), rhs[..., None])
    # A ridge keeps every system solvable; where the neighbours leave a direction free (on
    # one line), its columns stay near 0, and the square's check below rejects the fit.
    ata += 1e-9 * (np.trace(ata, axis1=1, axis2=2) + 1e-300)[:, None, None] * np.eye(8)
    h = np.linalg.solve(ata, atb)[..., 0]                              # (N, 8)
    jac = np.stack([h[:, [0, 1]] - h[:, 2:3] * h[:, [6, 7]], h[:, [3, 4]] - h[:, 5:6] * h[:, [6, 7]]], axis=1)
    square = scale * np.sqrt(np.abs(np.linalg.det(jac)))                # pixels per board spacing at the corner
    predicted = centre + scale[:, None] * h[:, [2, 5]]
    # A homography from a one-sided ring of noisy corners can be wild (a board's edge: two
    # columns of corners); its square then disagrees with the neighbours' own spread.
    good = (square > SPREAD_AGREEMENT[0] * scale) & (square < SPREAD_AGREEMENT[1] * scale)
    return np.where(good, np.linalg.norm(pixels - predicted, axis=1), np.nan), np.where(good, square, np.nan)
