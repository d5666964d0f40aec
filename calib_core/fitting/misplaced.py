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

import warnings

import numpy as np
from scipy.spatial import cKDTree

# Share of the local square (pixels per nearest-neighbour board distance) a corner may
# miss its neighbours' prediction by. Clean corners miss by 0.06 at most on the
# rendered 200° fisheye's edges and the real sets (docs/method.md, "Misplaced corners");
# a corner given its neighbour's id misses by a whole square.
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
    first = [n.miss(image_points[idx], outside[idx])[0] for idx, n in views]
    judged = np.concatenate(first + [np.zeros(0)])
    judged = judged[np.isfinite(judged)]
    out = outside.copy()
    if not len(judged):
        return out
    floor = NOISE_MULTIPLE * float(np.median(judged))
    for idx, n in views:
        out[idx] = n.misplaced(image_points[idx], floor, outside[idx])
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
        around = np.where(use[..., None], pixels[self.nbr], np.nan)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a corner with no neighbour: all NaN
            spread = np.linalg.norm(around - np.nanmedian(around, axis=1)[:, None], axis=2)
            use &= ~(spread > RING_SPREAD * np.nanmedian(spread, axis=1)[:, None])
        miss, square = _miss(self.board, pixels, self.nbr, use, self.spacing)
        enough = (use.sum(axis=1) >= MIN_NEIGHBOURS) & ~flagged
        return np.where(enough, miss, np.nan), square, use

    def misplaced(self, pixels: np.ndarray, floor: float, outside: np.ndarray) -> np.ndarray:
        flagged = outside.copy()
        for _ in range(MAX_ROUNDS):
            miss, square, use = self.miss(pixels, flagged)
            over = np.nan_to_num(miss) > np.maximum(MAX_MISS * np.nan_to_num(square, nan=np.inf), floor)
            if not over.any():
                break
            # The worst of each neighbourhood only: its neighbours' misses are partly its doing.
            rival = np.where(use & over[self.nbr], np.nan_to_num(miss)[self.nbr], 0.0).max(axis=1)
            flagged |= over & (miss >= rival)
        return flagged


def _miss(board: np.ndarray, pixels: np.ndarray, nbr: np.ndarray, use: np.ndarray,
          spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) each corner's distance (px) from its neighbours' homography prediction, and
    (N,) the local square (px per board spacing); NaN where the neighbours fix none. A homography, not an affine map:
    a board seen steeply shrinks its squares along the tilt, which an affine map over a
    3 x 3 ring misreads by half a square (measured on the synthetic hold-out views)."""
    x = (board[nbr] - board[:, None]) / spacing                      # (N, k, 2) board offsets
    centre = np.where(use[..., None], pixels[nbr], 0.0).sum(axis=1) / np.maximum(use.sum(axis=1), 1)[:, None]
    du = np.where(use[..., None], pixels[nbr] - centre[:, None], 0.0)
    scale = np.sqrt(np.where(use, np.sum(du**2, axis=2), 0.0).sum(axis=1) / np.maximum(use.sum(axis=1), 1))
    u = du / np.maximum(scale, 1e-12)[:, None, None]                 # (N, k, 2) pixel offsets, unit spread
    one, zero = np.ones(x.shape[:2]), np.zeros(x.shape[:2])
    # DLT rows: [x y 1 0 0 0 -ux -uy -u] and [0 0 0 x y 1 -vx -vy -v], weighted by use.
    row_u = np.stack([x[..., 0], x[..., 1], one, zero, zero, zero, -u[..., 0] * x[..., 0], -u[..., 0] * x[..., 1], -u[..., 0]], axis=2)
    row_v = np.stack([zero, zero, zero, x[..., 0], x[..., 1], one, -u[..., 1] * x[..., 0], -u[..., 1] * x[..., 1], -u[..., 1]], axis=2)
    w = use.astype(float)[..., None]
    ata = np.einsum("nki,nkj->nij", w * row_u, row_u) + np.einsum("nki,nkj->nij", w * row_v, row_v)
    vals, vecs = np.linalg.eigh(ata)
    h = vecs[:, :, 0].reshape(-1, 3, 3)                              # the least-squares homography
    determined = vals[:, 1] > 1e-9 * np.maximum(vals[:, -1], 1e-300)  # a one-dimensional null space only
    h33 = h[:, 2, 2]
    jac = (h[:, :2, :2] * h33[:, None, None] - h[:, :2, 2:3] * h[:, 2:3, :2]) / np.where(h33 == 0, 1.0, h33)[:, None, None] ** 2
    square = scale * np.sqrt(np.abs(np.linalg.det(jac)))                # pixels per board spacing at the corner
    predicted = centre + scale[:, None] * h[:, :2, 2] / np.where(h33 == 0, 1.0, h33)[:, None]
    # A homography from a one-sided ring of noisy corners can be wild (a board's edge: two
    # columns of corners); its square then disagrees with the neighbours' own spread.
    good = determined & (h33 != 0) & (square > SPREAD_AGREEMENT[0] * scale) & (square < SPREAD_AGREEMENT[1] * scale)
    return np.where(good, np.linalg.norm(pixels - predicted, axis=1), np.nan), np.where(good, square, np.nan)
